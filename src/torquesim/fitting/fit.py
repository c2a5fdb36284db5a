"""The fit: inverse-dynamics start, differential evolution, Nelder-Mead polish.

Budgets are counted in generations and simulations, never in wall time, so a fit is
reproducible with the same seed on any machine (``max_time`` is an optional safety cap that
gives up that guarantee). The optimiser state is checkpointed periodically and on
interruption; a resumed fit continues from the saved population (differential evolution keeps
the best member, so resuming never loses the best-so-far).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution, minimize
from scipy.stats import qmc

from ..errors import ModelError, check_range
from ..io.atomic import write_atomic
from .initial_guess import initial_guess
from .parameters import PARAMETER_NAMES
from .problem import FitProblem

CHECKPOINT_VERSION = 1


@dataclass(frozen=True)
class SearchSettings:
    """How hard the optimiser works.

    Attributes
    ----------
    seed : int
        Random seed; the same seed gives the same fit. Default 1.
    generations : int
        Differential-evolution generations. Default 300. Bounds [0, 100000].
    population_per_parameter : int
        Population = this × the number of free parameters (SciPy's ``popsize``). Default 10.
        Bounds [2, 100].
    polish_simulations : int
        Nelder-Mead simulations after the search. Default 4000. Bounds [0, 10^7].
    max_time : float or None
        Optional wall-time cap, s (the fit then depends on machine speed). Default None.
    checkpoint_every : float
        Seconds between checkpoints. Default 10.
    """

    seed: int = 1
    generations: int = 300
    population_per_parameter: int = 10
    polish_simulations: int = 4000
    max_time: float | None = None
    checkpoint_every: float = 10.0

    def __post_init__(self) -> None:
        check_range("seed", self.seed, 0, 2**32 - 1)
        check_range("generations", self.generations, 0, 100_000)
        check_range("population_per_parameter", self.population_per_parameter, 2, 100)
        check_range("polish_simulations", self.polish_simulations, 0, 10**7)
        if self.max_time is not None:
            check_range("max_time", self.max_time, 0.0, low_open=True, unit="s")
        check_range("checkpoint_every", self.checkpoint_every, 0.0, low_open=True, unit="s")


@dataclass
class FitOutcome:
    """What a fit found. ``x`` is the 18-vector; scores are in degrees."""

    x: np.ndarray
    score: float
    initial_x: np.ndarray
    initial_score: float
    simulations: int
    failed_simulations: int
    wall_time: float
    generations_done: int
    polish_done: int
    interrupted: bool
    history: list = field(default_factory=list)  # (simulations, wall time, best score)


def fingerprint(problem: FitProblem) -> str:
    """Hash of what a checkpoint is only valid for: target, model, space, technique."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(problem.target.time).tobytes())
    h.update(np.ascontiguousarray(problem.target.angle).tobytes())
    h.update(repr((problem.model.body, problem.model.flexor, problem.model.extensor,
                   problem.space, problem.method, problem.step, problem.weight_velocity,
                   problem.weight_end)).encode())
    return h.hexdigest()[:16]


def save_checkpoint(path, state: dict) -> None:
    """Write the optimiser state atomically (``.npz``)."""
    def write(tmp: Path) -> None:
        with tmp.open("wb") as fh:
            np.savez(fh, meta=json.dumps({k: v for k, v in state.items()
                                          if not isinstance(v, np.ndarray)}),
                     **{k: v for k, v in state.items() if isinstance(v, np.ndarray)})

    write_atomic(path, write)


#: What a checkpoint must hold to be resumed.
CHECKPOINT_KEYS = ("version", "fingerprint", "seed", "population_per_parameter", "stage",
                   "generations_done", "polish_done", "simulations", "failed", "best_score",
                   "best_x", "initial_x", "population", "history")


def load_checkpoint(path, problem: FitProblem, settings: SearchSettings) -> dict:
    """Read a checkpoint written by :func:`save_checkpoint` for this problem and these search
    settings (the seed and population size included; a larger generation or polish budget may
    differ). Never unpickles; an empty, truncated or foreign file is a one-line
    :class:`ModelError` saying which."""
    name = repr(str(path))
    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
    except OSError as exc:
        raise ModelError("resume", f"cannot read checkpoint {name}: {exc.strerror or exc}") \
            from None
    if magic != b"PK\x03\x04":  # every .npz is a zip archive
        raise ModelError("resume", f"{name} is {'empty' if not magic else 'not a zip file'}: "
                         "not a torquesim checkpoint; allowed: the fit_checkpoint.npz of an "
                         "earlier fit")
    try:
        with np.load(path, allow_pickle=False) as data:
            state = json.loads(str(data["meta"]))
            state.update({k: data[k] for k in data.files if k != "meta"})
    except Exception as exc:  # noqa: BLE001 - zip, npy and JSON damage all mean "corrupt"
        raise ModelError("resume", f"checkpoint {name} is corrupt or not a torquesim "
                         f"checkpoint ({type(exc).__name__}); allowed: the fit_checkpoint.npz "
                         "of an earlier fit, or start again without --resume") from None
    missing = [k for k in CHECKPOINT_KEYS if k not in state]
    if missing:
        raise ModelError("resume", f"{name} is not a torquesim checkpoint (no "
                         f"{', '.join(missing[:3])}); allowed: the fit_checkpoint.npz of an "
                         "earlier fit")
    if state["version"] != CHECKPOINT_VERSION or state["fingerprint"] != fingerprint(problem):
        raise ModelError("resume", f"checkpoint {name} belongs to another fit (target, "
                         "model, bounds, method or step differ); allowed: the same settings")
    for key in ("seed", "population_per_parameter"):
        if state[key] != getattr(settings, key):
            raise ModelError("resume", f"checkpoint {name} was made with {key} = "
                             f"{state[key]}, not {getattr(settings, key)}; allowed: the same "
                             f"{key} (or start again)")
    return state


def _initial_population(problem, guess, size, rng) -> np.ndarray:
    """Half Latin hypercube over the bounds, half a cloud around the inverse-dynamics guess
    (5 % of each range), with the guess itself first."""
    free = problem.space.free
    lo = np.array(problem.space.lower)[free]
    hi = np.array(problem.space.upper)[free]
    pop = np.empty((size, free.size))
    near = size // 2
    pop[0] = guess[free]
    pop[1:near] = np.clip(guess[free] + rng.normal(0.0, 0.05, (near - 1, free.size)) * (hi - lo),
                          lo, hi)
    pop[near:] = qmc.scale(qmc.LatinHypercube(d=free.size, rng=rng).random(size - near), lo, hi)
    return pop


def _explain_failed_start(problem: FitProblem, x) -> None:
    """The start cannot be simulated with the fit's explicit technique: say why and stop
    (a fit whose every run breaks the RK4 stability limit would fit numerical artefacts)."""
    from ..solvers.simulate import simulate

    run = simulate(problem.model_for(x), problem.method, problem.step,
                   coupling=problem.coupling, check=False)
    if run.stability is not None and run.stability.exceeded:
        raise ModelError("step", f"{problem.step * 1e3:.4g} ms is beyond explicit RK4's "
                         f"stability limit on this motion (step/τ = "
                         f"{run.stability.max_step_ratio:.3g} > 2.785 in the "
                         f"{run.stability.unit}); allowed: --step ≤ "
                         f"{run.stability.largest_safe_step * 1e3:.3g} ms, or --method imex")


def run_fit(problem: FitProblem, settings: SearchSettings = SearchSettings(), *,
            checkpoint: str | Path | None = None, resume: dict | None = None,
            progress: Callable[[str], None] | None = None,
            tick: Callable[[str, int, int], None] | None = None,
            should_stop: Callable[[], bool] = lambda: False) -> FitOutcome:
    """Fit the activation ramps of ``problem`` (module docstring).

    ``should_stop`` is polled once per generation / polish simulation batch; when it returns
    True the fit stops, checkpoints and returns the best so far with ``interrupted=True``.
    ``progress(message)`` receives a line now and then; ``tick(stage, done, total)`` is called
    after every generation (stage ``"search"``) and polish step (``"polish"``, counted in
    simulations), for a progress bar.
    """
    say = progress or (lambda _msg: None)
    space = problem.space
    free = space.free
    if free.size == 0:
        raise ModelError("freeze", "every parameter is frozen; allowed: at least one free")
    start = time.perf_counter()
    prior_wall = 0.0
    if resume is None:
        guess = initial_guess(problem.model, problem.target, space)
        scores, failed = problem.evaluate(guess)
        guess_score = float(scores[0])
        if failed[0] and problem.explicit_muscles:
            _explain_failed_start(problem, guess)
        say(f"initial guess (inverse dynamics): {guess_score:.3f} deg RMS")
        state = {"version": CHECKPOINT_VERSION, "fingerprint": fingerprint(problem),
                 "seed": settings.seed,
                 "population_per_parameter": settings.population_per_parameter,
                 "stage": "search", "generations_done": 0, "polish_done": 0,
                 "simulations": problem.simulations, "failed": problem.failed_simulations,
                 "initial_score": guess_score, "initial_x": guess, "best_x": guess,
                 "best_score": guess_score, "history": [[problem.simulations, 0.0,
                                                         guess_score]]}
        rng = np.random.default_rng(settings.seed)
        size = settings.population_per_parameter * free.size
        state["population"] = _initial_population(problem, guess, size, rng)
    else:
        state = dict(resume)
        problem.simulations = int(state["simulations"])
        problem.failed_simulations = int(state["failed"])
        prior_wall = float(state.get("wall_time", 0.0))
        state["history"] = [list(h) for h in np.atleast_2d(state["history"])]
        # A larger budget than the checkpoint's reopens the search or the polish.
        if int(state["generations_done"]) < settings.generations:
            state["stage"] = "search"
        elif int(state["polish_done"]) < settings.polish_simulations:
            state["stage"] = "polish"
        say(f"resuming at {state['stage']}: {state['generations_done']} generations, "
            f"best {float(state['best_score']):.3f} deg RMS")
    base = np.array(state["initial_x"], dtype=float)
    last_save = [time.perf_counter()]
    interrupted = [False]

    def elapsed() -> float:
        return prior_wall + time.perf_counter() - start

    def out_of_time() -> bool:
        return settings.max_time is not None and elapsed() >= settings.max_time

    def keep(x_free, score) -> None:
        if score < state["best_score"]:
            state["best_score"] = float(score)
            state["best_x"] = space.full(x_free, base)
        state["simulations"] = problem.simulations
        state["failed"] = problem.failed_simulations
        state["wall_time"] = elapsed()

    def save(force=False) -> None:
        if checkpoint is not None and (force or time.perf_counter() - last_save[0]
                                       >= settings.checkpoint_every):
            state["wall_time"] = elapsed()
            save_checkpoint(checkpoint, {**state, "history": np.array(state["history"])})
            last_save[0] = time.perf_counter()

    def objective(x_free_columns):
        rows = np.array([space.full(x, base) for x in np.atleast_2d(x_free_columns.T)])
        return problem.evaluate(rows)[0]

    remaining = settings.generations - int(state["generations_done"])
    if state["stage"] == "search" and remaining > 0:
        bounds = space.bounds()
        if resume is not None:  # the best so far (perhaps from a polish) takes part
            state["population"] = np.array(state["population"], dtype=float)
            state["population"][-1] = np.asarray(state["best_x"])[free]

        def on_generation(intermediate_result):
            state["generations_done"] += 1
            state["population"] = np.array(intermediate_result.population)
            keep(intermediate_result.x, intermediate_result.fun)
            state["history"].append([problem.simulations, elapsed(), state["best_score"]])
            if tick:
                tick("search", int(state["generations_done"]), settings.generations)
            if state["generations_done"] % 10 == 0:
                say(f"search  generation {state['generations_done']}/{settings.generations}  "
                    f"best {state['best_score']:.3f} deg RMS  {problem.simulations} "
                    f"simulations  {elapsed():.1f} s")
            save()
            if should_stop():
                interrupted[0] = True
            return interrupted[0] or out_of_time()

        # Each resumed segment draws from its own stream: seed and generation fix it.
        differential_evolution(
            objective, bounds, init=np.clip(state["population"], *np.array(bounds).T),
            maxiter=remaining, rng=np.random.default_rng([settings.seed,
                                                          int(state["generations_done"])]),
            vectorized=True, updating="deferred", polish=False, tol=0.0,
            mutation=(0.5, 1.0), recombination=0.9, callback=on_generation)
        state["simulations"] = problem.simulations
    if not interrupted[0] and not out_of_time() and state["stage"] == "search":
        state["stage"] = "polish"
        save(force=True)
    budget = settings.polish_simulations - int(state["polish_done"])
    if state["stage"] == "polish" and budget > 0 and not interrupted[0] and not out_of_time():
        say(f"polish  Nelder-Mead from {state['best_score']:.3f} deg RMS")
        before = problem.simulations
        done_before = int(state["polish_done"])

        def single(x_free):
            return objective(np.asarray(x_free)[:, None])[0]

        def on_step(intermediate_result):
            keep(intermediate_result.x, intermediate_result.fun)
            state["polish_done"] = done_before + problem.simulations - before
            if tick:
                tick("polish", int(state["polish_done"]), settings.polish_simulations)
            save()
            if should_stop():
                interrupted[0] = True
            if interrupted[0] or out_of_time():
                raise StopIteration

        result = minimize(single, state["best_x"][free], method="Nelder-Mead",
                          bounds=space.bounds(), callback=on_step,
                          options={"maxfev": budget, "xatol": 1e-6, "fatol": 1e-6,
                                   "adaptive": True})
        keep(result.x, result.fun)
        state["polish_done"] = done_before + problem.simulations - before
        state["history"].append([problem.simulations, elapsed(), state["best_score"]])
        if not interrupted[0] and not out_of_time():
            state["stage"] = "done"
    if state["stage"] == "polish" and budget <= 0:
        state["stage"] = "done"
    save(force=True)
    return FitOutcome(np.array(state["best_x"]), float(state["best_score"]),
                      np.array(state["initial_x"]), float(state["initial_score"]),
                      problem.simulations, problem.failed_simulations, elapsed(),
                      int(state["generations_done"]), int(state["polish_done"]), interrupted[0],
                      [list(h) for h in state["history"]])


def parameter_table(x) -> dict[str, float]:
    """Name → value of an 18-vector."""
    return {name: float(v) for name, v in zip(PARAMETER_NAMES, x, strict=True)}
