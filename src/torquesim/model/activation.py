"""Parametric activation profiles: a chain of quintic ramps (docs/model.md §3).

One ramp from level a_prev to a_i, starting at t_on and lasting r:

    a(t) = a_prev + (a_i − a_prev)·s³(6s² − 15s + 10),   s = (t − t_on)/r ∈ [0, 1]

This is the minimum-jerk (C², zero velocity and acceleration at both ends) transition.
A profile is an initial level a_0 and n ramps, each given by (delay after the previous ramp
ends, duration, new level).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from .fields import Allowed, check_fields
from .jit import njit

#: The allowed values of a ramp's numbers, of a profile's initial level (None: solved for
#: rest) and of activation dynamics' time constants (`Allowed`).
RAMP_FIELDS = {
    "delay": Allowed("s", "from the end of the previous ramp", 0.0, math.inf, high_open=True),
    "duration": Allowed("s", "", 0.0, math.inf, low_open=True, high_open=True),
    "level": Allowed("", "activation reached at its end", 0.0, 1.0),
}
PROFILE_FIELDS = {"initial_level": Allowed("", "a_0", 0.0, 1.0, optional=True)}
DYNAMICS_FIELDS = {
    "activation_time": Allowed("s", "tau_act of da/dt (Thelen 2003: 0.015)", 0.0, 1.0,
                               low_open=True),
    "deactivation_time": Allowed("s", "tau_deact of da/dt (Thelen 2003: 0.050)", 0.0, 1.0,
                                 low_open=True),
}


@dataclass(frozen=True)
class Ramp:
    """One activation ramp.

    Attributes
    ----------
    delay : float
        Time from the end of the previous ramp (or t = 0) to this ramp's start, s.
        Bounds [0, inf).
    duration : float
        Ramp duration r, s. Bounds (0, inf).
    level : float
        Activation reached at the end of the ramp. Bounds [0, 1].
    """

    delay: float
    duration: float
    level: float

    def __post_init__(self) -> None:
        check_fields(self, RAMP_FIELDS)


@dataclass(frozen=True)
class ActivationProfile:
    """Activation a(t) ∈ [0, 1] of one unit.

    Attributes
    ----------
    initial_level : float or None
        a_0. ``None`` means "from static equilibrium" (allowed for the flexor only, where it is
        the default). Bounds [0, 1].
    ramps : tuple of Ramp
        The ramps in time order. The default profile has 3 ramps, i.e. 9 parameters.
    """

    initial_level: float | None
    ramps: tuple[Ramp, ...] = ()

    def __post_init__(self) -> None:
        check_fields(self, PROFILE_FIELDS)
        object.__setattr__(self, "ramps", tuple(self.ramps))
        for i, ramp in enumerate(self.ramps):
            if not isinstance(ramp, Ramp):
                raise ModelError(f"ramps[{i}]", "must be a Ramp(delay, duration, level)")

    def ramp_times(self) -> list[tuple[float, float]]:
        """(start, end) of every ramp, s: ramp i starts at Σ_{j<i}(delay_j + r_j) + delay_i."""
        t = 0.0
        out = []
        for ramp in self.ramps:
            start = t + ramp.delay
            t = start + ramp.duration
            out.append((start, t))
        return out

    def to_array(self, initial_level: float | None = None) -> np.ndarray:
        """Pack as [a_0, n, t_on_1, r_1, a_1, …] for `activation`.

        ``initial_level`` supplies a_0 when the profile's own is ``None``.
        """
        a0 = self.initial_level if self.initial_level is not None else initial_level
        if a0 is None:
            raise ModelError("initial_level", "is 'equilibrium' but no level was supplied")
        out = [float(a0), float(len(self.ramps))]
        for ramp, (start, _) in zip(self.ramps, self.ramp_times(), strict=True):
            out += [start, ramp.duration, ramp.level]
        return np.array(out)

    def __call__(self, t, initial_level: float | None = None) -> np.ndarray:
        """a(t) at the times ``t`` (s), as an array."""
        packed = self.to_array(initial_level)
        t = np.asarray(t, dtype=float)
        return np.array([activation(float(ti), packed, 0) for ti in t.ravel()]).reshape(t.shape)


@njit(cache=True, error_model="numpy")
def quintic_ramp(s):
    """Minimum-jerk blend s³(6s² − 15s + 10) for s ∈ [0, 1]."""
    return s * s * s * (s * (6.0 * s - 15.0) + 10.0)


@njit(cache=True, error_model="numpy")
def activation(t, profile, o=0):
    """a(t) of a packed profile ``[a_0, n, (t_on, r, level) × n]`` (see module docstring)."""
    level = profile[o + 0]
    n = int(profile[o + 1])
    for i in range(n):
        t_on = profile[o + 2 + 3 * i]
        duration = profile[o + 3 + 3 * i]
        target = profile[o + 4 + 3 * i]
        if t <= t_on:
            return level
        if t < t_on + duration:
            return level + (target - level) * quintic_ramp((t - t_on) / duration)
        level = target
    return level


@dataclass(frozen=True)
class ActivationDynamics:
    """First-order activation dynamics of a unit (Thelen 2003, as OpenSim's Thelen2003Muscle).

    Without it a unit's activation is its profile, a = e(t). With it the profile is the unit's
    excitation e(t) (the neural drive) and the activation a becomes a state of the unit:

        da/dt = (e − a)/τ(e, a),   τ = τ_act·(0.5 + 1.5a) if e > a else τ_deact/(0.5 + 1.5a)

    (Thelen 2003, J Biomech Eng 125:70, doi:10.1115/1.1531112; the form of Winters 1995).

    Attributes
    ----------
    activation_time : float
        τ_act, s. Bounds (0, 1]. Thelen 2003: 0.015.
    deactivation_time : float
        τ_deact, s. Bounds (0, 1]. Thelen 2003: 0.050.
    """

    activation_time: float = 0.015
    deactivation_time: float = 0.050

    def __post_init__(self) -> None:
        check_fields(self, DYNAMICS_FIELDS)


@njit(cache=True, error_model="numpy", inline="always")
def activation_rate(excitation, level, activation_time, deactivation_time):
    """da/dt = (e − a)/τ(e, a), 1/s, of `ActivationDynamics` at excitation e and activation a."""
    scale = 0.5 + 1.5 * level
    if excitation > level:
        return (excitation - level) / (activation_time * scale)
    return (excitation - level) * scale / deactivation_time


@njit(cache=True, error_model="numpy", inline="always")
def activation_time_constant(excitation, level, activation_time, deactivation_time):
    """1/|∂(da/dt)/∂a| of `activation_rate`, s: the time constant the stability guard compares
    the step with. With s = 0.5 + 1.5a,

        e > a:      τ_act·s²/(s + 1.5·(e − a))
        otherwise:  τ_deact/(s + 1.5·(a − e))
    """
    scale = 0.5 + 1.5 * level
    if excitation > level:
        return activation_time * scale * scale / (scale + 1.5 * (excitation - level))
    return deactivation_time / (scale + 1.5 * (level - excitation))


@njit(cache=True, error_model="numpy", inline="always")
def implicit_activation(known, excitation, gamma_h, activation_time, deactivation_time):
    """The activation a of one implicit (diagonally implicit Runge-Kutta) stage,
    a = known + γh·da/dt(e, a), in closed form: on either branch of `activation_rate` it is
    the positive root of A·a² + B·a − C = 0. The branch is that of e against ``known``: the
    root lies between them, so e − a has the sign of e − known.

        e > known:  A = 1.5,     B = 0.5 − 1.5·known + γh/τ_act,  C = 0.5·known + γh/τ_act·e
        otherwise:  A = 1.5·c,   B = 1 + 0.5·c − 1.5·c·e,         C = known + 0.5·c·e,
                    c = γh/τ_deact

    Written as 2C/(B + √(B² + 4AC)), which does not cancel."""
    if excitation > known:
        c = gamma_h / activation_time
        a2, b, cc = 1.5, 0.5 - 1.5 * known + c, 0.5 * known + c * excitation
    else:
        c = gamma_h / deactivation_time
        a2, b, cc = 1.5 * c, 1.0 + 0.5 * c - 1.5 * c * excitation, known + 0.5 * c * excitation
    if cc <= 0.0:
        return 0.0
    return 2.0 * cc / (b + math.sqrt(b * b + 4.0 * a2 * cc))
