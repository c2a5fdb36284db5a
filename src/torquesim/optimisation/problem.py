"""An optimisation problem: the starting model, the goals, what may change, and the score.

The activation of every unit is written as 3 ramps (`torquesim.fitting.parameters`: 9
parameters per unit); a unit with fewer ramps gets ramps that hold its last level (the
profile is unchanged). By default every parameter may move within a window around the
starting model's value (`Window`), so that the optimum stays a technique the performer could
use; ``free`` picks what may move (everything else is frozen), ``frozen`` and ``bounds``
refine it, in the one parameter-path vocabulary (``UNIT``, ``UNIT.rampK``,
``UNIT.rampK.FIELD``; units by name or alias). A model field (any parameter path,
`torquesim.model.paths`: ``knee.initial_angle``, ``gastrocnemius.se_stiffness``) is searched
too when ``bounds`` gives its range; each candidate then starts from the static equilibrium
of its own model.

A candidate is simulated with the problem's technique and step (compiled, in parallel
threads, `torquesim.optimisation.population`); it fails, with the reason counted, when its run
is non-finite, diverges, breaks the RK4 stability limit (contacts always, units with explicit
techniques), or leaves a goal undefined. Its cost is the goals' combination
(`torquesim.optimisation.goals`); a robust problem scores the worst (or mean) cost over the
nominal run and ``robust`` copies with every ramp's onset moved by a random error in
±``timing_error`` (the same copies for every candidate, from ``perturbation_seed``).

Limits are the user's: a candidate is infeasible when a joint goes more than
``endstop_depth`` end-stop angle scales s_p past an end stop (default 0: an optimum may not
lean on the passive stop torque, which reaches k_p at the stop angle and e·k_p one s_p past
it), or a constraint's goal leaves its bounds (`Constraint`). An infeasible candidate costs
`INFEASIBLE_COST` plus its violation (end-stop scales past the allowed depth, plus each
constraint's distance outside its bounds in units of their width), so the search ranks it
below every feasible one and nearer ones first.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ModelError, check_range
from ..fitting.objective import (
    POPULATION_CHUNK,
    RUN_OK,
    RUN_REASONS,
    OwnStarts,
    run_own_models,
    run_population,
)
from ..fitting.parameters import (
    HARD_LIMITS,
    PER_UNIT,
    RAMPS_PER_UNIT,
    ParameterSpace,
    held_profiles,
    vector,
    with_ramps,
)
from ..fitting.problem import DEFAULT_METHOD, default_step, fit_step
from ..model.chain import ChainModel, as_chain
from ..model.paths import get_parameter, set_parameter
from ..solvers import step_loop
from ..solvers.choice import choose_technique
from ..solvers.techniques import (
    FIT_METHODS,
    default_coupling,
    explicit_muscles,
    runs_monolithic,
)
from .goals import Constraint, Goal, Trial

#: Cost of a failed candidate (costs of usable ones are O(1): goals in units of the start's).
FAILED_COST = 1.0e6
#: Cost of an infeasible candidate, before its violation is added (`OptimiseProblem`).
INFEASIBLE_COST = 1.0e3
ROBUST_MODES = ("worst", "mean")
#: The default `OptimiseProblem.accuracy`, rad: the max angle error of the chosen technique
#: and step on the start's run.
ACCURACY = math.radians(0.05)
#: Duration of the ramps added to a unit with fewer than 3 (they hold its level), s.
HOLD_RAMP_DURATION = 0.1


@dataclass(frozen=True)
class Window:
    """How far each kind of ramp parameter may move from the starting model's value.

    Attributes
    ----------
    delay : float
        ± s on every delay. Default 0.05. Bounds [0, 10].
    duration : float
        ± fraction of every duration. Default 0.3. Bounds [0, 0.99].
    level : float
        ± fraction of every level, at least ±`min_level`. Default 0.3. Bounds [0, 10].
    min_level : float
        Smallest ± window of a level (activation), so that a unit at rest may act.
        Default 0.05. Bounds [0, 1].
    """

    delay: float = 0.05
    duration: float = 0.3
    level: float = 0.3
    min_level: float = 0.05

    def __post_init__(self) -> None:
        check_range("window.delay", self.delay, 0.0, 10.0, unit="s")
        check_range("window.duration", self.duration, 0.0, 0.99)
        check_range("window.level", self.level, 0.0, 10.0)
        check_range("window.min_level", self.min_level, 0.0, 1.0)

    def around(self, name: str, value: float) -> tuple[float, float]:
        """(low, high) of parameter ``name`` (``….FIELD``) starting at ``value``, inside its
        physical limits."""
        kind = name.rsplit(".", 1)[1]
        if kind == "delay":
            low, high = value - self.delay, value + self.delay
        elif kind == "duration":
            low, high = value * (1 - self.duration), value * (1 + self.duration)
        else:
            half = max(self.level * value, self.min_level)
            low, high = value - half, value + half
        hard_low, hard_high = HARD_LIMITS[kind]
        return max(low, hard_low), min(high, hard_high)


def three_ramps(model: ChainModel) -> ChainModel:
    """``model`` with every unit's activation as exactly 3 ramps (`held_profiles`, held for
    `HOLD_RAMP_DURATION`): the activation is unchanged. A unit with more than 3 is a
    `ModelError`."""
    for u, unit in enumerate(model.units):
        if len(unit.activation.ramps) > RAMPS_PER_UNIT:
            raise ModelError(f"units[{u}].activation.ramps", f"{unit.name} has "
                             f"{len(unit.activation.ramps)} ramps; allowed: at most "
                             f"{RAMPS_PER_UNIT} (the optimised parameters are 3 ramps per "
                             "unit)")
    profiles = held_profiles(model, HOLD_RAMP_DURATION)
    return model.replace(units=tuple(replace(unit, activation=profile)
                                     for unit, profile in zip(model.units, profiles,
                                                              strict=True)))


def parameter_space(model: ChainModel, start, window: Window, free=(), frozen=None,
                    bounds=None) -> ParameterSpace:
    """The searched space around the ramp vector ``start`` of the 3-ramp ``model``
    (module docstring). ``frozen``: path → value (None: the start's); ``bounds``: path →
    (low, high), replacing the window, or for a model field its range (it is then searched,
    after the ramps); each must contain the start's value."""
    space = ParameterSpace.for_model(model)
    names = space.names
    lower, upper = zip(*(window.around(n, float(v)) for n, v in zip(names, start,
                                                                     strict=True)),
                       strict=True)
    lower, upper = list(lower), list(upper)
    fields = {}
    for path, (low, high) in (bounds or {}).items():
        if space.is_field(model, path):
            fields[path] = (low, high)
            continue
        for name in space.select(path, "bounds"):
            i = names.index(name)
            if not low <= start[i] <= high:
                raise ModelError(f"bounds.{path}", f"[{low:g}, {high:g}] excludes the starting "
                                 f"model's {name} = {start[i]:g}; allowed: bounds that "
                                 "contain it")
            lower[i], upper[i] = low, high
    # A parameter whose window is a point (e.g. a delay of 0 with window 0) is frozen there.
    pinned = {n: float(start[i]) for i, n in enumerate(names) if lower[i] >= upper[i]}
    for i, n in enumerate(names):
        if n in pinned:
            lower[i], upper[i] = HARD_LIMITS[n.rsplit(".", 1)[1]]
    space = ParameterSpace(units=space.units, lower=tuple(lower), upper=tuple(upper),
                           aliases=space.aliases)
    for path, (low, high) in fields.items():
        value = get_parameter(model, path, f"bounds.{path}")
        if not low <= value <= high:
            raise ModelError(f"bounds.{path}", f"[{low:g}, {high:g}] excludes the starting "
                             f"model's {path} = {value:g}; allowed: bounds that contain it")
        space = space.with_bounds(path, low, high, model)
    start = np.concatenate([start, space.field_values(model)])
    names = space.names
    chosen = set(names)
    if free:
        chosen = {n for path in free for n in _selected(space, model, path)}
    held = {n: float(start[i]) for i, n in enumerate(names) if n not in chosen}
    for path, value in (frozen or {}).items():
        for name in _selected(space, model, path, "frozen"):
            held[name] = float(start[names.index(name)]) if value is None else float(value)
    space = replace(space, frozen={**pinned, **held})
    if space.free.size == 0:
        raise ModelError("free", "every parameter is frozen; allowed: at least one free")
    return space


def _selected(space: ParameterSpace, model: ChainModel, path: str,
              what: str = "free") -> list[str]:
    """`ParameterSpace.select`, with a model field that has no range named as such."""
    try:
        return space.select(path, what)
    except ModelError:
        if space.is_field(model, path):
            raise ModelError(what, f"{path!r} is a model field without a range; allowed: give "
                             f"it one, --bound {path}=LOW,HIGH") from None
        raise


def apply_timing_errors(x, errors) -> np.ndarray:
    """The ramp vector ``x`` with every ramp's onset moved by ``errors`` (units × 3, s):
    delay_i + e_i − e_{i−1}, floored at 0 (a ramp cannot start before the previous ends)."""
    out = np.array(x, dtype=float)
    for u in range(errors.shape[0]):
        previous = 0.0
        for i in range(RAMPS_PER_UNIT):
            k = u * PER_UNIT + 3 * i
            out[k] = max(out[k] + errors[u, i] - previous, 0.0)
            previous = errors[u, i]
    return out


@dataclass
class OptimiseProblem:
    """Everything a candidate's score needs, with the model's arrays packed once.

    Attributes
    ----------
    model : ChainModel
        The starting model (its activations: the start of the search).
    goals : tuple of Goal
    method : str or None
        Technique of the candidates' runs, one of `FIT_METHODS`. Default (None, with ``step``
        None): the cheapest technique and step whose run of the start meets ``accuracy``
        (`torquesim.solvers.choice.choose_technique`, in ``choice``); with a ``step``:
        ``imex``.
    step : float or None
        s. Default (None): the cheapest step of ``method`` (or of the candidate techniques)
        that meets ``accuracy``; where none does, a fit's default
        (`torquesim.fitting.problem.default_step`).
    accuracy : float
        The max angle error (rad, estimated on the start's run) the chosen technique and step
        must meet. Default `ACCURACY` (0.05°): on the squat jump at 0.1° the search leant on
        the integration error (its optimum, re-simulated with the reference, no longer
        jumped). Bounds (0, π].
    window : Window
    free, frozen, bounds
        What may move (module docstring). A model field ``frozen`` at a value without a
        range in ``bounds`` is set to it in the start (which the gains are measured from).
    robust : int
        Perturbed copies per candidate (0: the plain optimum). Bounds [0, 1000].
    timing_error : float
        Largest onset error of the copies, s. Default 0.01. Bounds [0, 1].
    robust_mode : str
        ``worst`` (default: the score is never better than the nominal run's) or ``mean``.
    perturbation_seed : int
        Seed of the copies' errors. Default 1.
    constraints : tuple of Constraint
        Goals held within bounds (`torquesim.optimisation.goals.parse_constraint`).
    endstop_depth : float
        How far a run may go past an end stop, in end-stop angle scales s_p. Default 0 (not
        past the stop angle). Bounds [0, 20].
    """

    model: object = None
    goals: tuple = ()
    method: str | None = None
    step: float | None = None
    window: Window = field(default_factory=Window)
    free: tuple = ()
    frozen: dict | None = None
    bounds: dict | None = None
    robust: int = 0
    timing_error: float = 0.01
    robust_mode: str = "worst"
    perturbation_seed: int = 1
    constraints: tuple = ()
    endstop_depth: float = 0.0
    accuracy: float = ACCURACY
    simulations: int = 0
    failures: Counter = field(default_factory=Counter)

    def __post_init__(self) -> None:
        from ..model.presets import preset

        if self.method is not None and self.method not in FIT_METHODS:
            raise ModelError("method", f"{self.method!r}; allowed: {', '.join(FIT_METHODS)}")
        check_range("accuracy", self.accuracy, 0.0, math.pi, low_open=True, unit="rad")
        if not self.goals:
            raise ModelError("goal", "none given; allowed: at least one --maximise or "
                             "--minimise GOAL")
        self.goals = tuple(self.goals)
        if not all(isinstance(g, Goal) for g in self.goals):
            raise TypeError("goals: expected Goal objects (parse_goal or Goal.custom)")
        check_range("robust", self.robust, 0, 1000)
        check_range("timing_error", self.timing_error, 0.0, 1.0, unit="s")
        check_range("endstop_depth", self.endstop_depth, 0.0, 20.0)
        self.constraints = tuple(self.constraints)
        if not all(isinstance(c, Constraint) for c in self.constraints):
            raise TypeError("constraints: expected Constraint objects (parse_constraint)")
        if self.robust_mode not in ROBUST_MODES:
            raise ModelError("robust_mode", f"{self.robust_mode!r}; allowed: "
                             f"{', '.join(ROBUST_MODES)}")
        start = as_chain(self.model if self.model is not None
                         else preset("builtin:elbow-curl"))
        if not isinstance(start, ChainModel):
            raise TypeError("model: expected a model")
        frozen = dict(self.frozen or {})
        ramps_only = ParameterSpace.for_model(start)
        for path, value in list(frozen.items()):  # a model field held, not searched
            if path not in (self.bounds or {}) and ramps_only.is_field(start, path):
                del frozen[path]
                if value is not None:
                    try:
                        start = set_parameter(start, path, value)
                    except ModelError as exc:
                        raise ModelError(f"frozen.{path}", exc.reason) from None
        self.start_model = start
        self.model3 = three_ramps(start)
        ramps = vector([u.activation for u in self.model3.units])
        self.space = parameter_space(self.model3, ramps, self.window, self.free, frozen,
                                     self.bounds)
        self.x0 = np.concatenate([ramps, self.space.field_values(self.model3)])
        self.own_starts = OwnStarts(self.space, self.model3)
        self.choice = None
        if self.step is None:
            self.choice = choose_technique(start, self.accuracy,
                                           None if self.method is None else (self.method,))
            if self.choice is not None:
                self.method, self.step = self.choice.method, self.choice.step
            else:
                self.step = default_step(start)
        self.method = self.method or DEFAULT_METHOD
        self.step, self.n_steps = fit_step(start.duration, self.step)
        begin = self.model3.initial_state()
        self.y0 = begin.state
        self.levels = np.array(begin.levels, dtype=float)
        self.coupling = default_coupling(self.method)
        packed = self.model3.pack(self.levels)
        self.arrays = (packed.segments, packed.joints, packed.units)
        self.step_kinds = step_loop.model_step_kinds(start, runs_monolithic(self.method),
                                                     self.coupling.to_array())
        self.ground = bool(start.contacts) and start.base == "free"
        self.joint_names = tuple(j.name for j in start.joints)
        rng = np.random.default_rng(self.perturbation_seed)
        self.timing_errors = rng.uniform(-self.timing_error, self.timing_error,
                                         (self.robust, len(start.units), RAMPS_PER_UNIT))
        values, reasons, _ = self.goal_values(self.x0[None, :])
        if reasons[0]:
            raise ModelError("model", f"the starting model's run fails ({reasons[0]}) at "
                             f"step {self.step * 1e3:.4g} ms with {self.method}; allowed: a "
                             "start whose run is usable (another --step or --method, or a "
                             "goal it reaches)")
        self.start_values = values[0]
        self.scales = np.array([abs(v) if v != 0 else 1.0 for v in self.start_values])
        self.simulations = 0
        self.failures = Counter()

    # ---- simulating --------------------------------------------------------------------
    @property
    def explicit_muscles(self) -> bool:
        return explicit_muscles(self.method)

    def model_for(self, x) -> ChainModel:
        """The model with the activation ramps and the searched fields of the full parameter
        vector ``x``."""
        own_levels = [None] * len(self.model3.units)
        return self.space.with_fields(with_ramps(self.model3, x, own_levels), x)

    def trials(self, population) -> list[tuple[Trial | None, str]]:
        """(trial, "") or (None, why it failed) of every row of ``population`` (full
        parameter vectors), simulated in compiled parallel threads, `POPULATION_CHUNK` at a
        time."""
        population = np.ascontiguousarray(np.atleast_2d(population), dtype=float)
        out: list[tuple[Trial | None, str]] = []
        for begin in range(0, population.shape[0], POPULATION_CHUNK):
            out += self._chunk(population[begin:begin + POPULATION_CHUNK])
        self.simulations += population.shape[0]
        return out

    def _chunk(self, rows) -> list[tuple[Trial | None, str]]:
        m, steps = rows.shape[0], self.n_steps + 1
        ground_steps = np.arange(steps if self.ground else 0)
        if self.space.fields:  # each candidate from its own model's start
            states, activations, outputs, status, starts = run_own_models(
                rows, self.own_starts, self.step_kinds, self.coupling.to_array(), self.step,
                self.n_steps, self.explicit_muscles, ground_steps, activation_steps=steps)
        else:
            starts = [None] * m
            states, activations, outputs, status = run_population(
                rows, self.step_kinds, self.coupling.to_array(), self.y0, self.step,
                self.n_steps, self.arrays, self.levels, self.explicit_muscles, ground_steps,
                activation_steps=steps)
        n, nb = self.start_model.n_coordinates, self.start_model.n_base
        time = np.arange(steps) * self.step
        result = []
        for j in range(m):
            if status[j] != RUN_OK:
                result.append((None, RUN_REASONS[status[j]]))
                continue
            angles = states[j, :, nb:n]
            ground = {}
            if self.ground:
                com_x, com_y = outputs[j, 2], outputs[j, 3]
                ground = {"com_y": com_y, "grf_y": outputs[j, 1],
                          "com_speed_x": np.gradient(com_x, self.step),
                          "com_speed_y": np.gradient(com_y, self.step)}
            model = self.start_model if starts[j] is None else starts[j].model
            result.append((Trial(time, angles, states[j, :, n + nb:2 * n],
                                 activations[j].T, gravity=model.gravity, **ground), ""))
        return result

    # ---- scoring -----------------------------------------------------------------------
    def goal_values(self, population) -> tuple[np.ndarray, list[str], np.ndarray]:
        """Each goal's value (columns) on the nominal run of every row of ``population``
        (full vectors), NaN where the run failed; the reasons ("" when usable); and each
        row's violation of the limits (0: feasible; `OptimiseProblem`)."""
        population = np.atleast_2d(population)
        values = np.full((len(population), len(self.goals)), np.nan)
        violations = np.zeros(len(population))
        reasons = []
        for r, (trial, why) in enumerate(self.trials(population)):
            if trial is not None:
                why = self._fill(values[r], trial, population[r])
                if not why:
                    violations[r] = self._violation(trial, population[r])
            reasons.append(why)
            if why:
                self.failures[why] += 1
        return values, reasons, violations

    def _violation(self, trial, x) -> float:
        """End-stop scales past the allowed depth (the candidate's own stops, when they are
        searched fields) plus each constraint's violation."""
        model = self.own_starts(x).model if self.space.fields else self.start_model
        deepest = float(np.max(endstop_depths(model, trial.angles), initial=-np.inf))
        total = max(deepest - self.endstop_depth, 0.0)
        for constraint in self.constraints:
            goal = constraint.goal
            value = (float(goal.function(self.run(x))) if goal.function is not None
                     else goal.value(trial, self.joint_names)[0])
            total += constraint.violation(value)
        return total

    def _fill(self, row, trial, x) -> str:
        for g, goal in enumerate(self.goals):
            if goal.function is not None:
                value, why = float(goal.function(self.run(x))), ""
            else:
                value, why = goal.value(trial, self.joint_names)
            if why or not math.isfinite(value):
                return why or f"{goal.label} is undefined (NaN) on this run"
            row[g] = value
        return ""

    def run(self, x, reference: bool = False):
        """The `SimulationResult` of the full parameter vector ``x``: with the problem's
        technique and step, or the reference solver at that output step."""
        from ..solvers.simulation import simulate

        model = self.model_for(x)
        if reference:
            return simulate(model, "reference", output_step=self.step, check=False)
        return simulate(model, self.method, self.step, coupling=self.coupling, check=False,
                        advise=False, tolerance=None)

    def cost_of_values(self, values) -> np.ndarray:
        """C = Σ_g w_g·σ_g·v_g/scale_g of rows of goal values (`FAILED_COST` for NaN)."""
        signs = np.array([-g.weight if g.maximise else g.weight for g in self.goals])
        cost = (np.asarray(values) / self.scales) @ signs
        return np.where(np.isfinite(cost), cost, FAILED_COST)

    def expand(self, population) -> np.ndarray:
        """Every row of ``population`` (full vectors) followed by its `robust` perturbed
        copies: (m·(1 + robust)) rows."""
        rows = []
        for x in np.atleast_2d(population):
            rows.append(x)
            rows += [apply_timing_errors(x, e) for e in self.timing_errors]
        return np.array(rows)

    def score(self, population) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(costs, nominal goal values, robust goal values) of the rows of ``population``
        (full vectors). Without copies the robust values are the nominal ones; with them,
        per goal the worst (or mean) over the nominal run and the copies, and the cost the
        worst (or mean) of the copies' costs. A candidate with any failed run costs
        `FAILED_COST`."""
        population = np.atleast_2d(population)
        copies = 1 + self.robust
        values, _, violations = self.goal_values(self.expand(population))
        values = values.reshape(len(population), copies, len(self.goals))
        costs = self.cost_of_values(values.reshape(-1, len(self.goals))).reshape(
            len(population), copies)
        violation = violations.reshape(len(population), copies).max(axis=1)
        failed = ~np.isfinite(values).all(axis=(1, 2))
        if self.robust_mode == "worst":
            cost = costs.max(axis=1)
            robust = np.column_stack([values[:, :, g].min(axis=1) if goal.maximise
                                      else values[:, :, g].max(axis=1)
                                      for g, goal in enumerate(self.goals)])
        else:
            cost = costs.mean(axis=1)
            robust = values.mean(axis=1)
        cost = np.where(violation > 0, INFEASIBLE_COST + np.minimum(violation, 1e5), cost)
        cost = np.where(failed, FAILED_COST, cost)
        return cost, values[:, 0], robust


def endstop_depths(model: ChainModel, angles) -> np.ndarray:
    """How far each joint went past its end stops over a run (``angles``: samples × joints,
    rad), in end-stop angle scales s_p: max((θ_lo − min q), (max q − θ_hi))/s_p; negative
    when it stayed inside, −inf for a joint without end stops."""
    out = np.full(model.n_joints, -np.inf)
    for k, joint in enumerate(model.joints):
        if joint.endstop_torque > 0:
            q = angles[:, k]
            out[k] = max(joint.endstop_lower_angle - q.min(),
                         q.max() - joint.endstop_upper_angle) / joint.endstop_angle_scale
    return out
