"""A fit problem: the target, the model around it, the technique, and the objective."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ModelError, check_range
from ..model.activation import activation
from ..model.chain import ChainModel, as_chain
from ..model.paths import set_parameter
from ..model.presets import preset
from ..solvers import fixed_step as fs
from ..solvers import step_loop
from ..solvers.techniques import (
    FIT_METHODS,
    default_coupling,
    explicit_muscles,
    runs_monolithic,
)
from . import objective as obj
from .parameters import ParameterSpace, with_ramps
from .target import CHANNELS, Target, check_target

DEFAULT_METHOD = "imex"
#: Default fit step, s: IMEX is stable at any step; 5 ms keeps it within ~0.3° of the
#: reference on the default curl.
DEFAULT_STEP = 5.0e-3
#: Steps a body on the ground may default to, s, largest first (`default_step`).
GROUND_STEPS = (5e-3, 2.5e-3, 1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1e-5)
#: A body on the ground's default step stays within this fraction of its contacts' RK4
#: stability limit on the model's own run (a fit's candidates push harder or softer).
GROUND_STEP_MARGIN = 0.7


#: Model fields a fit sets itself, which its bounds cannot free: why, by field name.
FITTED_ELSEWHERE = {"initial_angle": "a fit starts each joint at its target's first angle",
                    "initial_speed": "a fit starts each joint at its target's first speed",
                    "initial_level": "a fit starts each unit at its rest level (--rest-level) "
                                     "or at static equilibrium"}


def held_field(model: ChainModel, path: str, value: float) -> ChainModel:
    """``model`` with the model field at ``path`` held at ``value`` for a fit (``--freeze``
    of a field that is not fitted); a field the fit sets itself (`FITTED_ELSEWHERE`) or a
    value the model does not allow is a `ModelError` on ``freeze.PATH``."""
    why = FITTED_ELSEWHERE.get(path.rpartition(".")[2])
    if why:
        raise ModelError(f"freeze.{path}", f"{why}; allowed: a field the fit leaves to the "
                         "model (torquesim model NAME --paths)")
    try:
        return set_parameter(model, path, value)
    except ModelError as exc:
        raise ModelError(f"freeze.{path}", exc.reason) from None


def default_step(model) -> float:
    """The fit's default step, s: `DEFAULT_STEP` on a fixed base. On a body on the ground,
    whose contacts every technique integrates explicitly, the largest of `GROUND_STEPS`
    within `GROUND_STEP_MARGIN` of the contacts' RK4 limit 2.785·τ, τ their smallest time
    constant on a run of the model as it is (IMEX at the smallest of those steps)."""
    if model.base != "free" or not model.contacts:
        return DEFAULT_STEP
    from ..solvers.simulation import simulate

    probe = GROUND_STEPS[-1] if model.duration / GROUND_STEPS[-1] <= 2e5 else GROUND_STEPS[-3]
    run = simulate(model, "imex", probe, check=False, advise=False, tolerance=None)
    tau = run.settings.get("contact_time_constant_min_s", math.inf)
    bound = GROUND_STEP_MARGIN * fs.RK4_STABILITY_LIMIT * tau
    return next((h for h in GROUND_STEPS if h <= bound), GROUND_STEPS[-1])


#: The smallest fit step, s (a fit simulates its model thousands of times).
MIN_STEP = 1.0e-5


def fit_step(duration: float, requested: float) -> tuple[float, int]:
    """The largest step ≤ ``requested`` that divides ``duration``, and the step count."""
    check_range("step", requested, MIN_STEP, duration, unit="s")
    n = math.ceil(duration / requested - 1e-9)
    return duration / n, n


@dataclass
class FitProblem:
    """Everything the objective needs, with the model's arrays packed once.

    The model spans the target: each scored joint starts at its first target angle (the
    others at the model's initial angle), at rest in static equilibrium, and the duration is
    the target's span; ``step`` (s) defaults to `default_step`. Every unit's activation is
    3 ramps (9 parameters,
    `ParameterSpace`) from its equilibrium or rest level; model fields given bounds in the
    space (a contact's stiffness, a unit's strength) are fitted too, each candidate then
    starting from the static equilibrium of its own model. ``residuals`` and
    ``evaluate`` simulate candidate parameter vectors (see
    `torquesim.fitting.objective`) and count simulations.

    Attributes
    ----------
    joint_weights : dict or None
        Scored joint → weight ≥ 0 (normalised to sum 1). Default: equal weights.
    weight_velocity, weight_end : float
        Weights of the angular-velocity and end-state errors. Default 0. Bounds [0, 1000].
    weight_effort : float
        w_a, deg² per squared activation: adds w_a·Σ_u mean (a_u − rest_u)₊² to the squared
        objective (rest_u: the unit's given initial level, 0 for units starting from
        equilibrium), so that among fits of equal angle error the least effort wins. Default
        0. Bounds [0, 1e6].
    weight_grf : float
        w_grf, deg per body weight: a target's ground reaction force channels add
        w_grf²·MSE(F/(m·g)) to the squared objective, so that with the default 20 an RMS error
        of 5 % of body weight weighs as much as 1° RMS on a joint. Bounds [0, 1e4].
    weight_com : float
        w_com, deg per m: a target's centre-of-mass channels add w_com²·MSE(x_CoM); default 100
        (1 cm as 1°). Bounds [0, 1e5].
    """

    target: Target
    space: ParameterSpace | None = None
    base_model: object = None
    method: str = DEFAULT_METHOD
    step: float | None = None
    weight_velocity: float = 0.0
    weight_end: float = 0.0
    weight_effort: float = 0.0
    joint_weights: dict | None = None
    weight_grf: float = 20.0
    weight_com: float = 100.0
    simulations: int = 0
    failed_simulations: int = 0

    def __post_init__(self) -> None:
        if self.method not in FIT_METHODS:
            raise ModelError("method", f"{self.method!r}; allowed: {', '.join(FIT_METHODS)}")
        check_range("weight_velocity", self.weight_velocity, 0.0, 1e3)
        check_range("weight_end", self.weight_end, 0.0, 1e3)
        check_range("weight_effort", self.weight_effort, 0.0, 1e6)
        check_range("weight_grf", self.weight_grf, 0.0, 1e4)
        check_range("weight_com", self.weight_com, 0.0, 1e5)
        base = as_chain(self.base_model if self.base_model is not None
                        else preset("builtin:elbow-curl"))
        if not isinstance(base, ChainModel):
            raise TypeError("base_model: expected a model")
        check_target(base, self.target)
        if self.space is None:
            self.space = ParameterSpace.for_model(base)
        if self.space.units != tuple(u.name for u in base.units):
            raise ModelError("model", f"the parameter space is for units "
                             f"{', '.join(self.space.units)}, the model has "
                             f"{', '.join(u.name for u in base.units)}")
        for path in self.space.fields:
            why = FITTED_ELSEWHERE.get(path.rpartition(".")[2])
            if why:
                raise ModelError(f"bounds.{path}", f"{why}; allowed: a field the fit leaves "
                                 "to the model (torquesim model NAME --paths)")
        names = [j.name for j in base.joints]
        for joint in self.target.joints:
            if joint not in names:
                raise ModelError("target", f"scores joint {joint!r}, which the model does not "
                                 f"have; allowed: {', '.join(names)}")
        # the state's coordinate of each scored joint (a free base's x, y come first)
        self.scored = np.array([base.n_base + names.index(j) for j in self.target.joints],
                               dtype=np.int64)
        weights = {j: 1.0 for j in self.target.joints} | dict(self.joint_weights or {})
        for joint, w in weights.items():
            if joint not in self.target.joints:
                raise ModelError("weight", f"{joint!r} is not a scored joint; allowed: "
                                 f"{', '.join(self.target.joints)}")
            check_range(f"weight.{joint}", w, 0.0, 1e6)
        raw = np.array([weights[j] for j in self.target.joints], dtype=float)
        if raw.sum() <= 0:
            raise ModelError("weight", "every joint weight is 0; allowed: at least one > 0")
        self.weights = raw / raw.sum()
        if self.step is None:
            self.step = default_step(base)
        self.requested_step = self.step
        self.step, self.n_steps = fit_step(self.target.duration, self.step)
        # initial levels: "equilibrium" units keep it; the others the rest level
        self.initial_levels = [None if u.activation.initial_level is None
                               else (u.activation.initial_level if self.space.rest_level is None
                                     else self.space.rest_level) for u in base.units]
        # a body on the ground starts from its first frames (its standing equilibrium is
        # sensitive to their noise); a fixed base, or a landing (its first frames span the
        # impact, which is no noise), from the first sample, as recorded
        landing = bool(base.landing_speed)
        first = (self.target.start_angles() if base.base == "free" and not landing
                 else self.target.angles[:, 0])
        start_angles = dict(zip(self.target.joints, first, strict=True))
        # a recording that begins in motion starts moving (its spline's speed at t0); a
        # landing's joints start still, the body moving down at the model's landing speed
        speeds = np.zeros(len(first)) if landing else self.target.start_speeds()
        self.start_speeds = dict(zip(self.target.joints, speeds.tolist(), strict=True))
        joints = tuple(j if j.name not in start_angles else
                       _with_start(j, float(start_angles[j.name]), self.start_speeds[j.name])
                       for j in base.joints)
        try:
            model = base.replace(joints=joints, duration=self.target.duration)
            self.model = with_ramps(model, np.array(self.space.upper), self.initial_levels)
            start = self.model.initial_state()
        except ModelError as exc:
            first = ", ".join(f"{j} {math.degrees(a):.2f}°" for j, a in start_angles.items())
            raise ModelError("target", f"cannot start at its first angles ({first}): "
                             f"{exc.reason}") from None
        self.y0 = start.state
        self.levels = np.array(start.levels, dtype=float)
        self.rests = np.array([0.0 if lv is None else lv for lv in self.initial_levels])
        self.coupling = default_coupling(self.method)
        packed = self.model.pack(self.levels)
        self.arrays = (packed.segments, packed.joints, packed.units)
        self.step_kinds = step_loop.model_step_kinds(base, runs_monolithic(self.method),
                                                     self.coupling.to_array())
        self.times = np.ascontiguousarray(self.target.elapsed)
        self.target_omega = np.ascontiguousarray(self.target.angular_velocity())
        self.target_angles = np.ascontiguousarray(self.target.angles)
        channels = self.target.channels
        self.channels = np.array([CHANNELS.index(c) for c in channels], dtype=np.int64)
        # the steps whose ground outputs the channels are sampled from (none without them)
        self.ground_steps = obj.steps_around(self.times, self.step, self.n_steps) \
            if channels else np.zeros(0, dtype=np.int64)
        self.target_channels = np.ascontiguousarray(
            np.array(list(channels.values())).reshape(len(channels), self.times.size))
        self.body_weight = base.weight
        self.channel_scales = np.array([self.weight_grf / self.body_weight if c.startswith("grf")
                                        else self.weight_com for c in channels])
        self.own_starts = obj.OwnStarts(self.space, self.model)
        self.terms = obj.ResidualTerms(
            self.times, self.scored, self.target_angles, self.target_omega, self.weights,
            self.channels, self.target_channels, self.channel_scales, self.rests,
            float(self.weight_velocity), float(self.weight_end), float(self.weight_effort))
        self.residual_size = obj.residual_size(len(self.scored), self.times.size,
                                               len(base.units), self.weight_velocity,
                                               self.weight_end, self.weight_effort,
                                               len(channels))

    @property
    def explicit_muscles(self) -> bool:
        return explicit_muscles(self.method)

    def residuals(self, population) -> tuple[np.ndarray, np.ndarray]:
        """Residual vectors (rows) and failure flags of the parameter vectors (rows) of
        ``population``, simulated in parallel."""
        population = np.ascontiguousarray(np.atleast_2d(population), dtype=float)
        out = np.empty((population.shape[0], self.residual_size))
        failed = np.zeros(population.shape[0], dtype=np.bool_)
        for begin in range(0, population.shape[0], obj.POPULATION_CHUNK):
            rows = population[begin:begin + obj.POPULATION_CHUNK]
            m = rows.shape[0]
            if not self.space.fields:
                states, _, outputs, status = obj.run_population(
                    rows, self.step_kinds, self.coupling.to_array(), self.y0, self.step,
                    self.n_steps, self.arrays, self.levels, self.explicit_muscles,
                    self.ground_steps)
                obj.population_residuals(
                    rows, self.levels, states, outputs, status, self.step,
                    self.arrays[1].shape[0], self.terms, out[begin:begin + m],
                    failed[begin:begin + m])
                continue
            states, _, outputs, status, starts = obj.run_own_models(
                rows, self.own_starts, self.step_kinds, self.coupling.to_array(), self.step,
                self.n_steps, self.explicit_muscles, self.ground_steps)
            for j, start in enumerate(starts):  # each from its own initial levels
                k = begin + j
                obj.population_residuals(
                    rows[j:j + 1], self.levels if start is None else start.levels,
                    states[j:j + 1], outputs[j:j + 1], status[j:j + 1], self.step,
                    self.arrays[1].shape[0], self.terms, out[k:k + 1], failed[k:k + 1])
        self.simulations += population.shape[0]
        self.failed_simulations += int(failed.sum())
        return out, failed

    def evaluate(self, population) -> tuple[np.ndarray, np.ndarray]:
        """Scores ‖r‖ (deg) and failure flags of the rows of ``population``."""
        residuals, failed = self.residuals(population)
        return np.sqrt(np.einsum("ij,ij->i", residuals, residuals)), failed

    def model_for(self, x) -> ChainModel:
        """The model with the activation ramps and the searched fields of the parameter
        vector ``x``."""
        return self.space.with_fields(with_ramps(self.model, x, self.initial_levels), x)

    def errors_deg(self, result) -> dict[str, tuple[float, float]]:
        """(RMS, max) angle error per scored joint of a simulation result at the target
        samples, deg; fixed-step results are sampled as in the fit (cubic Hermite)."""
        n = result.model.n_coordinates
        out = {}
        for row, (joint, j) in enumerate(zip(self.target.joints, self.scored, strict=True)):
            if result.step is not None:
                q, qd = np.empty_like(self.times), np.empty_like(self.times)
                obj.sample_joint(result.states, result.step, self.times, int(j), n, q, qd)
            else:
                q = np.interp(self.times, result.time, result.states[:, j])
            error = np.degrees(q - self.target.angles[row])
            out[joint] = (float(np.sqrt(np.mean(error**2))), float(np.max(np.abs(error))))
        return out

    def channel_errors(self, result) -> dict[str, tuple[float, float]]:
        """(RMS, max) error of each target channel of a simulation result at the target
        samples: ground reaction forces in % of body weight, the centre of mass in cm."""
        columns = result.columns()
        out = {}
        for name, target in self.target.channels.items():
            value = np.interp(self.times, result.time - result.time[0], columns[name])
            error = (value - target) * (100.0 / self.body_weight if name.startswith("grf")
                                        else 100.0)
            out[name] = (float(np.sqrt(np.mean(error**2))), float(np.max(np.abs(error))))
        return out

    def overall_rms(self, errors: dict[str, tuple[float, float]]) -> float:
        """√(Σ_j w_j·RMS_j²): the angle part of the objective, deg."""
        return float(math.sqrt(sum(w * errors[j][0] ** 2
                                   for j, w in zip(self.target.joints, self.weights,
                                                   strict=True))))

    def activations(self, x) -> np.ndarray:
        """Every unit's activation (units × target samples) under the parameter vector
        ``x``."""
        model = self.model_for(x)
        levels = model.initial_state().levels if self.space.fields else self.levels
        packed = model.pack(levels).activations
        return np.array([[activation(t, row, 0) for t in self.times] for row in packed])

    def mean_activations(self, x) -> dict[str, float]:
        """Each unit's mean activation over the target samples."""
        return dict(zip(self.space.units, np.mean(self.activations(x), axis=1).tolist(),
                        strict=True))

def _with_start(joint, angle: float, speed: float):
    return replace(joint, initial_angle=angle, initial_speed=speed)
