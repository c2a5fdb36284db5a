"""Scoring a generation on Dask: the problem is sent to every worker once, each generation
is split into one chunk per worker (one task each, `torquesim.batch.engine.run_tasks`), and
the chunks' scores are put back in order. A candidate's score does not depend on where it
ran, so the search is the same on any number of workers."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from .problem import OptimiseProblem


def score_chunk(problem: OptimiseProblem, rows: np.ndarray):
    """(costs, nominal values, robust values, failures by reason, simulations) of ``rows``
    on a worker (Numba limited to the worker's one thread)."""
    from ..batch.engine import single_threaded

    single_threaded()
    problem.simulations, problem.failures = 0, Counter()
    cost, nominal, robust = problem.score(rows)
    return cost, nominal, robust, problem.failures, problem.simulations


class DaskScorer:
    """``evaluate(rows)`` for `optimise_population`: the rows scored on the workers of
    ``client``, the problem's counters kept up to date here."""

    def __init__(self, client, problem: OptimiseProblem):
        from ..batch.engine import workers_of

        self.client, self.problem = client, problem
        self.workers = workers_of(client)
        self.remote = client.scatter(problem, broadcast=True)

    def __call__(self, rows):
        from ..batch.engine import run_tasks

        rows = np.atleast_2d(rows)
        size = math.ceil(len(rows) / self.workers)
        chunks = [rows[i:i + size] for i in range(0, len(rows), size)]
        parts: list = [None] * len(chunks)

        def keep(i, part):
            parts[i] = part

        run_tasks(self.client, [(score_chunk, (self.remote, chunk)) for chunk in chunks], keep)
        for part in parts:
            self.problem.failures.update(part[3])
            self.problem.simulations += part[4]
        return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))
