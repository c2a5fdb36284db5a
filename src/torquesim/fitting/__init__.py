"""Fitting activation profiles to a measured motion (``torquesim fit``)."""

from .fit import FitOutcome, SearchSettings, fit_to_accuracy, run_fit
from .parameters import ParameterSpace, parameter_names
from .problem import FitProblem
from .target import Target, load_target, min_jerk_curl

__all__ = ["FitOutcome", "FitProblem", "ParameterSpace", "SearchSettings", "Target",
           "fit_to_accuracy", "load_target", "min_jerk_curl", "parameter_names", "run_fit"]
