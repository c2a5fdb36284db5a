"""What a run returns: the trajectory, derived quantities, its cost and its stability."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..model.body import (
    CONTACT_SLOTS,
    JOINT_ROW_SIZE,
    body_accelerations,
    body_work_size,
    contacts_start,
    ground_kinds,
    passive_torque,
)
from ..model.chain import UNIT_ROW_SIZE, ChainModel, PackedChain
from ..model.contact import take_off_index
from ..model.jit import njit
from ..model.state import unit_state
from ..model.torque_generator import (
    ACTIVATION_FLOOR,
    unit_ce_velocity,
    unit_time_constant,
    unit_torque,
)
from .fixed_step import RK4_STABILITY_LIMIT
from .rates import (
    flat_arrays,
    joint_muscle_torques,
    unit_angle_at,
    unit_excitation,
    unit_level,
    unit_stretch,
)


@njit(cache=True)
def derived_quantities(time, states, system, outputs, ground):
    """Per row of ``states`` (y): fill ``unit_out`` (rows × U × 5) with each unit's torque T
    (N·m), activation max(a, 0.01), CE velocity ω_cc (rad/s), CE time constant τ (s) and
    profile value e(t);
    and ``joint_out`` (rows × n × 2) with each joint's net muscle torque (Σ over units of the
    moment arm × T) and end-stop
    torque T_p (N·m); and ``contact_out`` (rows × contacts × 4) with each contact's force
    and point. ``system``: the 2-D arrays of `PackedChain`; ``outputs`` = (unit_out,
    joint_out, contact_out); ``ground`` the `BodyKinds` of a body on the ground, else None
    (`ground_kinds`: then no contact code is compiled)."""
    unit_out, joint_out, contact_out = outputs
    seg = system[0]
    n, nu, width, units, joints, profiles = flat_arrays(system)
    torque = np.empty(n)
    n_contacts = contact_out.shape[1]
    work = np.empty(body_work_size(n, seg))
    start = contacts_start(n)
    for i in range(time.shape[0]):
        y = states[i]
        joint_muscle_torques(y, y, units, nu, torque, n)
        if ground is not None:
            if n_contacts > 0:
                body_accelerations(y, n, torque, seg, joints, work, ground)
                for c in range(n_contacts):
                    for k in range(4):
                        contact_out[i, c, k] = work[start + CONTACT_SLOTS * c + k]
        for j in range(n):
            joint_out[i, j, 0] = torque[j]
            joint_out[i, j, 1] = passive_torque(y[j], joints, j * JOINT_ROW_SIZE)
        for u in range(nu):
            o = u * UNIT_ROW_SIZE
            k = unit_state(n, units, u)
            theta_cc = y[k]
            stretch = unit_stretch(unit_angle_at(y, units, u), theta_cc, units, u)
            excitation = unit_excitation(time[i], profiles, width, u)
            level = max(unit_level(excitation, y, k, units, u), ACTIVATION_FLOOR)
            w = unit_ce_velocity(stretch, theta_cc, level, units, np.nan, o)
            unit_out[i, u, 0] = unit_torque(stretch, units, o)
            unit_out[i, u, 1] = level
            unit_out[i, u, 2] = w
            unit_out[i, u, 3] = unit_time_constant(w, theta_cc, level, units, o)
            unit_out[i, u, 4] = excitation


@dataclass(frozen=True)
class GroundEvents:
    """What a run of a body on the ground did (`SimulationResult.ground_events`).

    ``take_off``: the first sample (s) at which every contact is unloaded after one was
    loaded; ``landing``: the first loaded sample after it (None: not within the run; 0 for a
    model that starts at touchdown, `ChainModel.landing_speed`).
    ``rise``: the centre of mass's highest point above its start, m, at ``apex_time`` (s);
    ``sink``: its lowest point below its start, m, at ``lowest_time`` (s);
    ``flight_height``: v²/(2g) of its vertical speed at take-off, m (the height the flight
    phase adds; None without a take-off). ``peak_force``: the largest total vertical ground
    reaction force, N, at ``peak_time``; ``weight``: body weight, N; ``touchdown_speed``:
    the model's landing speed, m/s (0 when it starts standing)."""

    take_off: float | None
    landing: float | None
    rise: float
    apex_time: float
    flight_height: float | None
    peak_force: float
    peak_time: float
    weight: float
    sink: float = 0.0
    lowest_time: float = 0.0
    touchdown_speed: float = 0.0

    def summary_lines(self) -> list[str]:
        """The events as the command line's summary prints them."""
        lines = []
        if self.touchdown_speed:
            lines.append(f"touchdown     t = 0 at {self.touchdown_speed:.3g} m/s; the centre of "
                         f"mass sinks {self.sink:.4f} m, lowest at t = {self.lowest_time:.4f} s")
        if self.take_off is None:
            lines.append("take-off      none (some contact stays loaded)")
        else:
            lines.append(f"take-off      t = {self.take_off:.4f} s; flight adds "
                         f"{self.flight_height:.4f} m (v²/2g of the take-off speed)")
        if self.rise > 0.0 or not self.touchdown_speed:
            lines.append(f"CoM rise      {self.rise:.4f} m above the start, apex at t = "
                         f"{self.apex_time:.4f} s")
        lines.append(f"peak GRF      {self.peak_force:.1f} N ({self.peak_force / self.weight:.2f} "
                     f"body weights) at t = {self.peak_time:.4f} s")
        if self.take_off is not None:
            lines.append("landing       " + (f"t = {self.landing:.4f} s" if self.landing is not None
                                            else "not within the run"))
        return lines


@dataclass(frozen=True)
class RunCost:
    """What a run cost: deterministic work counts and the wall time (s).

    ``rhs_body``: evaluations of the body part's right-hand side (joint accelerations);
    ``rhs_muscle``: explicit evaluations of the muscle part (every unit's CE velocity);
    ``newton_iterations``: residual evaluations of the implicit unit equations (each a Newton
    iteration with its scalar linear solve; IMEX); ``implicit_solves``: implicit stage
    equations solved; ``jacobians`` and ``lu_decompositions``: the implicit body part's
    linearisations of its stiff forces, each with its factorisation (ROS2, one per step).
    For SciPy's solvers ``rhs_body`` = ``rhs_muscle`` = whole-system calls, ``jacobians`` and
    ``lu_decompositions`` their Jacobians and LU factorisations."""

    steps: int
    rhs_body: int
    rhs_muscle: int
    wall_time: float
    newton_iterations: int = 0
    implicit_solves: int = 0
    jacobians: int = 0
    lu_decompositions: int = 0


@dataclass(frozen=True)
class StabilityReport:
    """The stability guard of the explicit solvers.

    ``max_step_ratio`` is the largest step/τ seen (τ: a unit's CE time constant, or a ground
    contact's, `contact_time_constant`), at time ``time`` in unit ``unit`` (or "ground
    contact at POINT"): of the two, the one nearer its limit (a contact's is RK4's, the
    body part's explicit solver; none with the body on ROS2). ``exceeded`` is True when it
    passed the RK4 limit 2.785: the motion is then probably wrong although bounded.
    ``largest_safe_step`` (s) is the step found by running (``verified_step``, see
    `torquesim.solvers.simulation.verified_run`) when the run failed or broke the limit;
    otherwise the estimate 2.785·min τ of this run."""

    max_step_ratio: float
    time: float
    unit: str
    step: float
    limit: float = RK4_STABILITY_LIMIT
    verified_step: float | None = None

    @property
    def exceeded(self) -> bool:
        return self.max_step_ratio > self.limit

    @property
    def largest_safe_step(self) -> float:
        if self.verified_step is not None:
            return self.verified_step
        if self.max_step_ratio <= 0.0 or math.isinf(self.limit):
            return math.inf
        safe = self.limit * self.step / self.max_step_ratio
        return min(safe, 0.5 * self.step) if self.exceeded else safe

    @property
    def in_contact(self) -> bool:
        """Whether the binding time constant is a ground contact's (explicit in the body
        part's RK4, IMEX's included: a smaller step, ``imex-ros2`` or Radau helps)."""
        return self.unit.startswith("ground contact")

    def message(self) -> str:
        where = self.unit if self.in_contact else f"the {self.unit} unit"
        others = ("method 'imex-ros2' (implicit contacts) or 'reference'" if self.in_contact else
                  "method 'imex' (implicit muscles) or 'reference'")
        head = (f"step {self.step * 1e3:g} ms exceeds the RK4 stability limit in "
                f"{where} at t = {self.time:.4f} s (step/τ = {self.max_step_ratio:.3g} "
                f"> {RK4_STABILITY_LIMIT:.3f}); the motion is probably wrong although bounded. ")
        safe = self.largest_safe_step
        if self.verified_step == 0.0:
            return head + ("No smaller step tried (down to 1/256 of it, runs of at most 1e6 "
                           f"steps) passed: use {others}.")
        how = ("a run at that step was checked" if self.verified_step is not None
               else "estimated on this run's motion")
        return head + f"Use a step ≤ {safe * 1e3:.4g} ms ({how}) or {others}."


@dataclass(frozen=True)
class SimulationResult:
    """A simulated motion.

    Attributes
    ----------
    model : ChainModel
    time : ndarray, shape (n,)
        s.
    states : ndarray, shape (n, 2·joints + units)
        y = (q, q̇, θ_cc of every unit), rad and rad/s (names: ``model.state_names()``).
    method : str
        ``monolithic``, ``partitioned[...]``, ``imex``, ``reference`` or ``scipy:NAME``.
    step : float or None
        Fixed step, s (None for adaptive solvers).
    cost : RunCost
    stability : StabilityReport or None
        None for adaptive solvers.
    status : str
        ``"success"`` or ``"failed"``; ``message`` says why (or warns).
    """

    model: ChainModel
    packed: PackedChain = field(repr=False)
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
    def q(self) -> np.ndarray:
        """Joint angles, rad, shape (n, joints)."""
        return self.states[:, self.model.layout.angles]

    @property
    def qd(self) -> np.ndarray:
        """Joint angular velocities, rad/s, shape (n, joints)."""
        return self.states[:, self.model.layout.speeds]

    @property
    def theta_cc(self) -> np.ndarray:
        """CE angles of the units, rad, shape (n, units)."""
        return self.states[:, self.model.layout.theta_cc]

    @property
    def theta(self) -> np.ndarray:
        """Angle of the first (for the elbow: the only) joint, rad."""
        return self.q[:, 0]

    @property
    def omega(self) -> np.ndarray:
        """Angular velocity of the first joint, rad/s."""
        return self.qd[:, 0]

    def angle(self, joint: str) -> np.ndarray:
        """Angle of the joint named ``joint``, rad."""
        return self.q[:, self.model.joint_index(joint)]

    def _derived(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per unit (T, a, ω_cc, τ, e), per joint (net muscle torque, end-stop torque) and
        per contact (F_x, F_y, x, y) over the run."""
        nu, nb, nc = self.model.n_units, self.model.n_base, self.model.n_coordinates
        unit_out = np.empty((self.time.size, nu, 5))
        joint_out = np.empty((self.time.size, nc, 2))
        contact_out = np.zeros((self.time.size, len(self.model.contacts), 4))
        derived_quantities(self.time, self.states, tuple(self.packed),
                           (unit_out, joint_out, contact_out),
                           ground_kinds(self.packed.segments, nc))
        return unit_out, joint_out[:, nb:], contact_out

    def columns(self) -> dict[str, np.ndarray]:
        """The output table as ordered columns, SI units, angles in rad: ``time``; per joint
        its coordinate (e.g. ``elbow_flexion``) and ``<coordinate>_speed``; per unit
        ``theta_cc_<unit>``; per unit ``torque_<unit>``; per joint ``torque_net_<joint>``
        (muscles, flexion positive) and ``torque_passive_<joint>`` (end stops); per unit
        ``activation_<unit>`` (floored at 0.01) and ``omega_cc_<unit>`` (concentric
        positive). A unit with activation dynamics adds its state ``activation_state_<unit>``
        after its θ_cc and its profile value ``excitation_<unit>``. A free base starts with
        ``base_x``, ``base_y`` (m) and their speeds; named points add ``<point>_x``,
        ``<point>_y`` and the centre of mass ``com_x``, ``com_y``, ``com_speed_x``,
        ``com_speed_y`` (m, m/s); ground contacts add their forces ``grf_x_<point>``,
        ``grf_y_<point>`` and the totals ``grf_x``, ``grf_y`` (N) with the centre of pressure
        ``cop_x`` (m; NaN in flight)."""
        unit_out, joint_out, contact_out = self._derived()
        m = self.model
        values = [self.time, *self.states.T, *unit_out[:, :, 0].T]
        for j in range(m.n_joints):
            values += [joint_out[:, j, 0], joint_out[:, j, 1]]
        values += [*unit_out[:, :, 1].T, *unit_out[:, :, 2].T]
        values += [unit_out[:, u, 4] for u, unit in enumerate(m.units)
                   if unit.activation_dynamics is not None]
        if m.points or m.base == "free":
            where = self.kinematics()
            for i in range(len(m.points)):
                values += [where["points"][:, i, 0], where["points"][:, i, 1]]
            values += [*where["com"].T, *where["com_velocity"].T]
        if m.contacts:
            for c in range(len(m.contacts)):
                values += [contact_out[:, c, 0], contact_out[:, c, 1]]
            total = contact_out[:, :, 1].sum(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                pressure = np.where(total > 0, (contact_out[:, :, 1] * contact_out[:, :, 2])
                                    .sum(axis=1) / total, np.nan)
            values += [contact_out[:, :, 0].sum(axis=1), total, pressure]
        return dict(zip(m.output_columns(), values, strict=True))

    def ground_events(self) -> GroundEvents | None:
        """Take-off, landing and jump height of a body on the ground (None without contacts):
        see `GroundEvents`."""
        m = self.model
        if not m.contacts:
            return None
        c = self.columns()
        loaded = c["grf_y"] > 0.0
        weight = m.weight
        peak = int(np.argmax(c["grf_y"]))
        rise = float(c["com_y"].max() - c["com_y"][0])
        take_off = landing = None
        flight = None
        i = take_off_index(c["grf_y"])
        if i is not None:
            take_off = float(self.time[i])
            speed = float(c["com_speed_y"][i])
            flight = max(speed, 0.0) ** 2 / (2.0 * m.gravity) if m.gravity > 0 else math.inf
            back = np.flatnonzero(loaded[i:])
            landing = float(self.time[i + back[0]]) if back.size else None
        if m.landing_speed and take_off is None:
            landing = 0.0
        low = int(np.argmin(c["com_y"]))
        return GroundEvents(take_off, landing, rise, float(self.time[int(np.argmax(c["com_y"]))]),
                            flight, float(c["grf_y"][peak]), float(self.time[peak]), weight,
                            float(c["com_y"][0] - c["com_y"][low]), float(self.time[low]),
                            m.landing_speed)

    def kinematics(self) -> dict[str, np.ndarray]:
        """Positions and velocities over the run (`ChainModel.kinematics`): joints, centres,
        points, the centre of mass, m and m/s."""
        layout = self.model.layout
        return self.model.kinematics(self.states[:, layout.coordinates],
                                     self.states[:, layout.coordinate_speeds])

    def time_constants(self) -> dict[str, np.ndarray]:
        """Each unit's CE time constant τ (s) over the motion; inf where the CE is clamped."""
        unit_out, _, _ = self._derived()
        return {unit.name: unit_out[:, u, 3] for u, unit in enumerate(self.model.units)}

    def to_dataframe(self):
        """The output table as a pandas DataFrame (needs pandas)."""
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("to_dataframe needs pandas: pip install pandas") from exc
        return pd.DataFrame(self.columns())

    def peak(self, joint: str | None = None) -> tuple[float, float]:
        """(peak angle in rad, its time in s) of ``joint`` (default: the first joint)."""
        angle = self.theta if joint is None else self.angle(joint)
        i = int(np.argmax(angle))
        return float(angle[i]), float(self.time[i])
