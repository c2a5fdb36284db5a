"""The allowed values of the model's numeric fields, each written once (`Allowed`) and read by
the range check of its class (`check_fields`), the model file's comments and the docs' field
tables."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import check_range

#: A bound that is another field's value times a factor: (factor, field name).
Related = tuple[float, str]


@dataclass(frozen=True)
class Allowed:
    """The allowed values of one numeric field of the model, written once: its class's range
    check (`check_fields`), its docstring's "Bounds" (held to it by a test), the model
    file's comment (`text`) and the field table of docs/model-files.md are made from it.

    ``low`` and ``high`` are numbers, or (factor, field) for a bound that is another field's
    value times the factor; ``low_open``/``high_open`` exclude an end. ``unit`` is the SI
    unit as messages print it ("" for a ratio); ``meaning`` says what the field is, in plain
    ASCII, as model files print it.
    """

    unit: str
    meaning: str
    low: float | Related
    high: float | Related
    low_open: bool = False
    high_open: bool = False
    #: None is allowed too (a field whose None means "chosen by the model").
    optional: bool = False

    @property
    def related(self) -> bool:
        """True when a bound is another field's value."""
        return isinstance(self.low, tuple) or isinstance(self.high, tuple)

    def limits(self, values: dict[str, float]) -> tuple[float, float]:
        """(low, high) given the values of the fields checked before this one."""
        return tuple(b[0] * values[b[1]] if isinstance(b, tuple) else b
                     for b in (self.low, self.high))

    def interval(self, plain: bool = False) -> str:
        """The bounds as the docs write them, e.g. ``(0, 1e4]``, ``[−π, 2π]``,
        ``(isometric_torque, 10 × isometric_torque]``; ``plain``: ASCII (``[-pi, 2pi]``),
        for model files."""
        low, high = _bound(self.low, plain), _bound(self.high, plain)
        return f"{'(' if self.low_open else '['}{low}, {high}{')' if self.high_open else ']'}"

    def text(self) -> str:
        """The model file's comment: unit, meaning and bounds, ASCII (``s, simulated time.
        (0, 600]``)."""
        said = ", ".join(p for p in (self.unit.replace("·", " "), self.meaning) if p)
        return f"{said + '. ' if said else ''}{self.interval(plain=True)}"


def _bound(value: float | Related, plain: bool) -> str:
    """One end of an interval in words: a field's name (times its factor), a multiple of π,
    a power of ten from 1000 (``1e4``) or the number."""
    minus = "-" if plain else "−"
    if isinstance(value, tuple):
        factor, name = value
        if abs(factor) == 1.0:
            return f"{minus if factor < 0 else ''}{name}"
        return f"{factor:g}{' ' if plain else ' × '}{name}"
    if math.isinf(value):
        return f"{minus if value < 0 else ''}inf"
    for k in (-1, 1, 2):
        if value == k * math.pi:
            return f"{minus if k < 0 else ''}{'2' if k == 2 else ''}{'pi' if plain else 'π'}"
    if value >= 1e3 and math.log10(value) == int(math.log10(value)):
        return f"1e{int(math.log10(value))}"
    return f"{value:g}"


def check_fields(owner, table: dict[str, Allowed]) -> dict[str, float]:
    """Check every field of ``owner`` named in ``table`` against its `Allowed` values, in the
    table's order (a field that bounds another comes first); a `ModelError` naming the field
    and its range for the first out of range. Returns the values checked, as floats (an
    optional field's None left out)."""
    values: dict[str, float] = {}
    for name, allowed in table.items():
        value = getattr(owner, name)
        if value is None and allowed.optional:
            continue
        low, high = allowed.limits(values)
        values[name] = check_range(
            name, value, low, high, low_open=allowed.low_open, high_open=allowed.high_open,
            unit=allowed.unit + (f", that is {allowed.interval()}" if allowed.related else ""))
    return values
