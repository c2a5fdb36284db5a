"""The elbow parametrisation of the model (docs/model.md §1–§3): body, flexor and extensor
units, their activation, and the start, as in the abstract. It converts to a one-segment
`ChainModel` (`to_chain`), which every solver runs; its state is the chain's,
y = (θ, ω, θ_cc,F, θ_cc,E) in rad and rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from ..errors import ModelError, check_range
from .activation import ActivationProfile, Ramp
from .body import BodyParameters
from .torque_generator import TorqueGeneratorUnit


class InitialState(NamedTuple):
    """Static equilibrium at rest (docs/model.md §3)."""

    state: np.ndarray  #: (θ0, 0, θ_cc,F, θ_cc,E), rad
    flexor_level: float  #: a_0,F used in the run
    extensor_level: float  #: a_0,E
    flexor_torque: float  #: T_F(0), N·m
    extensor_torque: float  #: T_E(0), N·m


def default_flexor_activation() -> ActivationProfile:
    """The fitted flexor profile of the default curl (docs/model.md §3)."""
    return ActivationProfile(None, (Ramp(0.058, 0.311, 0.556), Ramp(0.498, 0.613, 0.227),
                                    Ramp(0.511, 0.462, 0.26)))


def default_extensor_activation() -> ActivationProfile:
    """Constant extensor co-activation 0.1 as three flat ramps (docs/model.md §3)."""
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
        """Static equilibrium at rest at θ0 with ω_cc = 0 in both units (docs/model.md §3), as
        solved by `ChainModel.initial_state` on `to_chain`.

        The extensor SE stretch s solves k_E·s = a_0,E·T_θ,E(θ0 − s)·h_E(0); the flexor then
        carries T_F = G·sin θ0 − T_p(θ0) + T_E, so s_F = T_F/k_F and
        a_0,F = T_F / (h_F(0)·T_θ,F(θ0 + s_F)). If the flexor profile gives its own initial
        level, that level is used and the flexor CE starts away from isometric.
        """
        try:
            start = self.to_chain(check=False).initial_state()
        except ModelError as exc:
            raise ModelError("initial_angle", exc.reason) from None
        return InitialState(start.state, float(start.levels[0]), float(start.levels[1]),
                            float(start.torques[0]), float(start.torques[1]))

    def to_chain(self, check: bool = True):
        """This elbow as a one-segment `ChainModel` (joint
        ``elbow``, units ``elbow_flexor`` and ``elbow_extensor``, the dumbbell a point load)."""
        from .chain import ChainModel, Joint, PointLoad, Segment, Unit

        b = self.body
        segment = Segment("forearm_hand", b.segment_mass, b.segment_com_distance,
                          b.segment_inertia, b.dumbbell_distance,
                          (PointLoad("dumbbell", b.dumbbell_mass, b.dumbbell_distance,
                                     b.dumbbell_inertia),))
        joint = Joint("elbow", self.initial_angle, b.endstop_torque, b.endstop_angle_scale,
                      b.endstop_lower_angle, b.endstop_upper_angle)
        units = (Unit("elbow_flexor", "elbow", 1, self.flexor, self.flexor_activation),
                 Unit("elbow_extensor", "elbow", -1, self.extensor, self.extensor_activation))
        fields = dict(name="elbow_curl", segments=(segment,), joints=(joint,), units=units,
                      gravity=b.gravity, duration=self.duration)
        if check:
            return ChainModel(**fields)
        chain = object.__new__(ChainModel)
        for key, value in dict(base_angle=0.0, notes=(), **fields).items():
            object.__setattr__(chain, key, value)
        return chain


def default_model() -> ElbowModel:
    """The built-in 5 kg dumbbell curl of docs/model.md (θ0 = 10°, 3.0 s)."""
    return ElbowModel()
