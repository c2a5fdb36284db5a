"""Numerical studies of the solution techniques (``torquesim compare``)."""

from .cases import smooth_case, smooth_chain_case
from .checks import check_study
from .compare import calibrate, run_study, verdict, verdict_table

__all__ = ["calibrate", "check_study", "run_study", "smooth_case", "smooth_chain_case",
           "verdict", "verdict_table"]
