"""The whole elbow model: body, flexor and extensor units, their activation, and the start.

State vector used everywhere: y = (θ, ω, θ_cc,F, θ_cc,E), rad and rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from ..errors import ModelError, check_range
from .activation import ActivationProfile, Ramp
from .body import BodyParameters, passive_torque
from .torque_generator import (
    ACTIVATION_FLOOR,
    H_ISOMETRIC,
    TorqueGeneratorUnit,
    torque_angle,
)

STATE_NAMES = ("theta", "omega", "theta_cc_flexor", "theta_cc_extensor")


class PackedModel(NamedTuple):
    """Plain float arrays handed to the compiled solvers."""

    body: np.ndarray
    flexor: np.ndarray
    extensor: np.ndarray
    flexor_activation: np.ndarray
    extensor_activation: np.ndarray


class InitialState(NamedTuple):
    """Static equilibrium at rest (MODEL.md §3)."""

    state: np.ndarray  #: (θ0, 0, θ_cc,F, θ_cc,E), rad
    flexor_level: float  #: a_0,F used in the run
    extensor_level: float  #: a_0,E
    flexor_torque: float  #: T_F(0), N·m
    extensor_torque: float  #: T_E(0), N·m


def default_flexor_activation() -> ActivationProfile:
    """The fitted flexor profile of the default curl (MODEL.md §3)."""
    return ActivationProfile(None, (Ramp(0.058, 0.311, 0.556), Ramp(0.498, 0.613, 0.227),
                                    Ramp(0.511, 0.462, 0.26)))


def default_extensor_activation() -> ActivationProfile:
    """Constant extensor co-activation 0.1 as three flat ramps (MODEL.md §3)."""
    return ActivationProfile(0.1, tuple(Ramp(0.0, 0.3, 0.1) for _ in range(3)))


@dataclass(frozen=True)
class ElbowModel:
    """A complete simulation model.

    Attributes
    ----------
    body : BodyParameters
    flexor, extensor : TorqueGeneratorUnit
    flexor_activation, extensor_activation : ActivationProfile
        The flexor's initial level may be ``None`` (default): it is then fixed by static
        equilibrium at the initial angle. The extensor's initial level must be given.
    initial_angle : float
        θ0, elbow flexion at t = 0, rad. Default 10° = 0.174533 rad. Bounds [-π, π].
    duration : float
        Simulated time, s. Default 3.0. Bounds (0, 600].
    """

    body: BodyParameters = field(default_factory=BodyParameters)
    flexor: TorqueGeneratorUnit = field(default_factory=TorqueGeneratorUnit.flexor_default)
    extensor: TorqueGeneratorUnit = field(default_factory=TorqueGeneratorUnit.extensor_default)
    flexor_activation: ActivationProfile = field(default_factory=default_flexor_activation)
    extensor_activation: ActivationProfile = field(default_factory=default_extensor_activation)
    initial_angle: float = math.radians(10.0)
    duration: float = 3.0

    def __post_init__(self) -> None:
        for name, kind in (("body", BodyParameters), ("flexor", TorqueGeneratorUnit),
                           ("extensor", TorqueGeneratorUnit),
                           ("flexor_activation", ActivationProfile),
                           ("extensor_activation", ActivationProfile)):
            if not isinstance(getattr(self, name), kind):
                raise ModelError(name, f"must be a {kind.__name__}")
        check_range("initial_angle", self.initial_angle, -math.pi, math.pi, unit="rad")
        check_range("duration", self.duration, 0.0, 600.0, low_open=True, unit="s")
        if self.extensor_activation.initial_level is None:
            raise ModelError("extensor_activation.initial_level",
                             "must be a number in [0, 1] ('equilibrium' is for the flexor only)")
        self.initial_state()  # raises if the start cannot be held

    def replace(self, **changes) -> ElbowModel:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    def initial_state(self) -> InitialState:
        """Static equilibrium at rest at θ0 with ω_cc = 0 in both units (MODEL.md §3).

        The extensor SE stretch s solves k_E·s = a_0,E·T_θ,E(θ0 − s)·h_E(0); the flexor then
        carries T_F = G·sin θ0 − T_p(θ0) + T_E, so s_F = T_F/k_F and
        a_0,F = T_F / (h_F(0)·T_θ,F(θ0 + s_F)). If the flexor profile gives its own initial
        level, that level is used and the flexor CE starts away from isometric.
        """
        theta0 = self.initial_angle
        fp, ep, bp = self.flexor.to_array(), self.extensor.to_array(), self.body.to_array()
        a_e = max(float(self.extensor_activation.initial_level), ACTIVATION_FLOOR)
        k_e = self.extensor.se_stiffness

        def extensor_balance(s: float) -> float:
            return k_e * s - a_e * torque_angle(theta0 - s, ep) * ep[H_ISOMETRIC]

        s_max = a_e * ep[H_ISOMETRIC] / k_e  # T_θ ≤ 1 bounds the stretch
        s_e = brentq(extensor_balance, 0.0, s_max * (1 + 1e-12) + 1e-300, xtol=1e-16, rtol=1e-15)
        torque_e = k_e * s_e
        torque_f = (self.body.gravity_torque_coefficient * math.sin(theta0)
                    - passive_torque(theta0, bp) + torque_e)
        if torque_f <= 0.0:
            raise ModelError(
                "initial_angle",
                f"the arm cannot rest at {math.degrees(theta0):.2f}° with extensor level "
                f"{a_e:g}: the flexor would have to push ({torque_f:.3g} N·m); allowed: a start "
                "where the flexor pulls (raise initial_angle or lower the extensor level)")
        s_f = torque_f / self.flexor.se_stiffness
        level_f = torque_f / (fp[H_ISOMETRIC] * torque_angle(theta0 + s_f, fp))
        if self.flexor_activation.initial_level is not None:
            level_f = float(self.flexor_activation.initial_level)
        elif level_f > 1.0:
            raise ModelError(
                "initial_angle",
                f"holding the arm at {math.degrees(theta0):.2f}° needs flexor activation "
                f"{level_f:.3f} > 1; allowed: a start the flexor can hold (activation ≤ 1)")
        state = np.array([theta0, 0.0, theta0 + s_f, theta0 - s_e])
        return InitialState(state, level_f, float(self.extensor_activation.initial_level),
                            torque_f, torque_e)

    def pack(self) -> PackedModel:
        """The arrays the compiled solvers read (activation initial levels resolved)."""
        start = self.initial_state()
        return PackedModel(
            self.body.to_array(), self.flexor.to_array(), self.extensor.to_array(),
            self.flexor_activation.to_array(start.flexor_level),
            self.extensor_activation.to_array(start.extensor_level),
        )


def default_model() -> ElbowModel:
    """The built-in 5 kg dumbbell curl of MODEL.md (θ0 = 10°, 3.0 s)."""
    return ElbowModel()
