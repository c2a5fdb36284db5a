"""Solution techniques: monolithic and partitioned RK4, IMEX, and SciPy's adaptive solvers.

Names are imported on first use (PEP 562): the technique registry (`techniques`) can be read
without loading Numba.
"""

from importlib import import_module

_EXPORTS = {
    "Coupling": "coupling", "RunCost": "result", "SimulationResult": "result",
    "StabilityReport": "result", "simulate": "simulation",
    "step_count": "simulation", "METHODS": "techniques", "TECHNIQUES": "techniques",
    "Technique": "techniques",
}


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_EXPORTS])


__all__ = ["METHODS", "TECHNIQUES", "Coupling", "RunCost", "SimulationResult", "StabilityReport",
           "Technique", "simulate", "step_count"]
