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

from ._lazy import lazy_exports

try:
    __version__ = version("torquesim")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

#: Public name → the module that defines it. Imported on first use (PEP 562), so that
#: ``torquesim --help`` and other light commands do not load Numba, SciPy or Matplotlib.
_EXPORTS = {
    "ModelError": "errors", "SimulationError": "errors",
    "load_model": "io", "read_table": "io", "save_model": "io", "save_result": "io",
    "ActivationDynamics": "model", "ActivationProfile": "model", "BodyParameters": "model",
    "ChainModel": "model",
    "ElbowModel": "model", "GroundContact": "model", "Joint": "model", "Point": "model",
    "PointLoad": "model", "Ramp": "model",
    "Segment": "model", "TorqueGeneratorUnit": "model", "Unit": "model",
    "default_model": "model",
    "Coupling": "solvers", "SimulationResult": "solvers", "simulate": "solvers",
    "optimise": "optimisation",
}


__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)


__all__ = [
    "ActivationDynamics",
    "ActivationProfile",
    "BodyParameters",
    "ChainModel",
    "Coupling",
    "ElbowModel",
    "GroundContact",
    "Joint",
    "ModelError",
    "Point",
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
    "optimise",
    "read_table",
    "save_model",
    "save_result",
    "simulate",
]
