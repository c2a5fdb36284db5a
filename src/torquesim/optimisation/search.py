"""The search: CMA-ES (the maintained ``cmaes`` package) over the free parameters, each
scaled to [0, 1] across its bounds, starting at the starting model with step size ``sigma``.

Every generation's population is scored together (`OptimiseProblem.score`: compiled parallel
threads locally, or chunks on Dask workers through ``evaluate``). Budgets are counted in
generations, never in wall time, and a candidate's score does not depend on where it ran, so
the same seed gives the same optimum on any number of workers.

Checkpoints hold every generation's costs, never the optimiser's internals: a resumed search
replays them (asking CMA-ES for the same candidates from the same seed and telling it the
stored costs, no simulation) and continues, so it ends where an uninterrupted one does.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError, check_range
from ..fitting.objective import blas_on_one_thread
from ..io.checkpoint import read_checkpoint, save_checkpoint
from ..io.fingerprint import fingerprint as hash_parts
from .problem import FAILED_COST, OptimiseProblem

CHECKPOINT_VERSION = 1


@dataclass(frozen=True)
class OptimiseSettings:
    """How the search works.

    Attributes
    ----------
    seed : int
        Seed of CMA-ES; the same seed gives the same optimum. Default 1.
    generations : int
        Generations of CMA-ES. Default 60. Bounds [1, 100000].
    population : int or None
        Candidates per generation. Default None: CMA-ES's 4 + ⌊3·ln d⌋ for d free
        parameters. Bounds [4, 10000].
    sigma : float
        Initial step size as a fraction of each parameter's bounds. Default 0.2.
        Bounds (0, 1].
    checkpoint_every : float
        Seconds between checkpoints. Default 10.
    """

    seed: int = 1
    generations: int = 60
    population: int | None = None
    sigma: float = 0.2
    checkpoint_every: float = 10.0

    def __post_init__(self) -> None:
        check_range("seed", self.seed, 0, 2**32 - 1)
        check_range("generations", self.generations, 1, 100_000)
        if self.population is not None:
            check_range("population", self.population, 4, 10_000)
        check_range("sigma", self.sigma, 0.0, 1.0, low_open=True)
        check_range("checkpoint_every", self.checkpoint_every, 0.0, low_open=True, unit="s")

    def population_for(self, free: int) -> int:
        return self.population or 4 + int(3 * math.log(free))


@dataclass
class OptimiseOutcome:
    """What the search found. Values are the goals' (SI), costs the combined cost (lower is
    better; see
    `torquesim.optimisation.goals`)."""

    x: np.ndarray
    cost: float
    values: np.ndarray
    robust_values: np.ndarray
    start_x: np.ndarray
    start_cost: float
    start_values: np.ndarray
    start_robust_values: np.ndarray
    simulations: int
    failures: Counter
    generations_done: int
    population: int
    interrupted: bool
    converged: bool
    wall_time: float
    history: list = field(default_factory=list)  # (generation, simulations, best cost)


def fingerprint(problem: OptimiseProblem) -> str:
    """Hash of what a checkpoint is only valid for: model, space, goals, technique, copies."""
    goals = [(g.name, g.maximise, g.weight, g.joint, g.angle, g.label) for g in problem.goals]
    return hash_parts((problem.model3, problem.space, problem.method, problem.step, goals,
                       problem.robust, problem.robust_mode, problem.timing_error,
                       problem.perturbation_seed), problem.timing_errors)


CHECKPOINT_KEYS = ("version", "fingerprint", "seed", "population", "sigma",
                   "generations_done", "costs", "best_x", "simulations", "failures",
                   "history", "wall_time", "converged")


def load_checkpoint(path, problem: OptimiseProblem, settings: OptimiseSettings) -> dict:
    """Read a checkpoint of this problem and these settings (a larger ``generations`` may
    differ). Never unpickles; a foreign, empty or damaged file is a one-line `ModelError`."""
    name = repr(str(path))
    state = read_checkpoint(path, CHECKPOINT_KEYS,
                            "the optimise_checkpoint.npz of an earlier optimisation")
    if state["version"] != CHECKPOINT_VERSION or state["fingerprint"] != fingerprint(problem):
        raise ModelError("resume", f"checkpoint {name} belongs to another optimisation "
                         "(model, goals, bounds, technique, step or perturbations differ); "
                         "allowed: the same settings")
    own = {"seed": settings.seed, "sigma": settings.sigma,
           "population": settings.population_for(problem.space.free.size)}
    for key, value in own.items():
        if state[key] != value:
            raise ModelError("resume", f"checkpoint {name} was made with {key} = "
                             f"{state[key]}, not {value}; allowed: the same {key} (or start "
                             "again)")
    return state


@blas_on_one_thread
def optimise_population(problem: OptimiseProblem, settings: OptimiseSettings = OptimiseSettings(),
                        *, checkpoint=None, resume: dict | None = None,
                        progress: Callable[[str], None] | None = None,
                        tick: Callable[[int, int], None] | None = None,
                        should_stop: Callable[[], bool] = lambda: False,
                        evaluate: Callable | None = None) -> OptimiseOutcome:
    """Run CMA-ES on ``problem`` (module docstring). ``evaluate(X)`` scores full parameter
    vectors (rows) and returns what `OptimiseProblem.score` does (default: that, locally);
    ``should_stop`` is polled every generation (True: checkpoint and return the best so far,
    ``interrupted``); ``tick(done, total)`` reports generations."""
    from cmaes import CMA

    say = progress or (lambda _msg: None)
    score = evaluate or problem.score
    space = problem.space
    free = space.free
    low = np.array(space.lower)[free]
    span = np.array(space.upper)[free] - low
    start_x = space.full(problem.x0[free], problem.x0)
    size = settings.population_for(free.size)
    began = time.perf_counter()

    def full(u) -> np.ndarray:
        return np.array([space.full(low + row * span, problem.x0) for row in u])

    start_cost, start_values, start_robust = (a[0] for a in score(start_x[None, :]))
    if start_cost >= FAILED_COST:
        raise ModelError("robust", "a perturbed copy of the starting model fails; allowed: a "
                         "smaller --timing-error or fewer --robust copies")
    cma = CMA(mean=np.clip((problem.x0[free] - low) / span, 0.0, 1.0), sigma=settings.sigma,
              bounds=np.tile([0.0, 1.0], (free.size, 1)), seed=settings.seed,
              population_size=size)
    costs: list[np.ndarray] = []
    best = {"cost": float(start_cost), "x": start_x, "values": start_values,
            "robust": start_robust}
    history = [[0, problem.simulations, float(start_cost)]]
    prior_wall, converged = 0.0, False
    if resume is not None:
        for row in np.atleast_2d(resume["costs"]):
            asked = [cma.ask() for _ in range(size)]
            cma.tell(list(zip(asked, row.tolist(), strict=True)))
            costs.append(np.array(row))
        best_x = np.asarray(resume["best_x"], dtype=float)
        if not np.array_equal(best_x, start_x):
            cost, values, robust = (a[0] for a in score(best_x[None, :]))
            best = {"cost": float(cost), "x": best_x, "values": values, "robust": robust}
        problem.simulations = int(resume["simulations"])
        problem.failures = Counter(resume["failures"])
        history = [list(h) for h in resume["history"]]
        prior_wall = float(resume["wall_time"])
        converged = bool(resume["converged"])
        say(f"resuming after generation {len(costs)}: best cost {best['cost']:.5g}")
    last_save = time.perf_counter()

    def state() -> dict:
        return {"version": CHECKPOINT_VERSION, "fingerprint": fingerprint(problem),
                "seed": settings.seed, "population": size, "sigma": settings.sigma,
                "generations_done": len(costs),
                "costs": np.array(costs).reshape(len(costs), size),
                "best_x": np.asarray(best["x"]), "simulations": problem.simulations,
                "failures": dict(problem.failures), "history": history,
                "wall_time": prior_wall + time.perf_counter() - began, "converged": converged}

    interrupted = False
    while len(costs) < settings.generations and not converged:
        if should_stop():
            interrupted = True
            break
        asked = [cma.ask() for _ in range(size)]
        candidates = full(np.array(asked))
        cost, values, robust = score(candidates)
        cma.tell(list(zip(asked, cost.tolist(), strict=True)))
        costs.append(np.asarray(cost, dtype=float))
        i = int(np.argmin(cost))
        if cost[i] < best["cost"]:
            best = {"cost": float(cost[i]), "x": candidates[i], "values": values[i],
                    "robust": robust[i]}
        history.append([len(costs), problem.simulations, best["cost"]])
        converged = bool(cma.should_stop())
        if tick is not None:
            tick(len(costs), settings.generations)
        if checkpoint is not None and time.perf_counter() - last_save >= settings.checkpoint_every:
            save_checkpoint(checkpoint, state())
            last_save = time.perf_counter()
    if checkpoint is not None:
        save_checkpoint(checkpoint, state())
    return OptimiseOutcome(np.asarray(best["x"]), best["cost"], np.asarray(best["values"]),
                           np.asarray(best["robust"]), start_x, float(start_cost),
                           np.asarray(start_values), np.asarray(start_robust),
                           problem.simulations, Counter(problem.failures), len(costs), size,
                           interrupted, converged,
                           prior_wall + time.perf_counter() - began, history)
