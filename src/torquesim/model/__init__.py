"""The elbow model: body, torque generator units, activation profiles."""

from .activation import ActivationProfile, Ramp
from .body import BodyParameters
from .elbow import STATE_NAMES, ElbowModel, InitialState, PackedModel, default_model
from .torque_generator import TorqueGeneratorUnit

__all__ = [
    "STATE_NAMES",
    "ActivationProfile",
    "BodyParameters",
    "ElbowModel",
    "InitialState",
    "PackedModel",
    "Ramp",
    "TorqueGeneratorUnit",
    "default_model",
]
