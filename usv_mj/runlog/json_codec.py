"""JSON for run logs: orjson when installed (fast), the standard library otherwise (same files, slower).

Floats are written as the shortest decimal that reads back to the same double (orjson's Ryu-based
formatting, or ``repr``), NaN as ``null``, +-inf as ``1e999`` / ``-1e999`` in the row topics (see
:mod:`usv_mj.runlog.topics`). In other messages (events, Foxglove) a non-finite float is ``null``.
"""

from __future__ import annotations

import json
import math

import numpy as np

try:  # orjson is a dependency of usv_mj; the fallback keeps the log working without it
    import orjson
except ImportError:  # pragma: no cover - exercised by monkeypatching in tests
    orjson = None

_OPTS = (orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS) if orjson is not None else 0


def _plain(obj):
    """numpy scalars/arrays, tuples and non-finite floats made standard-JSON-safe (fallback path)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_plain(v) for v in obj.tolist()]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def dumps(obj) -> bytes:
    """Compact JSON bytes of plain data (numpy values allowed; other objects via str())."""
    if orjson is not None:
        return orjson.dumps(obj, option=_OPTS, default=str)
    return json.dumps(_plain(obj), separators=(",", ":"), default=str, allow_nan=False).encode()


def dumps_floats(flat: np.ndarray) -> bytes:
    """A 1-D float64 array as a JSON array, one token per value (NaN -> null; +-inf: any token)."""
    if orjson is not None:
        return orjson.dumps(np.ascontiguousarray(flat, dtype=np.float64), option=orjson.OPT_SERIALIZE_NUMPY)
    return ("[" + ",".join("null" if v != v else ("1e999" if v == math.inf else ("-1e999" if v == -math.inf
                                                                                else repr(v)))
                           for v in flat.tolist()) + "]").encode()


def loads(text):
    """Parse JSON; numbers too large for a double (1e999) become +-inf."""
    if orjson is not None:
        try:
            return orjson.loads(text)
        except orjson.JSONDecodeError:
            pass
    return json.loads(text)
