"""A fit problem: the target, the model around it, the technique, and the objective."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError, check_range
from ..model.elbow import ElbowModel, default_model
from ..solvers.coupling import IMEX, Coupling
from ..solvers.simulate import simulate
from . import objective as obj
from .parameters import ParameterSpace, profiles
from .target import Target

FIT_METHODS = ("imex", "monolithic", "partitioned")
DEFAULT_METHOD = "imex"
#: Default fit step, s: IMEX is stable at any step; 5 ms keeps it within ~0.3° of the
#: reference on the default curl.
DEFAULT_STEP = 5.0e-3


def fit_step(duration: float, requested: float) -> tuple[float, int]:
    """The largest step ≤ ``requested`` that divides ``duration``, and the step count."""
    check_range("step", requested, 0.0, duration, low_open=True, unit="s")
    n = math.ceil(duration / requested - 1e-9)
    return duration / n, n


@dataclass
class FitProblem:
    """Everything the objective needs, with the model's arrays packed once.

    The model spans the target: θ0 = the first target angle (static equilibrium there, the
    flexor's initial level from it), duration = target span. ``evaluate`` scores
    candidate 18-vectors (see :mod:`torquesim.fitting.objective`) and counts simulations.
    """

    target: Target
    space: ParameterSpace = field(default_factory=ParameterSpace)
    base_model: ElbowModel | None = None
    method: str = DEFAULT_METHOD
    step: float = DEFAULT_STEP
    weight_velocity: float = 0.0
    weight_end: float = 0.0
    simulations: int = 0
    failed_simulations: int = 0

    def __post_init__(self) -> None:
        if self.method not in FIT_METHODS:
            raise ModelError("method", f"{self.method!r}; allowed: {', '.join(FIT_METHODS)}")
        check_range("weight_velocity", self.weight_velocity, 0.0, 1e3)
        check_range("weight_end", self.weight_end, 0.0, 1e3)
        base = self.base_model or default_model()
        if not isinstance(base, ElbowModel):
            base = ElbowModel.from_chain(base, "fit")
        self.requested_step = self.step
        self.step, self.n_steps = fit_step(self.target.duration, self.step)
        flexor, extensor = profiles(np.array(self.space.upper), self.space.extensor_rest)
        try:
            self.model = base.replace(initial_angle=float(self.target.angle[0]),
                                      duration=self.target.duration,
                                      flexor_activation=flexor, extensor_activation=extensor)
        except ModelError as exc:
            raise ModelError("target", f"cannot start at its first angle "
                             f"{math.degrees(self.target.angle[0]):.2f}°: {exc.reason}") from None
        start = self.model.initial_state()
        self.y0 = start.state
        self.level_f, self.level_e = start.flexor_level, start.extensor_level
        self.coupling = {"imex": IMEX, "partitioned": Coupling(),
                         "monolithic": Coupling()}[self.method]
        packed = self.model.to_chain().pack()
        self.arrays = (packed.segments, packed.joints, packed.units)
        self.times = np.ascontiguousarray(self.target.elapsed)
        self.target_omega = self.target.angular_velocity()

    @property
    def explicit_muscles(self) -> bool:
        return self.method != "imex"

    def evaluate(self, population) -> tuple[np.ndarray, np.ndarray]:
        """Scores (deg) and failure flags of the rows (18-vectors) of ``population``."""
        population = np.ascontiguousarray(np.atleast_2d(population), dtype=float)
        scores = np.empty(population.shape[0])
        failed = np.zeros(population.shape[0], dtype=np.bool_)
        seg, joints, units = self.arrays
        obj.score_population(
            population, obj.MONOLITHIC if self.method == "monolithic" else obj.PARTITIONED,
            self.coupling.to_array(), self.y0, self.step, self.n_steps, seg, joints, units,
            self.level_f, self.level_e, self.explicit_muscles, self.times, self.target.angle,
            self.target_omega, self.weight_velocity, self.weight_end, scores, failed)
        self.simulations += population.shape[0]
        self.failed_simulations += int(failed.sum())
        return scores, failed

    def model_for(self, x) -> ElbowModel:
        """The model with the activation profiles of the 18-vector ``x``."""
        flexor, extensor = profiles(x, self.space.extensor_rest)
        return self.model.replace(flexor_activation=flexor, extensor_activation=extensor)

    def errors_deg(self, result) -> tuple[float, float]:
        """(RMS, max) angle error of a simulation result at the target samples, deg."""
        theta = np.interp(self.times, result.time, result.theta)
        if result.step is not None:  # fixed step: the same Hermite sampling as the fit
            omega = np.empty_like(theta)
            obj.sample_motion(result.states, result.step, self.times, theta, omega)
        error = np.degrees(theta - self.target.angle)
        return float(np.sqrt(np.mean(error**2))), float(np.max(np.abs(error)))

    def reference_errors_deg(self, x) -> tuple[float, float]:
        """(RMS, max) angle error of ``x`` re-simulated with the reference solver, deg."""
        ref = simulate(self.model_for(x), "reference", output_step=self.step)
        return self.errors_deg(ref)
