"""JSON that every reader accepts: a number that is not finite (a goal a run could not
compute, the error of a failed run) is written as ``null``, never as the ``NaN`` or
``Infinity`` that Python's `json` writes and strict parsers refuse."""

from __future__ import annotations

import json
import math
import numbers


def _finite(value):
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, bool):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        value = float(value)
        return value if math.isfinite(value) else None
    if hasattr(value, "tolist"):  # NumPy arrays and scalars
        return _finite(value.tolist())
    return value


def json_text(data) -> str:
    """``data`` as indented JSON with a final newline, non-finite numbers as ``null``."""
    return json.dumps(_finite(data), indent=2, allow_nan=False) + "\n"
