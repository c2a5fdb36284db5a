"""The project's `njit`: Numba's, with Python's cyclic garbage collector paused while Numba
compiles.

A cold first run spends most of its time in Numba's compiler, which builds and copies
millions of small Python objects (its intermediate representation of our kernels). Every
700 new objects start a collection, and the older generations' collections traverse every
object alive (NumPy's, SciPy's, Numba's own), again and again, for garbage that is freed
when the compilation ends. So the collector is paused from the start of the outermost
compilation (Numba's ``numba:compile`` event; compilations run one at a time, under Numba's
compiler lock) to its end, and what it left is collected then, at the collector's next run.
Runs of compiled code allocate no Python objects and are unaffected. What this saves on a
cold start is measured by ``benchmarks/bench_cold_start.py``."""

from __future__ import annotations

import gc

from numba import njit
from numba.core import event

__all__ = ["njit"]


class _CollectorPaused(event.Listener):
    """Pauses the garbage collector during the outermost ``numba:compile`` event."""

    def __init__(self) -> None:
        self.depth = 0
        self.was_enabled = False

    def on_start(self, _event) -> None:
        if self.depth == 0:
            self.was_enabled = gc.isenabled()
            gc.disable()
        self.depth += 1

    def on_end(self, _event) -> None:
        self.depth -= 1
        if self.depth == 0 and self.was_enabled:
            gc.enable()


event.register("numba:compile", _CollectorPaused())
