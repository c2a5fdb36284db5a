"""Errors raised at the boundary of torquesim (files, CLI, constructors).

Every message names the offending field and the allowed range, so the CLI can print it as a
single line and exit with status 2.
"""

from __future__ import annotations

import math
import numbers

import numpy as np


class ModelError(ValueError):
    """An invalid model, parameter or input.

    Parameters
    ----------
    field : str
        Dotted name of the offending field (``"flexor.se_stiffness"``), or ``""``.
    message : str
        What is wrong and what is allowed.
    """

    def __init__(self, field: str, message: str):
        self.field = field
        self.reason = message
        super().__init__(f"{field}: {message}" if field else message)

    def under(self, prefix: str) -> ModelError:
        """The same error with ``prefix.`` put in front of the field name (unless it is
        already there)."""
        if self.field == prefix or self.field.startswith((f"{prefix}.", f"{prefix}[")):
            return self
        return ModelError(f"{prefix}.{self.field}" if self.field else prefix, self.reason)


class SimulationError(RuntimeError):
    """A run that could not be completed (non-finite state, divergence)."""


def shown(value) -> str:
    """A value for a message: numbers to 6 significant digits (never 300 of them), other
    things by repr, cut at 60 characters."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return f"{float(value):.6g}"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def check_name(field: str, value) -> str:
    """Return ``value`` or raise `ModelError` naming ``field``: a name that heads output
    columns must be non-empty letters, digits and ``_`` (a space or a dash breaks the columns
    of a ``.sto`` header and of a CSV read by name)."""
    if not isinstance(value, str) or not value or not all(c.isalnum() or c == "_"
                                                          for c in value):
        raise ModelError(field, f"{shown(value)}: allowed a non-empty name of letters, digits "
                         "and _ (it names output columns)")
    return value


def check_range(
    field: str,
    value: float,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
) -> float:
    """Return ``float(value)`` or raise `ModelError` naming ``field`` and the range.

    Any real number is accepted (NumPy scalars included); booleans are not. The interval is
    ``[low, high]``; ``low_open``/``high_open`` exclude an end.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ModelError(field, f"must be a number, got {shown(value)}")
    v = float(value)
    lo_ok = v > low if low_open else v >= low
    hi_ok = v < high if high_open else v <= high
    if not math.isfinite(v) or not (lo_ok and hi_ok):
        interval = (
            ("(" if low_open or low == -math.inf else "[")
            + f"{low:g}, {high:g}"
            + (")" if high_open or high == math.inf else "]")
        )
        u = f" {unit}" if unit else ""
        raise ModelError(field, f"{shown(v)} is out of range; allowed {interval}{u}")
    return v
