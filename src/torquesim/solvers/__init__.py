"""Solution techniques: monolithic and partitioned RK4, and an implicit reference."""

from .coupling import Coupling
from .result import COLUMNS, RunCost, SimulationResult, StabilityReport
from .simulate import METHODS, simulate, step_count

__all__ = ["COLUMNS", "METHODS", "Coupling", "RunCost", "SimulationResult", "StabilityReport",
           "simulate", "step_count"]
