"""The fitted parameters: 3 ramps × (delay, duration, level) for each unit, 18 in all."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ModelError, check_range
from ..model.activation import ActivationProfile, Ramp

UNITS = ("flexor", "extensor")
RAMPS_PER_UNIT = 3
RAMP_FIELDS = ("delay", "duration", "level")
#: ``flexor.ramp1.delay`` … ``extensor.ramp3.level``, in vector order.
PARAMETER_NAMES = tuple(f"{unit}.ramp{i + 1}.{name}" for unit in UNITS
                        for i in range(RAMPS_PER_UNIT) for name in RAMP_FIELDS)
PER_UNIT = RAMPS_PER_UNIT * len(RAMP_FIELDS)
#: Default bounds per ramp field (s, s, activation), as the fit issue specifies.
DEFAULT_BOUNDS = {"delay": (0.0, 1.0), "duration": (0.05, 0.8), "level": (0.0, 1.0)}
#: The physical limits a user's bounds must stay inside.
HARD_LIMITS = {"delay": (0.0, 600.0), "duration": (1e-3, 600.0), "level": (0.0, 1.0)}
DEFAULT_EXTENSOR_REST = 0.1


def _field_of(name: str) -> str:
    return name.rsplit(".", 1)[1]


@dataclass(frozen=True)
class ParameterSpace:
    """Bounds and frozen values of the 18 ramp parameters.

    Attributes
    ----------
    lower, upper : tuple of float
        Bounds in :data:`PARAMETER_NAMES` order. Defaults: delays [0, 1] s, durations
        [0.05, 0.8] s, levels [0, 1].
    frozen : dict
        Parameter name → fixed value; those are not searched.
    extensor_rest : float
        The extensor's initial (rest) activation, a setting, not fitted. Default 0.1
        (docs/model.md). The flexor's initial level comes from static equilibrium.
    """

    lower: tuple[float, ...] = tuple(DEFAULT_BOUNDS[_field_of(n)][0] for n in PARAMETER_NAMES)
    upper: tuple[float, ...] = tuple(DEFAULT_BOUNDS[_field_of(n)][1] for n in PARAMETER_NAMES)
    frozen: dict = field(default_factory=dict)
    extensor_rest: float = DEFAULT_EXTENSOR_REST

    def __post_init__(self) -> None:
        check_range("extensor_rest", self.extensor_rest, 0.0, 1.0)
        for i, name in enumerate(PARAMETER_NAMES):
            low, high = HARD_LIMITS[_field_of(name)]
            check_range(f"bounds.{name}", self.lower[i], low, high)
            check_range(f"bounds.{name}", self.upper[i], low, high)
            if self.lower[i] > self.upper[i]:
                raise ModelError(f"bounds.{name}", f"lower {self.lower[i]:g} > upper "
                                 f"{self.upper[i]:g}; allowed lower ≤ upper")
        for name, value in self.frozen.items():
            if name not in PARAMETER_NAMES:
                raise ModelError("freeze", f"{name!r} is not a parameter; allowed: "
                                 "flexor|extensor.ramp1|2|3.delay|duration|level")
            low, high = HARD_LIMITS[_field_of(name)]
            check_range(f"freeze.{name}", value, low, high)

    def with_bounds(self, name: str, low: float, high: float) -> ParameterSpace:
        i = _index(name, "bounds")
        lower, upper = list(self.lower), list(self.upper)
        lower[i], upper[i] = low, high
        return replace(self, lower=tuple(lower), upper=tuple(upper))

    def with_frozen(self, name: str, value: float) -> ParameterSpace:
        _index(name, "freeze")
        return replace(self, frozen={**self.frozen, name: value})

    @property
    def free(self) -> np.ndarray:
        """Indices (into the 18) of the searched parameters."""
        return np.array([i for i, n in enumerate(PARAMETER_NAMES) if n not in self.frozen],
                        dtype=np.int64)

    def bounds(self) -> list[tuple[float, float]]:
        """(low, high) of each free parameter."""
        return [(self.lower[i], self.upper[i]) for i in self.free]

    def full(self, free_values, base) -> np.ndarray:
        """All 18 values: a copy of ``base`` (an 18-vector) with ``free_values`` in the free
        slots and the frozen values in the frozen ones."""
        x = np.array(base, dtype=float)
        for name, value in self.frozen.items():
            x[PARAMETER_NAMES.index(name)] = value
        x[self.free] = free_values
        return x

    def clip(self, x) -> np.ndarray:
        """An 18-vector moved inside the bounds."""
        return np.clip(np.asarray(x, dtype=float), self.lower, self.upper)


def _index(name: str, what: str) -> int:
    if name not in PARAMETER_NAMES:
        raise ModelError(what, f"{name!r} is not a parameter; allowed: "
                         "flexor|extensor.ramp1|2|3.delay|duration|level")
    return PARAMETER_NAMES.index(name)


def profiles(x, extensor_rest: float) -> tuple[ActivationProfile, ActivationProfile]:
    """The flexor (initial level from equilibrium) and extensor profiles of an 18-vector."""
    def ramps(offset: int) -> tuple[Ramp, ...]:
        return tuple(Ramp(float(x[offset + 3 * i]), float(x[offset + 3 * i + 1]),
                          float(x[offset + 3 * i + 2])) for i in range(RAMPS_PER_UNIT))

    return (ActivationProfile(None, ramps(0)),
            ActivationProfile(float(extensor_rest), ramps(PER_UNIT)))


def vector(flexor: ActivationProfile, extensor: ActivationProfile) -> np.ndarray:
    """The 18-vector of two 3-ramp profiles."""
    out = []
    for profile, unit in ((flexor, "flexor"), (extensor, "extensor")):
        if len(profile.ramps) != RAMPS_PER_UNIT:
            raise ModelError(f"{unit}_activation.ramps",
                             f"has {len(profile.ramps)} ramps; the fit uses {RAMPS_PER_UNIT}")
        for ramp in profile.ramps:
            out += [ramp.delay, ramp.duration, ramp.level]
    return np.array(out)
