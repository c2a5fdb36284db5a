"""The model: planar chains of segments, torque generator units, activation profiles."""

from .activation import ActivationDynamics, ActivationProfile, Ramp
from .body import BodyParameters
from .chain import ChainModel, ChainStart, Joint, PackedChain, PointLoad, Segment, Unit, as_chain
from .contact import GroundContact, Point
from .elbow import ElbowModel, InitialState, default_model
from .torque_generator import TorqueGeneratorUnit

__all__ = [
    "ActivationDynamics",
    "ActivationProfile",
    "BodyParameters",
    "ChainModel",
    "ChainStart",
    "ElbowModel",
    "GroundContact",
    "InitialState",
    "Joint",
    "PackedChain",
    "Point",
    "PointLoad",
    "Ramp",
    "Segment",
    "TorqueGeneratorUnit",
    "Unit",
    "as_chain",
    "default_model",
]
