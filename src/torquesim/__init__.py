"""torquesim: torque-driven simulation of human motion.

A planar open chain of rigid segments (the default: forearm and hand holding a dumbbell,
turning about the elbow) is driven by Hill-type torque generator units at its joints. The body
and muscle equations can be solved partitioned (each part its own integrator, exchanging at
step boundaries), monolithic (one RK4), IMEX, or by SciPy's adaptive solvers.

>>> import torquesim as ts
>>> result = ts.simulate(ts.default_model(), "monolithic", step=1e-4)   # doctest: +SKIP
>>> ts.save_result(result, "curl.sto")                                  # doctest: +SKIP
"""

from importlib.metadata import PackageNotFoundError, version

from .errors import ModelError, SimulationError
from .io import load_model, read_table, save_model, save_result
from .model import (
    ActivationProfile,
    BodyParameters,
    ChainModel,
    ElbowModel,
    Joint,
    PointLoad,
    Ramp,
    Segment,
    TorqueGeneratorUnit,
    Unit,
    default_model,
)
from .solvers import Coupling, SimulationResult, simulate

try:
    __version__ = version("torquesim")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = [
    "ActivationProfile",
    "BodyParameters",
    "ChainModel",
    "Coupling",
    "ElbowModel",
    "Joint",
    "ModelError",
    "PointLoad",
    "Ramp",
    "Segment",
    "SimulationError",
    "SimulationResult",
    "TorqueGeneratorUnit",
    "Unit",
    "__version__",
    "default_model",
    "load_model",
    "read_table",
    "save_model",
    "save_result",
    "simulate",
]
