"""What a run returns: the trajectory, derived quantities, its cost and its stability."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..model.activation import activation
from ..model.elbow import ElbowModel, PackedModel
from ..model.torque_generator import (
    ACTIVATION_FLOOR,
    RK4_STABILITY_LIMIT,
    unit_ce_velocity,
    unit_time_constant,
    unit_torque,
)
from .rates import extensor_stretch, flexor_stretch

#: Output columns, in order (SI units, angles in rad).
COLUMNS = ("time", "theta", "omega", "theta_cc_flexor", "theta_cc_extensor", "torque_flexor",
           "torque_extensor", "torque_net", "activation_flexor", "activation_extensor",
           "omega_cc_flexor", "omega_cc_extensor")
UNITS = {"time": "s", "theta": "rad", "omega": "rad/s", "theta_cc_flexor": "rad",
         "theta_cc_extensor": "rad", "torque_flexor": "N·m", "torque_extensor": "N·m",
         "torque_net": "N·m", "activation_flexor": "-", "activation_extensor": "-",
         "omega_cc_flexor": "rad/s", "omega_cc_extensor": "rad/s"}
UNIT_NAMES = ("flexor", "extensor")


@njit(cache=True)
def derived_quantities(time, states, pf, pe, af, ae, out):
    """Fill ``out`` (n × 9) with T_F, T_E, T_net, a_F, a_E (floored), ω_cc,F, ω_cc,E,
    τ_F, τ_E at each row of ``states`` = (θ, ω, θ_cc,F, θ_cc,E)."""
    for i in range(time.shape[0]):
        t, th, tf, te = time[i], states[i, 0], states[i, 2], states[i, 3]
        s_f = flexor_stretch(th, tf)
        s_e = extensor_stretch(th, te)
        a_f = max(activation(t, af), ACTIVATION_FLOOR)
        a_e = max(activation(t, ae), ACTIVATION_FLOOR)
        torque_f = unit_torque(s_f, pf)
        torque_e = unit_torque(s_e, pe)
        w_f = unit_ce_velocity(s_f, tf, a_f, pf)
        w_e = unit_ce_velocity(s_e, te, a_e, pe)
        out[i, 0] = torque_f
        out[i, 1] = torque_e
        out[i, 2] = torque_f - torque_e
        out[i, 3] = a_f
        out[i, 4] = a_e
        out[i, 5] = w_f
        out[i, 6] = w_e
        out[i, 7] = unit_time_constant(w_f, tf, a_f, pf)
        out[i, 8] = unit_time_constant(w_e, te, a_e, pe)


@dataclass(frozen=True)
class RunCost:
    """What a run cost: steps, right-hand-side evaluations per part, wall time (s)."""

    steps: int
    rhs_body: int
    rhs_muscle: int
    wall_time: float


@dataclass(frozen=True)
class StabilityReport:
    """The stability guard of the explicit solvers.

    ``max_step_ratio`` is the largest step/τ seen (τ: a unit's CE time constant), at time
    ``time`` in unit ``unit``. ``exceeded`` is True when it passed the RK4 limit 2.785: the
    motion is then probably wrong although bounded. ``largest_safe_step`` (s) is
    2.785·min τ; when the limit was exceeded the τ seen belong to a wrong motion, so the
    suggestion is also capped at half the step used."""

    max_step_ratio: float
    time: float
    unit: str
    step: float
    limit: float = RK4_STABILITY_LIMIT

    @property
    def exceeded(self) -> bool:
        return self.max_step_ratio > self.limit

    @property
    def largest_safe_step(self) -> float:
        if self.max_step_ratio <= 0.0 or math.isinf(self.limit):
            return math.inf
        safe = self.limit * self.step / self.max_step_ratio
        return min(safe, 0.5 * self.step) if self.exceeded else safe

    def message(self) -> str:
        return (f"step {self.step * 1e3:g} ms exceeds the RK4 stability limit in the {self.unit} "
                f"unit at t = {self.time:.4f} s (step/τ = {self.max_step_ratio:.3g} > "
                f"{RK4_STABILITY_LIMIT:.3f}); the motion is probably wrong although bounded. "
                f"Use a step ≤ {self.largest_safe_step * 1e3:.3g} ms (estimated on this run's "
                "motion) or method 'reference'.")


@dataclass(frozen=True)
class SimulationResult:
    """A simulated motion.

    Attributes
    ----------
    time : ndarray, shape (n,)
        s.
    states : ndarray, shape (n, 4)
        (θ, ω, θ_cc,F, θ_cc,E), rad and rad/s.
    method : str
        ``monolithic``, ``partitioned[...]`` or ``reference``.
    step : float or None
        Fixed step, s (None for adaptive solvers).
    cost : RunCost
    stability : StabilityReport or None
        None for implicit solvers.
    status : str
        ``"success"`` or ``"failed"``; ``message`` says why.
    """

    model: ElbowModel
    packed: PackedModel = field(repr=False)
    time: np.ndarray = field(repr=False)
    states: np.ndarray = field(repr=False)
    method: str
    step: float | None
    cost: RunCost
    stability: StabilityReport | None
    status: str = "success"
    message: str = ""
    settings: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status == "success"

    @property
    def theta(self) -> np.ndarray:
        """Elbow flexion angle, rad."""
        return self.states[:, 0]

    @property
    def omega(self) -> np.ndarray:
        """Elbow angular velocity, rad/s."""
        return self.states[:, 1]

    def derived(self) -> np.ndarray:
        """(n × 9) T_F, T_E, T_net, a_F, a_E, ω_cc,F, ω_cc,E, τ_F, τ_E (see COLUMNS)."""
        out = np.empty((self.time.size, 9))
        p = self.packed
        derived_quantities(self.time, self.states, p.flexor, p.extensor, p.flexor_activation,
                           p.extensor_activation, out)
        return out

    def columns(self) -> dict[str, np.ndarray]:
        """The output table as ordered columns (names and order of :data:`COLUMNS`)."""
        d = self.derived()
        arrays = [self.time, *self.states.T, *d[:, :7].T]
        return dict(zip(COLUMNS, arrays, strict=True))

    def time_constants(self) -> tuple[np.ndarray, np.ndarray]:
        """CE time constants τ_F, τ_E (s) over the motion; inf where the CE is clamped."""
        d = self.derived()
        return d[:, 7], d[:, 8]

    def to_dataframe(self):
        """The output table as a pandas DataFrame (needs pandas)."""
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("to_dataframe needs pandas: pip install pandas") from exc
        return pd.DataFrame(self.columns())

    def peak(self) -> tuple[float, float]:
        """(peak angle in rad, its time in s)."""
        i = int(np.argmax(self.theta))
        return float(self.theta[i]), float(self.time[i])

    def save(self, path) -> None:
        """Write the table to ``.csv`` or OpenSim ``.sto``/``.mot`` (by extension), atomically,
        with a manifest ``<path>.manifest.json`` beside it."""
        from ..io.tables import save_result

        save_result(self, path)
