"""Studies of the solution techniques: test cases, convergence, accuracy against cost."""

from .cases import smooth_case, smooth_chain_case

__all__ = ["smooth_case", "smooth_chain_case"]
