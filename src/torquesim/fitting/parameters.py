"""The searched parameters: 3 ramps × (delay, duration, level) for every unit of the model,
then any model fields given a range.

A ramp parameter is named ``UNIT.rampK.FIELD`` after the model's unit, e.g.
``elbow_flexor.ramp1.delay`` (9 per unit, units in model order). ``JOINT.flexor`` and
``JOINT.extensor`` name the joint's one unit of that direction (``elbow.flexor.ramp1.delay``),
and on a one-joint model the bare ``flexor``/``extensor`` do too (``flexor.ramp1.delay``, the
names of torquesim 0.2's elbow fit). A model field is named by its parameter path
(`torquesim.model.paths`: ``toe.stiffness``, ``knee_extensors.isometric_torque``) and is
searched when it is given bounds (`ParameterSpace.with_bounds` with the model); it follows
the ramps in the vector, in the order given.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ModelError, check_range
from ..model.activation import ActivationProfile, Ramp
from ..model.paths import canonical_path, get_parameter, limits_at, set_parameter, without_group

RAMPS_PER_UNIT = 3
RAMP_FIELDS = ("delay", "duration", "level")
PER_UNIT = RAMPS_PER_UNIT * len(RAMP_FIELDS)
#: Default bounds per ramp field (s, s, activation).
DEFAULT_BOUNDS = {"delay": (0.0, 1.0), "duration": (0.05, 0.8), "level": (0.0, 1.0)}
#: The physical limits a user's bounds must stay inside.
HARD_LIMITS = {"delay": (0.0, 600.0), "duration": (1e-3, 600.0), "level": (0.0, 1.0)}
#: The units of torquesim's default elbow model, in model order.
ELBOW_UNITS = ("elbow_flexor", "elbow_extensor")
NAME_HELP = "UNIT.ramp1|2|3.delay|duration|level, UNIT one of"


def parameter_names(units) -> tuple[str, ...]:
    """``UNIT.rampK.FIELD`` for every unit, ramp and field, in vector order."""
    return tuple(f"{unit}.ramp{i + 1}.{name}" for unit in units
                 for i in range(RAMPS_PER_UNIT) for name in RAMP_FIELDS)


#: The end of a ramp's parameter path (``UNIT.rampK.FIELD``).
_RAMP_PATH = re.compile(r"\.ramp\d+\.(" + "|".join(RAMP_FIELDS) + ")$")


def _field_of(name: str) -> str:
    return name.rsplit(".", 1)[1]


@dataclass(frozen=True)
class ParameterSpace:
    """Bounds and frozen values of the ramp parameters of a model's units.

    Attributes
    ----------
    units : tuple of str
        The model's unit names, in model order; 9 parameters each. Default: the elbow's.
    lower, upper : tuple of float or None
        Bounds in `parameter_names` order; None gives the defaults: delays [0, 1] s,
        durations [0.05, 0.8] s, levels [0, 1].
    frozen : dict
        Parameter name → fixed value; those are not searched.
    rest_level : float or None
        Initial (rest) activation of every unit whose model gives one (the antagonists; the
        others start from static equilibrium). None: each unit's own. Bounds [0, 1].
    aliases : dict
        Other names of units (see `unit_aliases`).
    fields : dict
        Model fields searched beside the ramps: canonical parameter path → (low, high,
        low_open, high_open), the values the model allows there (`paths.limits_at`); their
        bounds follow the ramps' in ``lower`` and ``upper``. Default: none.
    """

    units: tuple[str, ...] = ELBOW_UNITS
    lower: tuple[float, ...] | None = None
    upper: tuple[float, ...] | None = None
    frozen: dict = field(default_factory=dict)
    rest_level: float | None = None
    aliases: dict = field(default_factory=lambda: {"flexor": ELBOW_UNITS[0],
                                                   "extensor": ELBOW_UNITS[1],
                                                   "elbow.flexor": ELBOW_UNITS[0],
                                                   "elbow.extensor": ELBOW_UNITS[1]})
    fields: dict = field(default_factory=dict)

    @classmethod
    def for_model(cls, model, **kwargs) -> ParameterSpace:
        """The space of ``model``'s units (a `ChainModel`)."""
        return cls(units=tuple(u.name for u in model.units), aliases=model.unit_aliases(),
                   **kwargs)

    def __post_init__(self) -> None:
        names = self.names
        defaults = [DEFAULT_BOUNDS[_field_of(n)] for n in parameter_names(self.units)]
        if self.lower is None:
            object.__setattr__(self, "lower", tuple(d[0] for d in defaults))
        if self.upper is None:
            object.__setattr__(self, "upper", tuple(d[1] for d in defaults))
        if not len(self.lower) == len(self.upper) == len(names):
            raise ModelError("bounds", f"{len(self.lower)} lower and {len(self.upper)} upper "
                             f"bounds; allowed: {len(names)}, one per parameter")
        if self.rest_level is not None:
            check_range("rest_level", self.rest_level, 0.0, 1.0)
        for i, name in enumerate(names):
            low, high, low_open, high_open = self._limits(name)
            for value in (self.lower[i], self.upper[i]):
                check_range(f"bounds.{name}", value, low, high, low_open=low_open,
                            high_open=high_open)
            if self.lower[i] >= self.upper[i]:
                raise ModelError(f"bounds.{name}", f"lower {self.lower[i]:g} ≥ upper "
                                 f"{self.upper[i]:g}; allowed lower < upper (to hold a "
                                 "parameter at one value, freeze it)")
        resolved = {}
        for name, value in self.frozen.items():
            canonical = self.resolve(name, "freeze")
            low, high, low_open, high_open = self._limits(canonical)
            check_range(f"freeze.{name}", value, low, high, low_open=low_open,
                        high_open=high_open)
            i = names.index(canonical)
            if not self.lower[i] <= value <= self.upper[i]:
                raise ModelError(f"freeze.{name}", f"{value:g} is outside its bounds; allowed "
                                 f"[{self.lower[i]:g}, {self.upper[i]:g}] (or change them with "
                                 "--bound)")
            if canonical in resolved:
                raise ModelError(f"freeze.{name}", "given twice (under two names); allowed: "
                                 "once")
            resolved[canonical] = float(value)
        object.__setattr__(self, "frozen", resolved)

    def _limits(self, name: str) -> tuple[float, float, bool, bool]:
        """(low, high, low_open, high_open) any value of parameter ``name`` must keep."""
        return self.fields.get(name) or (*HARD_LIMITS[_field_of(name)], False, False)

    @property
    def names(self) -> tuple[str, ...]:
        return parameter_names(self.units) + tuple(self.fields)

    @property
    def size(self) -> int:
        return len(self.units) * PER_UNIT + len(self.fields)

    def resolve(self, name: str, what: str = "parameter") -> str:
        """The canonical name of the parameter path ``name`` (`torquesim.model.paths`: a unit
        alias replaced by the unit's name, an optional leading ``units.`` dropped)."""
        bare = without_group(name)
        unit, dot, rest = bare.rpartition(".ramp")
        canonical = f"{self.aliases.get(unit, unit)}{dot}{rest}"
        if canonical in self.names:
            return canonical
        for alias in sorted(self.aliases, key=len, reverse=True):  # a searched model field
            if bare.startswith(alias + "."):
                bare = self.aliases[alias] + bare[len(alias):]
                break
        if bare in self.fields:
            return bare
        raise ModelError(what, f"{name!r} is not a parameter; allowed: {NAME_HELP} "
                         f"{', '.join(self.units)}; or a model field given a range, "
                         "--bound PATH=LOW,HIGH (torquesim model NAME --paths)")

    def select(self, path: str, what: str = "parameter") -> list[str]:
        """The parameter names ``path`` selects: all of a unit's (``UNIT``), one ramp's
        (``UNIT.rampK``) or one (``UNIT.rampK.FIELD``), a unit by name or alias, an optional
        leading ``units.``; a `ModelError` on ``what`` for a path that names none."""
        bare = without_group(path)
        unit = self.aliases.get(bare, bare)
        if unit in self.units:
            return [n for n in self.names if n.startswith(unit + ".ramp")]
        head, dot, ramp = bare.rpartition(".")
        if dot and ramp.startswith("ramp") and ramp[4:].isdigit():
            if int(ramp[4:]) not in range(1, RAMPS_PER_UNIT + 1):
                raise ModelError(what, f"{path!r}: no ramp {ramp[4:]}; allowed ramp1 to "
                                 f"ramp{RAMPS_PER_UNIT} of a unit ({', '.join(self.units)})")
            return [self.resolve(f"{bare}.{f}", what) for f in RAMP_FIELDS]
        return [self.resolve(bare, what)]

    def index(self, name: str) -> int:
        return self.names.index(self.resolve(name))

    def with_bounds(self, name: str, low: float, high: float, model=None) -> ParameterSpace:
        """This space with the bounds of ``name`` set to [low, high]: a ramp parameter or a
        searched field, else, given the ``model`` (a `ChainModel`), the model field at that
        parameter path, searched from now on."""
        try:
            i = self.names.index(self.resolve(name, "bounds"))
        except ModelError:
            if model is None or not self.is_field(model, name):
                raise
            path = canonical_path(model, name, "bounds")
            return replace(self, fields={**self.fields, path: limits_at(model, path)},
                           lower=(*self.lower, low), upper=(*self.upper, high))
        lower, upper = list(self.lower), list(self.upper)
        lower[i], upper[i] = low, high
        return replace(self, lower=tuple(lower), upper=tuple(upper))

    def is_field(self, model, path: str) -> bool:
        """Whether ``path`` names a model field of ``model`` (`torquesim.model.paths`) that
        is not a ramp parameter."""
        try:
            name = canonical_path(model, path)
        except ModelError:
            return False
        return name not in parameter_names(self.units) and not _RAMP_PATH.search(name)

    def field_values(self, model) -> np.ndarray:
        """The searched fields' values in ``model``, in vector order (SI)."""
        return np.array([get_parameter(model, path) for path in self.fields], dtype=float)

    def difference_scales(self) -> np.ndarray:
        """Each parameter's scale for a difference quotient: 1 (s, activation) for a ramp
        parameter, its range for a model field (a stiffness of 1e6 N/m^1.5 moves in N/m^1.5)."""
        ramps = len(self.units) * PER_UNIT
        return np.concatenate([np.ones(ramps), np.subtract(self.upper, self.lower)[ramps:]])

    def with_fields(self, model, x):
        """``model`` with the searched fields at their values in the full vector ``x``; a
        value the model does not allow is a `ModelError`."""
        ramps = len(self.units) * PER_UNIT
        for k, path in enumerate(self.fields):
            model = set_parameter(model, path, float(x[ramps + k]))
        return model

    def with_frozen(self, name: str, value: float) -> ParameterSpace:
        return replace(self, frozen={**self.frozen, self.resolve(name, "freeze"): value})

    @property
    def free(self) -> np.ndarray:
        """Indices of the searched parameters."""
        return np.array([i for i, n in enumerate(self.names) if n not in self.frozen],
                        dtype=np.int64)

    def bounds(self) -> list[tuple[float, float]]:
        """(low, high) of each free parameter."""
        return [(self.lower[i], self.upper[i]) for i in self.free]

    def full(self, free_values, base) -> np.ndarray:
        """All values: a copy of ``base`` with ``free_values`` in the free slots and the
        frozen values in the frozen ones."""
        x = np.array(base, dtype=float)
        for name, value in self.frozen.items():
            x[self.names.index(name)] = value
        x[self.free] = free_values
        return x

    def clip(self, x) -> np.ndarray:
        """``x`` moved inside the bounds."""
        return np.clip(np.asarray(x, dtype=float), self.lower, self.upper)

    def table(self, x) -> dict[str, float]:
        """Name → value of a parameter vector."""
        return {name: float(v) for name, v in zip(self.names, x, strict=True)}


def ramps_of(x, unit_index: int) -> tuple[Ramp, ...]:
    """The 3 ramps of unit ``unit_index`` in the parameter vector ``x``."""
    o = unit_index * PER_UNIT
    return tuple(Ramp(float(x[o + 3 * i]), float(x[o + 3 * i + 1]), float(x[o + 3 * i + 2]))
                 for i in range(RAMPS_PER_UNIT))


def vector(profiles) -> np.ndarray:
    """The parameter vector of 3-ramp activation profiles (one per unit, in order)."""
    out = []
    for k, profile in enumerate(profiles):
        if len(profile.ramps) != RAMPS_PER_UNIT:
            raise ModelError(f"units[{k}].activation.ramps",
                             f"has {len(profile.ramps)} ramps; the fit uses {RAMPS_PER_UNIT}")
        for ramp in profile.ramps:
            out += [ramp.delay, ramp.duration, ramp.level]
    return np.array(out)


def held_profiles(model, hold: float) -> tuple[ActivationProfile, ...] | None:
    """Each unit's activation profile padded to `RAMPS_PER_UNIT` ramps with ramps (delay 0,
    duration ``hold`` s) that hold its last level, so that the activation is unchanged; a
    unit without ramps holds the level it starts at (its static level for "equilibrium").
    None when a unit has more ramps than that."""
    if any(len(u.activation.ramps) > RAMPS_PER_UNIT for u in model.units):
        return None
    levels = model.initial_state().levels
    out = []
    for unit, start in zip(model.units, levels, strict=True):
        ramps = unit.activation.ramps
        last = ramps[-1].level if ramps else float(start)
        out.append(replace(unit.activation, ramps=tuple(ramps) + (Ramp(0.0, hold, last),) * (
            RAMPS_PER_UNIT - len(ramps))))
    return tuple(out)


def own_vector(model) -> np.ndarray | None:
    """``model``'s own activation profiles as the fit's parameter vector (`held_profiles`,
    held over the shortest default duration; None when a unit has more ramps than the fit
    uses)."""
    profiles = held_profiles(model, DEFAULT_BOUNDS["duration"][0])
    return None if profiles is None else vector(profiles)


def with_ramps(model, x, initial_levels) -> object:
    """``model`` (a chain) with every unit's activation the 3 ramps of ``x`` from
    ``initial_levels`` (None: the model's; a number: that level; per unit)."""
    units = tuple(replace(u, activation=ActivationProfile(
        u.activation.initial_level if level is None else level, ramps_of(x, k)))
        for k, (u, level) in enumerate(zip(model.units, initial_levels, strict=True)))
    return model.replace(units=units)
