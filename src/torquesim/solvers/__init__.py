"""Solution techniques: monolithic and partitioned RK4, IMEX, and SciPy's adaptive solvers.

Names are imported on first use (PEP 562): the technique registry (`techniques`) can be read
without loading Numba.
"""

from .._lazy import lazy_exports

_EXPORTS = {
    "Coupling": "coupling", "RunCost": "result", "SimulationResult": "result",
    "StabilityReport": "result", "simulate": "simulation",
    "step_count": "simulation", "METHODS": "techniques", "TECHNIQUES": "techniques",
    "Technique": "techniques",
}


__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)


__all__ = ["METHODS", "TECHNIQUES", "Coupling", "RunCost", "SimulationResult", "StabilityReport",
           "Technique", "simulate", "step_count"]
