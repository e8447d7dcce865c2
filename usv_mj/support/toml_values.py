"""Reading TOML files and checking their values, with messages that name the file and the key.

Scenarios, sea settings and sweep files all use these two functions, each with its own error
class (a ``ValueError`` subclass), so that a user always sees one line such as
``my.toml: quantizer.delta_u must be a number, got 'x'``.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any


def read_toml(path: str | Path, error: type[Exception], what: str = "file") -> dict:
    """The table of a TOML file; a missing file or bad TOML raises ``error`` naming the path."""
    path = Path(path)
    if path.exists() and not path.is_file():  # a folder, a named pipe (reading one would wait forever)
        raise error(f"{path}: is not a regular file; name a TOML file")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a UTF-8 text file (byte {exc.start}); TOML files are UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:  # arrays or tables nested thousands deep
        raise error(f"{path}: not valid TOML here: nested too deeply") from None


def coerce(source: str, where: str, value: Any, default: Any, error: type[Exception]) -> Any:
    """``value`` converted to the type of ``default`` (bool, int, float, str, a fixed-length vector
    or a list of pairs); otherwise ``error`` with ``source`` and the key ``where`` in its message."""
    def bad(what):
        return error(f"{source}: {where} must be {what}, got {value!r}")

    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise bad("true or false")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise bad("an integer")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad("a number")
        if math.isnan(value) or (math.isinf(value) and not math.isinf(default)):
            # inf only where the default is inf ("no limit": the actuators' limits)
            raise bad("a finite number" if math.isfinite(default) else "a number or inf (no limit)")
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise bad("a string")
        return value
    if isinstance(default, tuple):
        if not isinstance(value, (list, tuple)):
            raise bad("a list")
        if default and not isinstance(default[0], tuple):  # flat vector of fixed length
            if len(value) != len(default):
                raise bad(f"a list of {len(default)} numbers")
            return tuple(coerce(source, f"{where}[{i}]", v, 0.0, error) for i, v in enumerate(value))
        return tuple(tuple(coerce(source, f"{where}[{i}]", v, (0.0, 0.0), error)) for i, v in enumerate(value))
    return value
