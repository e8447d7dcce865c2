"""JSON for run logs (events, Foxglove topics, metadata), through orjson (a block's numbers in one call).

Floats are written as the shortest decimal that reads back to the same double (orjson's Ryu-based
formatting), NaN as ``null``; +-inf as ``1e999`` / ``-1e999`` in the numbers laid out from templates
(the Foxglove frames and funnel, the metadata: see :mod:`usv_mj.outputs.log.topics`), ``null`` in
messages dumped whole (events, the Foxglove scenes).
"""

from __future__ import annotations

import json

import numpy as np
import orjson

_OPTS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


def dumps(obj) -> bytes:
    """Compact JSON bytes of plain data (numpy values allowed; other objects via str())."""
    return orjson.dumps(obj, option=_OPTS, default=str)


def dumps_floats(flat: np.ndarray) -> bytes:
    """A 1-D float64 array as a JSON array, one token per value (NaN -> null; +-inf: any token)."""
    return orjson.dumps(np.ascontiguousarray(flat, dtype=np.float64), option=orjson.OPT_SERIALIZE_NUMPY)


def loads(text):
    """Parse JSON; numbers too large for a double (1e999) become +-inf."""
    try:
        return orjson.loads(text)
    except orjson.JSONDecodeError:  # orjson refuses 1e999; the standard parser reads it as inf
        return json.loads(text)
