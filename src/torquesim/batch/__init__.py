"""Many runs on Dask distributed: batch fits (`fit_many`) and Monte Carlo or grid
sweeps over model parameters (`sweep`), on a local cluster or an existing scheduler."""

from .fits import fit_many
from .sweep import sweep

__all__ = ["fit_many", "sweep"]
