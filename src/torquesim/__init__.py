"""torquesim: torque-driven simulation of human motion.

A planar forearm-hand segment holding a dumbbell turns about the elbow, driven by a flexor and
an extensor Hill-type torque generator. The body and muscle equations can be solved
partitioned (each part its own RK4, exchanging at step boundaries) or monolithic (one RK4).

>>> import torquesim as ts
>>> result = ts.simulate(ts.default_model(), "monolithic", step=1e-4)   # doctest: +SKIP
>>> result.save("curl.sto")                                              # doctest: +SKIP
"""

from importlib.metadata import PackageNotFoundError, version

from .errors import ModelError, SimulationError
from .io import load_model, read_table, save_model
from .model import (
    ActivationProfile,
    BodyParameters,
    ElbowModel,
    Ramp,
    TorqueGeneratorUnit,
    default_model,
)
from .solvers import COLUMNS, Coupling, SimulationResult, simulate

try:
    __version__ = version("torquesim")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = [
    "COLUMNS",
    "ActivationProfile",
    "BodyParameters",
    "Coupling",
    "ElbowModel",
    "ModelError",
    "Ramp",
    "SimulationError",
    "SimulationResult",
    "TorqueGeneratorUnit",
    "__version__",
    "default_model",
    "load_model",
    "read_table",
    "save_model",
    "simulate",
]
