"""The model: planar chains of segments, torque generator units, activation profiles.

Names are imported on first use (PEP 562), so that the list of presets (`preset_names`) can
be read without loading Numba.
"""

from .._lazy import lazy_exports

_EXPORTS = {
    "ActivationDynamics": "activation", "ActivationProfile": "activation", "Ramp": "activation",
    "BodyParameters": "body", "ChainModel": "chain", "ChainStart": "chain", "Joint": "chain",
    "PackedChain": "chain", "PointLoad": "chain", "Segment": "chain", "Unit": "chain",
    "as_chain": "chain", "GroundContact": "contact", "Point": "contact",
    "ElbowModel": "elbow", "InitialState": "elbow", "default_model": "elbow",
    "TorqueGeneratorUnit": "torque_generator",
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)

__all__ = sorted(_EXPORTS)
