"""Solution techniques: monolithic and partitioned RK4, IMEX, and SciPy's adaptive solvers."""

from .coupling import Coupling
from .result import RunCost, SimulationResult, StabilityReport, column_units
from .simulate import METHODS, simulate, step_count

__all__ = ["METHODS", "Coupling", "RunCost", "SimulationResult", "StabilityReport",
           "column_units", "simulate", "step_count"]
