"""The fit: an inverse-dynamics start, then one of two searches.

``least-squares`` (default): SciPy's trust-region reflective least squares on the residual
vector (`torquesim.fitting.objective`) from the inverse-dynamics start and from
``starts − 1`` seeded perturbations of it; the Jacobian comes from forward differences whose
(free parameters) simulations run in parallel in compiled code. Its cost grows with the
number of parameters only through the Jacobian, so chains fit in seconds.

``global``: differential evolution over the bounds (population 10 × free parameters), then a
Nelder-Mead polish: robust when the start is poor, but ~10× the simulations.

Budgets are counted in iterations, generations and simulations, never in wall time, so a fit
is reproducible with the same seed on any machine (``max_time`` is an optional safety cap
that gives up that guarantee). The state is checkpointed periodically and on interruption;
a resumed fit continues where it stopped (a least-squares start that was cut off is run again
from its beginning, so the result is the one an uninterrupted fit gives).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution, minimize
from scipy.stats import qmc

from ..errors import ModelError, check_range
from ..io.checkpoint import read_checkpoint, save_checkpoint
from ..io.fingerprint import fingerprint as hash_parts
from .initial_guess import initial_guess
from .objective import FAILED_SCORE, blas_on_one_thread
from .problem import FitProblem

CHECKPOINT_VERSION = 2
SEARCHES = ("least-squares", "global")
#: Difference step of the Jacobian (s for delays and durations, activation for levels; for a
#: model field this times its range, `ParameterSpace.difference_scales`): forward, backward
#: where the upper bound is closer.
DIFFERENCE_STEP = 1e-6
JACOBIANS = ("forward", "central")
#: Residual evaluations each least-squares start gets before the best one is refined: at
#: least `SCREEN_EVALUATIONS`, and one per `SCREEN_PARAMETERS_PER_EVALUATION` free
#: parameters (`screen_evaluations`).
SCREEN_EVALUATIONS = 6
SCREEN_PARAMETERS_PER_EVALUATION = 4


def _better_start(problem, guess, guess_score, failed, say):
    """The inverse-dynamics guess, or on a free body the model's own activation ramps where
    they simulate closer to the target (a preset or a fitted model already holds a plausible
    pattern; inverse dynamics can miss a balance-sensitive movement by tens of degrees).
    Frozen parameters keep the guess's values."""
    from ..model.chain import as_chain
    from .parameters import own_vector

    base = as_chain(problem.base_model) if problem.base_model is not None else None
    own = own_vector(base) if base is not None and base.base == "free" else None
    if own is not None:  # with the guess's model fields
        own = np.concatenate([own, guess[own.size:]])
    if own is None or own.size != guess.size:
        return guess, guess_score, failed
    own = np.clip(own, problem.space.lower, problem.space.upper)
    frozen = np.setdiff1d(np.arange(guess.size), problem.space.free)
    own[frozen] = guess[frozen]
    scores, own_failed = problem.evaluate(own)
    if own_failed[0] or not float(scores[0]) < guess_score:
        say(f"initial guess (inverse dynamics): {guess_score:.3f} deg")
        return guess, guess_score, failed
    say(f"initial guess: the model's own ramps, {float(scores[0]):.3f} deg (inverse "
        f"dynamics {guess_score:.3f} deg)")
    return own, float(scores[0]), own_failed


def screen_evaluations(free_parameters: int) -> int:
    """Residual evaluations that screen each least-squares start: 6 for the elbow's 18
    parameters, 9 for the arm raise's 36, 14 for the squat jump's 54. Measured on the squat
    jump fitted to two jumps the preset did not make (`benchmarks/bench_jump_fit_unseen.py`):
    with 6, the best-looking start was the wrong one and the fit stopped at 1.96° and 0.78°
    of objective (400 refining evaluations instead of 200: 1.88°); with 12 and 20 both reached
    ≤ 0.011°."""
    return max(SCREEN_EVALUATIONS, math.ceil(free_parameters / SCREEN_PARAMETERS_PER_EVALUATION))


@dataclass(frozen=True)
class SearchSettings:
    """Which search, and how hard it works.

    Attributes
    ----------
    search : str
        ``least-squares`` (default) or ``global`` (module docstring).
    seed : int
        Random seed; the same seed gives the same fit. Default 1.
    starts : int
        Least squares: the inverse-dynamics start plus ``starts − 1`` perturbed copies of it
        (normal, 10 % of each range), each screened with a few iterations; the best is
        refined. Default 4. Bounds [1, 100].
    iterations : int
        Least squares: residual evaluations of the refinement of the best start (most also
        cost a Jacobian). Default 200. Bounds [1, 100000].
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
    jacobian : str
        Least squares: the Jacobian's differences, ``forward`` (default: one simulation per
        free parameter, reusing the residual just evaluated) or ``central`` (two, accurate
        to second order; torquesim 0.2.0's). Measured on targets other muscle models made
        (`benchmarks/bench_fit_other_model.py`): no better fit for twice the simulations.
    """

    search: str = "least-squares"
    seed: int = 1
    starts: int = 4
    iterations: int = 200
    generations: int = 300
    population_per_parameter: int = 10
    polish_simulations: int = 4000
    max_time: float | None = None
    checkpoint_every: float = 10.0
    jacobian: str = "forward"

    def __post_init__(self) -> None:
        if self.jacobian not in JACOBIANS:
            raise ModelError("jacobian", f"{self.jacobian!r}; allowed: {', '.join(JACOBIANS)}")
        if self.search not in SEARCHES:
            raise ModelError("search", f"{self.search!r}; allowed: {', '.join(SEARCHES)}")
        check_range("seed", self.seed, 0, 2**32 - 1)
        check_range("starts", self.starts, 1, 100)
        check_range("iterations", self.iterations, 1, 100_000)
        check_range("generations", self.generations, 0, 100_000)
        check_range("population_per_parameter", self.population_per_parameter, 2, 100)
        check_range("polish_simulations", self.polish_simulations, 0, 10**7)
        if self.max_time is not None:
            check_range("max_time", self.max_time, 0.0, low_open=True, unit="s")
        check_range("checkpoint_every", self.checkpoint_every, 0.0, low_open=True, unit="s")


@dataclass
class FitOutcome:
    """What a fit found. ``x`` is the parameter vector; scores are in degrees. ``generations``
    counts least-squares starts for that search."""

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
    #: The budget the last search stage stopped on instead of its tolerance ("" if none).
    capped: str = ""


def fingerprint(problem: FitProblem) -> str:
    """Hash of what a checkpoint is only valid for: target, model, space, technique."""
    channels = (problem.target_channels, tuple(problem.target.channels), problem.weight_grf,
                problem.weight_com) if problem.target.channels else ()
    return hash_parts(np.asarray(problem.target.time, dtype=float),
                      np.asarray(problem.target.angles, dtype=float),  # every scored joint
                      (problem.model, problem.space, problem.method, problem.step,
                       problem.weight_velocity, problem.weight_end, problem.weight_effort,
                       problem.weights.tolist(), problem.target.joints), *channels)


#: What a checkpoint must hold to be resumed.
CHECKPOINT_KEYS = ("version", "fingerprint", "search", "seed", "population_per_parameter",
                   "starts", "stage", "generations_done", "polish_done", "simulations", "failed",
                   "best_score", "best_x", "initial_x", "population", "history")


def load_checkpoint(path, problem: FitProblem, settings: SearchSettings) -> dict:
    """Read a checkpoint written by `save_checkpoint` for this problem and these search
    settings (the seed and population size included; a larger generation or polish budget may
    differ). Never unpickles; an empty, truncated or foreign file is a one-line
    `ModelError` saying which."""
    name = repr(str(path))
    state = read_checkpoint(path, CHECKPOINT_KEYS, "the fit_checkpoint.npz of an earlier fit")
    if state["version"] != CHECKPOINT_VERSION or state["fingerprint"] != fingerprint(problem):
        raise ModelError("resume", f"checkpoint {name} belongs to another fit (target, "
                         "model, bounds, method, step or weights differ, or an older "
                         "torquesim made it); allowed: the same settings")
    for key in ("search", "seed", "population_per_parameter"):
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
    """The start cannot be simulated at the fit's step: if it breaks the RK4 stability limit
    (explicit muscles, or a ground contact, which every technique integrates explicitly), say
    so and stop (a fit whose every run breaks it would fit numerical artefacts)."""
    from ..solvers.simulation import simulate

    run = simulate(problem.model_for(x), problem.method, problem.step,
                   coupling=problem.coupling, check=False)
    if run.stability is not None and run.stability.exceeded:
        other = "" if run.stability.in_contact else ", or --method imex"
        raise ModelError("step", f"{problem.step * 1e3:.4g} ms is beyond explicit RK4's "
                         f"stability limit on this motion (step/τ = "
                         f"{run.stability.max_step_ratio:.3g} > 2.785 in the "
                         f"{run.stability.unit}); allowed: --step ≤ "
                         f"{run.stability.largest_safe_step * 1e3:.3g} ms{other}")


#: A fit's own RMS error per scored joint (simulated with its technique and step) and that of
#: the written model re-simulated with the reference solver must agree within this fraction
#: of the fit's RMS, or within `AGREEMENT_DEG`, whichever is larger.
AGREEMENT_FRACTION = 0.10
AGREEMENT_DEG = 0.02
#: At most this many halvings of the fit's step to reach that agreement.
MAX_REFINEMENTS = 4


#: The last reference re-simulation, as (its key, the run): see `reference_resimulation`.
_LAST_REFERENCE: dict = {}


def reference_resimulation(problem: FitProblem, x):
    """The model with parameters ``x`` re-simulated by the reference solver on the fit's step
    grid. The last such run is kept, so that the integration-error check of
    `fit_to_accuracy` and the summary (`torquesim.fitting.outputs.summarise`) read one Radau
    solve, not two of the same model (seconds each). Read it, do not change it."""
    from ..solvers.simulation import simulate

    model = problem.model_for(x)
    key = (model, problem.step)
    last = _LAST_REFERENCE.get("run")  # one read and one write: safe between threads
    if last is not None and last[0] == key:
        return last[1]
    run = simulate(model, "reference", output_step=problem.step, check=False)
    _LAST_REFERENCE["run"] = (key, run)
    return run


def integration_gap(problem: FitProblem, x) -> dict[str, tuple[float, float]]:
    """Per scored joint (RMS error of the fit's own simulation, RMS error of the reference
    re-simulation), deg, of the model with parameters ``x``."""
    from ..solvers.simulation import simulate

    model = problem.model_for(x)
    own = simulate(model, problem.method, problem.step, coupling=problem.coupling,
                   check=False, advise=False, tolerance=None)
    reference = reference_resimulation(problem, x)
    failed = {j: (math.inf, math.inf) for j in problem.target.joints}
    mine = problem.errors_deg(own) if own.success else failed
    theirs = problem.errors_deg(reference) if reference.success else failed
    return {j: (mine[j][0], theirs[j][0]) for j in problem.target.joints}


def integration_floor(problem: FitProblem, x) -> float:
    """The integration error of the fit's own simulation of the parameters ``x`` in the
    objective's units (deg): ‖r_h − r_h/2‖·2^p/(2^p − 1), r the residual vectors at the fit's
    step and at half of it, p the technique's order (`nominal_order`): Richardson's estimate,
    as `simulate`'s check makes a run's. Below it the objective measures the integration
    error, not the fit. Infinite when either run fails."""
    from ..solvers.techniques import nominal_order

    finer = replace(problem, step=problem.step / 2)
    row = np.asarray(x, dtype=float)[None, :]
    coarse, failed = problem.residuals(row)
    fine, failed_fine = finer.residuals(row)
    if failed[0] or failed_fine[0]:
        return math.inf
    p = nominal_order(problem.method, problem.coupling)
    return float(np.linalg.norm(coarse[0] - fine[0])) * 2**p / (2**p - 1)


def agrees(gap: dict[str, tuple[float, float]]) -> bool:
    """Whether every joint's fit RMS and reference RMS agree (`AGREEMENT_FRACTION`)."""
    return all(abs(ref - own) <= max(AGREEMENT_FRACTION * own, AGREEMENT_DEG)
               for own, ref in gap.values())


def fit_to_accuracy(problem: FitProblem, settings: SearchSettings = SearchSettings(), *,
                    checkpoint: str | Path | None = None, resume: dict | None = None,
                    progress: Callable[[str], None] | None = None,
                    tick: Callable[[str, int, int], None] | None = None,
                    should_stop: Callable[[], bool] = lambda: False
                    ) -> tuple[FitProblem, FitOutcome, list[dict]]:
    """`run_fit`, then control the fit's integration error: while the reference
    re-simulation of the fitted model and the fit's own simulation disagree on a joint's RMS
    error (`agrees`), continue the fit by least squares from the current parameters at
    half the step (at most `MAX_REFINEMENTS` times). So the headline error of the fit is
    that of the model it writes, simulated accurately.

    Returns (the problem at the final step, the outcome, the refinements: one dict per step
    tried with its per-joint fit and reference RMS)."""
    say = progress or (lambda _msg: None)
    outcome = run_fit(problem, settings, checkpoint=checkpoint, resume=resume,
                      progress=progress, tick=tick, should_stop=should_stop)
    refinements: list[dict] = []
    while not outcome.interrupted and outcome.score < FAILED_SCORE:
        gap = integration_gap(problem, outcome.x)
        agreed = agrees(gap)
        refinements.append({"step_s": problem.step, "joints": {
            j: {"rms_error_deg": own, "reference_rms_error_deg": ref}
            for j, (own, ref) in gap.items()}, "agree": agreed})
        if agreed or len(refinements) > MAX_REFINEMENTS:
            break
        worst = max(gap, key=lambda j: abs(gap[j][1] - gap[j][0]))
        finer = replace(problem, step=problem.step / 2, simulations=problem.simulations,
                        failed_simulations=problem.failed_simulations)
        say(f"integration error: at step {problem.step * 1e3:.4g} ms the fit's {worst} RMS "
            f"is {gap[worst][0]:.3f} deg but the reference re-simulation's "
            f"{gap[worst][1]:.3f} deg; continuing at {finer.step * 1e3:.4g} ms")
        more = run_fit(finer, replace(settings, search="least-squares", starts=1),
                       progress=progress, tick=tick, should_stop=should_stop, start=outcome.x)
        outcome = FitOutcome(more.x, more.score, outcome.initial_x, outcome.initial_score,
                             more.simulations, more.failed_simulations,
                             outcome.wall_time + more.wall_time, outcome.generations_done,
                             outcome.polish_done, more.interrupted,
                             outcome.history + [[h[0], h[1] + outcome.wall_time, h[2]]
                                                for h in more.history], more.capped)
        problem = finer
    return problem, outcome, refinements


class _Stop(Exception):
    """Raised inside a least-squares residual evaluation to stop the search."""


@blas_on_one_thread
def run_fit(problem: FitProblem, settings: SearchSettings = SearchSettings(), *,
            checkpoint: str | Path | None = None, resume: dict | None = None,
            progress: Callable[[str], None] | None = None,
            tick: Callable[[str, int, int], None] | None = None,
            should_stop: Callable[[], bool] = lambda: False,
            start: np.ndarray | None = None) -> FitOutcome:
    """Fit the activation ramps of ``problem`` (module docstring), from the inverse-dynamics
    guess or, given, the parameter vector ``start``.

    ``should_stop`` is polled at every simulation batch; when it returns True the fit stops,
    checkpoints and returns the best so far with ``interrupted=True``. ``progress(message)``
    receives a line now and then; ``tick(stage, done, total)`` is called as work is done
    (stages ``"least squares"`` counted in starts, ``"search"`` in generations, ``"polish"``
    in simulations), for a progress bar.
    """
    say = progress or (lambda _msg: None)
    space = problem.space
    free = space.free
    if free.size == 0:
        raise ModelError("freeze", "every parameter is frozen; allowed: at least one free")
    run = _Run(problem, settings, checkpoint, say, tick, should_stop)
    if resume is None:
        guess = initial_guess(problem) if start is None else np.asarray(start, dtype=float)
        scores, failed = problem.evaluate(guess)
        guess_score = float(scores[0])
        if start is None:
            guess, guess_score, failed = _better_start(problem, guess, guess_score, failed, say)
        if failed[0]:
            _explain_failed_start(problem, guess)
        say(f"initial guess: {guess_score:.3f} deg")
        floor = integration_floor(problem, guess) if settings.search == "least-squares" \
            else math.inf
        run.state = {"version": CHECKPOINT_VERSION, "fingerprint": fingerprint(problem),
                     "search": settings.search, "seed": settings.seed,
                     "population_per_parameter": settings.population_per_parameter,
                     "starts": settings.starts,
                     "stage": "search", "generations_done": 0, "polish_done": 0,
                     "simulations": problem.simulations, "failed": problem.failed_simulations,
                     "initial_score": guess_score, "initial_x": guess, "best_x": guess,
                     "integration_floor": floor,
                     "best_score": guess_score,
                     "history": [[problem.simulations, 0.0, guess_score]]}
        if settings.search == "global":
            rng = np.random.default_rng(settings.seed)
            size = settings.population_per_parameter * free.size
            run.state["population"] = _initial_population(problem, guess, size, rng)
        else:
            run.state["population"] = np.zeros((0, free.size))
    else:
        run.state = state = dict(resume)
        problem.simulations = int(state["simulations"])
        problem.failed_simulations = int(state["failed"])
        run.prior_wall = float(state.get("wall_time", 0.0))
        state["history"] = [list(h) for h in np.atleast_2d(state["history"])]
        state["best_x"] = np.asarray(state["best_x"], dtype=float)
        # A larger budget than the checkpoint's reopens the search or the polish.
        if settings.search == "least-squares":
            if state["stage"] != "done" or int(state["generations_done"]) < settings.starts:
                state["stage"] = "search"
        elif int(state["generations_done"]) < settings.generations:
            state["stage"] = "search"
        elif int(state["polish_done"]) < settings.polish_simulations:
            state["stage"] = "polish"
        say(f"resuming at {state['stage']}: {state['generations_done']} "
            f"{'starts' if settings.search == 'least-squares' else 'generations'} done, "
            f"best {float(state['best_score']):.3f} deg")
    if settings.search == "least-squares":
        run.least_squares()
    else:
        run.differential_evolution()
        run.polish()
    state = run.state
    run.save(force=True)
    return FitOutcome(np.array(state["best_x"]), float(state["best_score"]),
                      np.array(state["initial_x"]), float(state["initial_score"]),
                      problem.simulations, problem.failed_simulations, run.elapsed(),
                      int(state["generations_done"]), int(state["polish_done"]),
                      run.interrupted, [list(h) for h in state["history"]],
                      str(state.get("capped", "")))


class _Run:
    """The state of one fit and the searches that advance it."""

    def __init__(self, problem, settings, checkpoint, say, tick, should_stop):
        self.problem, self.settings = problem, settings
        self.checkpoint, self.say, self.should_stop = checkpoint, say, should_stop
        self._tick, self._last_tick = tick, None
        self.tick = None if tick is None else self._tick_remembered
        self.space = problem.space
        self.free = self.space.free
        self.start = time.perf_counter()
        self.prior_wall = 0.0
        self.last_save = time.perf_counter()
        self.interrupted = False
        self.state: dict = {}

    @property
    def base(self) -> np.ndarray:
        return np.array(self.state["initial_x"], dtype=float)

    def elapsed(self) -> float:
        return self.prior_wall + time.perf_counter() - self.start

    def out_of_time(self) -> bool:
        return self.settings.max_time is not None and self.elapsed() >= self.settings.max_time

    def stopping(self) -> bool:
        if self.should_stop():
            self.interrupted = True
        return self.interrupted or self.out_of_time()

    def _tick_remembered(self, stage, done, total) -> None:
        """The caller's ``tick(stage, done, total)``, the call remembered so that every
        simulation batch can repeat it (a log then hears from a long stage every few
        seconds)."""
        self._last_tick = (stage, done, total)
        self._tick(stage, done, total)

    def keep(self, x_free, score) -> None:
        if self._tick is not None and self._last_tick is not None:
            self._tick(*self._last_tick)
        state = self.state
        if score < state["best_score"]:
            state["best_score"] = float(score)
            state["best_x"] = self.space.full(x_free, self.base)
        state["simulations"] = self.problem.simulations
        state["failed"] = self.problem.failed_simulations
        state["wall_time"] = self.elapsed()

    def save(self, force=False) -> None:
        if self.checkpoint is not None and (force or time.perf_counter() - self.last_save
                                            >= self.settings.checkpoint_every):
            self.state["wall_time"] = self.elapsed()
            save_checkpoint(self.checkpoint, {**self.state,
                                              "history": np.array(self.state["history"])})
            self.last_save = time.perf_counter()

    def record(self) -> None:
        self.state["history"].append([self.problem.simulations, self.elapsed(),
                                      self.state["best_score"]])

    # -- least squares ---------------------------------------------------------------------
    def starting_points(self) -> np.ndarray:
        """The inverse-dynamics start and ``starts − 1`` seeded perturbations of it."""
        lo = np.array(self.space.lower)[self.free]
        hi = np.array(self.space.upper)[self.free]
        guess = self.base[self.free]
        rng = np.random.default_rng(self.settings.seed)
        points = [guess]
        for _ in range(self.settings.starts - 1):
            points.append(np.clip(guess + rng.normal(0.0, 0.1, guess.size) * (hi - lo), lo, hi))
        return np.array(points)

    def jacobian(self, z, at=None) -> np.ndarray:
        """∂r/∂z by differences (`SearchSettings.jacobian`), in parallel: central (2·len(z)
        simulations; one-sided at a bound) or forward (len(z) simulations; backward where the
        upper bound is closer than the difference step; ``at`` is r(z) when already known,
        else it is simulated too). A column whose run fails is 0."""
        lo = np.array(self.space.lower)[self.free]
        hi = np.array(self.space.upper)[self.free]
        h = DIFFERENCE_STEP * self.space.difference_scales()[self.free]
        if self.settings.jacobian == "central":
            plus = np.minimum(z + h, hi)
            minus = np.maximum(z - h, lo)
            rows = np.empty((2 * z.size, self.space.size))
            for i in range(z.size):
                zp, zm = z.copy(), z.copy()
                zp[i], zm[i] = plus[i], minus[i]
                rows[2 * i] = self.space.full(zp, self.base)
                rows[2 * i + 1] = self.space.full(zm, self.base)
            residuals, failed = self.problem.residuals(rows)
            jac = (residuals[0::2] - residuals[1::2]).T / (plus - minus)
            jac[:, failed[0::2] | failed[1::2]] = 0.0
            return jac
        moved = np.where(z + h <= hi, z + h, z - h)
        moved = np.clip(moved, lo, hi)
        rows = np.empty((z.size + (at is None), self.space.size))
        for i in range(z.size):
            zi = z.copy()
            zi[i] = moved[i]
            rows[i] = self.space.full(zi, self.base)
        if at is None:
            rows[-1] = self.space.full(z, self.base)
        residuals, failed = self.problem.residuals(rows)
        centre = residuals[-1] if at is None else at
        jac = (residuals[:z.size] - centre).T / (moved - z)
        jac[:, failed[:z.size]] = 0.0
        return jac

    def _solve(self, z0, budget: int):
        """Trust-region reflective least squares from ``z0`` for at most ``budget`` residual
        evaluations; the result, or None when stopped."""
        from scipy.optimize import least_squares

        problem = self.problem
        last = {}

        def residual(z):
            if self.stopping():
                raise _Stop
            r, _ = problem.residuals(self.space.full(z, self.base))
            self.keep(z, float(np.sqrt(r[0] @ r[0])))
            self.save()
            last["z"], last["r"] = np.array(z, dtype=float), r[0]
            return r[0]

        def jacobian(z):
            if self.stopping():
                raise _Stop
            z = np.asarray(z, dtype=float)
            known = last.get("r") if np.array_equal(z, last.get("z")) else None
            return self.jacobian(z, known)

        lo, hi = np.array(self.space.bounds()).T
        try:
            return least_squares(residual, np.clip(z0, lo, hi), jac=jacobian, bounds=(lo, hi),
                                 method="trf", max_nfev=budget, x_scale="jac", ftol=1e-6,
                                 xtol=1e-8, gtol=1e-10)
        except _Stop:
            return None

    def least_squares(self) -> None:
        """Screen every start with `screen_evaluations` residual evaluations, then refine
        the best screened point for up to ``iterations`` evaluations."""
        state, problem, settings = self.state, self.problem, self.settings
        if state["stage"] != "search":
            return
        points = self.starting_points()
        screened = np.asarray(state["population"], dtype=float).reshape(-1, self.free.size + 1)
        if self.tick:
            self.tick("least squares", int(state["generations_done"]), settings.starts + 1)
        for k in range(int(state["generations_done"]), settings.starts):
            result = self._solve(points[k], min(screen_evaluations(self.free.size),
                                                settings.iterations))
            if result is None:
                self.record()
                return
            score = float(np.sqrt(2.0 * result.cost))
            screened = np.vstack([screened, np.append(result.x, score)])
            state["population"] = screened
            state["generations_done"] = k + 1
            self.record()
            self.say(f"least squares  start {k + 1}/{settings.starts} screened: {score:.4f} "
                     f"deg, {problem.simulations} simulations, {self.elapsed():.1f} s")
            if self.tick:
                self.tick("least squares", k + 1, settings.starts + 1)
            self.save(force=True)
            floor = float(state.get("integration_floor", 0.0))
            if state["best_score"] <= floor:
                self.say(f"least squares  done: {float(state['best_score']):.4f} deg is within "
                         f"the integration error of the fit's simulations ({floor:.4f} deg, "
                         "by step halving), which no further start or refinement can tell "
                         "from a better fit")
                if self.tick:
                    self.tick("least squares", settings.starts + 1, settings.starts + 1)
                state["stage"] = "done"
                return
        best = screened[int(np.argmin(screened[:, -1]))]
        result = self._solve(best[:-1], settings.iterations)
        if result is None:
            self.record()
            return
        self.keep(result.x, float(np.sqrt(2.0 * result.cost)))
        state["capped"] = (f"the refining least squares' {settings.iterations} residual "
                           "evaluations (--iterations)" if result.status == 0 else "")
        self.record()
        self.say(f"least squares  refined: {np.sqrt(2.0 * result.cost):.4f} deg "
                 f"({result.message}), {problem.simulations} simulations, "
                 f"{self.elapsed():.1f} s")
        if self.tick:
            self.tick("least squares", settings.starts + 1, settings.starts + 1)
        state["stage"] = "done"

    # -- global: differential evolution and Nelder-Mead ------------------------------------
    def objective(self, x_free_columns):
        rows = np.array([self.space.full(x, self.base) for x in np.atleast_2d(x_free_columns.T)])
        return self.problem.evaluate(rows)[0]

    def differential_evolution(self) -> None:
        state, settings = self.state, self.settings
        remaining = settings.generations - int(state["generations_done"])
        if state["stage"] == "search" and remaining > 0:
            bounds = self.space.bounds()
            state["population"] = np.array(state["population"], dtype=float)
            if state["generations_done"] > 0:  # resumed: the best so far takes part
                state["population"][-1] = np.asarray(state["best_x"])[self.free]

            def on_generation(intermediate_result):
                state["generations_done"] += 1
                state["population"] = np.array(intermediate_result.population)
                self.keep(intermediate_result.x, intermediate_result.fun)
                self.record()
                if self.tick:
                    self.tick("search", int(state["generations_done"]), settings.generations)
                if state["generations_done"] % 10 == 0:
                    self.say(f"search  generation {state['generations_done']}/"
                             f"{settings.generations}  best {state['best_score']:.3f} deg  "
                             f"{self.problem.simulations} simulations  {self.elapsed():.1f} s")
                self.save()
                return self.stopping()

            # Each resumed segment draws from its own stream: seed and generation fix it.
            differential_evolution(
                self.objective, bounds, init=np.clip(state["population"], *np.array(bounds).T),
                maxiter=remaining, rng=np.random.default_rng([settings.seed,
                                                              int(state["generations_done"])]),
                vectorized=True, updating="deferred", polish=False, tol=0.0,
                mutation=(0.5, 1.0), recombination=0.9, callback=on_generation)
            state["simulations"] = self.problem.simulations
        if not self.interrupted and not self.out_of_time() and state["stage"] == "search":
            state["stage"] = "polish"
            self.save(force=True)

    def polish(self) -> None:
        state, settings, problem = self.state, self.settings, self.problem
        budget = settings.polish_simulations - int(state["polish_done"])
        if state["stage"] == "polish" and budget > 0 and not self.stopping():
            self.say(f"polish  Nelder-Mead from {state['best_score']:.3f} deg")
            before = problem.simulations
            done_before = int(state["polish_done"])

            def single(x_free):
                return self.objective(np.asarray(x_free)[:, None])[0]

            def on_step(intermediate_result):
                self.keep(intermediate_result.x, intermediate_result.fun)
                state["polish_done"] = done_before + problem.simulations - before
                if self.tick:
                    self.tick("polish", int(state["polish_done"]), settings.polish_simulations)
                self.save()
                if self.stopping():
                    raise StopIteration

            result = minimize(single, state["best_x"][self.free], method="Nelder-Mead",
                              bounds=self.space.bounds(), callback=on_step,
                              options={"maxfev": budget, "xatol": 1e-6, "fatol": 1e-6,
                                       "adaptive": True})
            self.keep(result.x, result.fun)
            state["polish_done"] = done_before + problem.simulations - before
            self.record()
            if not self.stopping():
                state["stage"] = "done"
        if state["stage"] == "polish" and budget <= 0:
            state["stage"] = "done"
