"""Fitting activation profiles to a measured motion (``torquesim fit``)."""

from .fit import FitOutcome, SearchSettings, run_fit
from .parameters import PARAMETER_NAMES, ParameterSpace
from .problem import FitProblem
from .target import Target, load_target, min_jerk_curl

__all__ = ["PARAMETER_NAMES", "FitOutcome", "FitProblem", "ParameterSpace", "SearchSettings",
           "Target", "load_target", "min_jerk_curl", "run_fit"]
