"""Goals of an optimisation: numbers computed from a run, to maximise or minimise.

=====================================  =====================================================
goal                                   value (SI; degrees only where printed)
=====================================  =====================================================
``jump_height``                        the centre of mass's apex above its start, m: after
                                       take-off t_off (the first sample with every contact
                                       unloaded after one was loaded), the highest y in flight
                                       − y(0) when the run reaches the apex in flight; a run
                                       that ends in flight before it, y(t_off) +
                                       max(v_y(t_off), 0)²/(2g) − y(0) (the flight is
                                       ballistic); max y − y(0) for a run that never leaves
                                       the ground. A run that touches down again before its
                                       apex made no jump: undefined
``com_speed_at_takeoff``               |v_CoM| at take-off, m/s (undefined without one)
``com_speed_x_at_takeoff``             v_CoM,x at take-off, m/s, forwards positive (the
                                       drift a jump should not have; undefined without one)
``peak_speed:JOINT``                   max |q̇| of the joint over the run, rad/s
``speed_at:JOINT=ANGLE``               |q̇| when q first reaches ANGLE, rad/s
``time_to:JOINT=ANGLE``                the time q first reaches ANGLE, s (linear between
                                       samples)
``final_angle:JOINT``                  q at the end of the run, rad
``effort``                             Σ_u mean_t a_u(t)², the units' activation profiles
=====================================  =====================================================

ANGLE is in degrees unless it ends in ``rad`` (``90deg``, ``90``, ``1.57rad``). A goal written
``W*GOAL`` carries the weight W > 0 (default 1). A goal that cannot be computed on a run (no
take-off, the angle never reached) makes that run fail, with the reason counted.

Several goals are combined into the cost that the search minimises,

    C = Σ_g w_g · σ_g · v_g / |v_g(start)|,   σ_g = −1 to maximise, +1 to minimise,

each goal measured in units of its value on the starting model (1 if that is 0), so that the
weights compare fractions of the start's values. In Python a goal may be any function of a
`SimulationResult` (`Goal.custom`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, check_range
from ..model.contact import take_off_index

#: Goal name → (needs a joint, needs an angle, unit of its value, needs ground contacts).
GOALS = {
    "jump_height": (False, False, "m", True),
    "com_speed_at_takeoff": (False, False, "m/s", True),
    "com_speed_x_at_takeoff": (False, False, "m/s", True),
    "peak_speed": (True, False, "rad/s", False),
    "speed_at": (True, True, "rad/s", False),
    "time_to": (True, True, "s", False),
    "final_angle": (True, False, "rad", False),
    "effort": (False, False, "", False),
}
SYNTAX = ("jump_height, com_speed_at_takeoff, com_speed_x_at_takeoff, peak_speed:JOINT, "
          "speed_at:JOINT=ANGLE, "
          "time_to:JOINT=ANGLE, final_angle:JOINT, effort (optionally W*GOAL)")
_SPEC = re.compile(r"\s*(?:([0-9.eE+-]+)\s*\*)?\s*([a-z_]+)\s*(?::\s*([A-Za-z0-9_.\-]+)\s*"
                   r"(?:=\s*([-+0-9.eE]+)\s*(deg|rad)?)?)?\s*")


@dataclass(frozen=True)
class Trial:
    """What the goals read from one run, on its sample grid (T samples).

    Attributes
    ----------
    time : ndarray (T,)
        s from the start.
    angles, speeds : ndarray (T, joints)
        Joint angles (rad) and angular velocities (rad/s), in model joint order.
    activations : ndarray (T, units)
        The units' activation profiles.
    com_y, com_speed_x, com_speed_y, grf_y : ndarray (T,) or None
        Centre-of-mass height (m), velocity (m/s) and total vertical ground reaction force (N)
        of a body on the ground; None otherwise.
    gravity : float
        m/s².
    """

    time: np.ndarray
    angles: np.ndarray
    speeds: np.ndarray
    activations: np.ndarray
    com_y: np.ndarray | None = None
    com_speed_x: np.ndarray | None = None
    com_speed_y: np.ndarray | None = None
    grf_y: np.ndarray | None = None
    gravity: float = 9.81

    @classmethod
    def of(cls, result) -> Trial:
        """The trial of a `SimulationResult`."""
        model = result.model
        cols = result.columns()
        angles = np.column_stack([cols[j.coordinate] for j in model.joints])
        speeds = np.column_stack([cols[f"{j.coordinate}_speed"] for j in model.joints])
        elapsed = result.time - result.time[0]
        starts = result.packed.activations[:, 0]  # each profile's initial level a_0
        activations = np.column_stack([unit.activation(elapsed, a0) for unit, a0 in
                                       zip(model.units, starts, strict=True)])
        ground = {}
        if model.contacts:
            ground = {k: cols[c] for k, c in (("com_y", "com_y"), ("com_speed_x", "com_speed_x"),
                                              ("com_speed_y", "com_speed_y"),
                                              ("grf_y", "grf_y"))}
        return cls(elapsed, angles, speeds, activations,
                   gravity=model.gravity, **ground)


def jump_height(trial: Trial, take_off: int | None) -> tuple[float, str]:
    """(apex of the centre of mass above its start, m; "") or (NaN, why): the highest point in
    flight when the run reaches its apex before touching down, the ballistic apex from
    take-off when the run ends in flight before it, max y − y(0) without a take-off."""
    y = trial.com_y
    if take_off is None:
        return float(np.max(y) - y[0]), ""
    i = take_off
    after = np.arange(y.size) > i
    down = np.flatnonzero(after & (trial.grf_y > 0.0))
    falling = np.flatnonzero(after & (trial.com_speed_y <= 0.0))
    landing = int(down[0]) if down.size else None
    if falling.size and (landing is None or falling[0] < landing):
        return float(np.max(y[i:landing]) - y[0]), ""
    if landing is not None:
        return math.nan, "touched down again before its apex (no jump)"
    flight = max(float(trial.com_speed_y[i]), 0.0) ** 2 / (2.0 * trial.gravity)
    return float(y[i] + flight - y[0]), ""


def _crossing(time, q, angle) -> tuple[int, float] | None:
    """(sample index before, fraction) where q first reaches ``angle`` (None: never)."""
    side = np.sign(q - angle)
    if side[0] == 0:
        return 0, 0.0
    change = np.flatnonzero(side[1:] != side[0])
    if not change.size:
        return None
    i = int(change[0])
    fraction = (angle - q[i]) / (q[i + 1] - q[i])
    return i, float(fraction)


@dataclass(frozen=True)
class Goal:
    """One goal: what to compute, in which direction, with what weight.

    Attributes
    ----------
    name : str
        A key of `GOALS`, or ``custom``.
    maximise : bool
    weight : float
        w > 0. Default 1.
    joint : str or None
        The joint of ``peak_speed``, ``speed_at``, ``time_to``, ``final_angle``.
    angle : float or None
        rad, for ``speed_at`` and ``time_to``.
    function : callable or None
        ``custom``: f(SimulationResult) → float (NaN when undefined).
    label : str
        How the goal was written (the summary's name for it).
    """

    name: str
    maximise: bool
    weight: float = 1.0
    joint: str | None = None
    angle: float | None = None
    function: Callable | None = None
    label: str = ""

    @classmethod
    def custom(cls, function: Callable, *, maximise: bool, weight: float = 1.0,
               label: str = "custom") -> Goal:
        """A goal computed by ``function(result)`` from each run's `SimulationResult`
        (slower than the named goals: every candidate's result is built in Python)."""
        return cls("custom", maximise, check_range("weight", weight, 0.0, low_open=True),
                   function=function, label=label)

    @property
    def unit(self) -> str:
        return "" if self.name == "custom" else GOALS[self.name][2]

    def value(self, trial: Trial, joints: tuple[str, ...]) -> tuple[float, str]:
        """(value, "") or (NaN, why it is undefined) on ``trial``; ``joints``: the model's
        joint names."""
        name = self.name
        if name == "effort":
            return float(np.sum(np.mean(trial.activations**2, axis=0))), ""
        if name in ("jump_height", "com_speed_at_takeoff", "com_speed_x_at_takeoff"):
            i = take_off_index(trial.grf_y)
            if name != "jump_height":
                if i is None:
                    return math.nan, "no take-off"
                if name == "com_speed_x_at_takeoff":
                    return float(trial.com_speed_x[i]), ""
                return float(math.hypot(trial.com_speed_x[i], trial.com_speed_y[i])), ""
            return jump_height(trial, i)
        j = joints.index(self.joint)
        q, qd = trial.angles[:, j], trial.speeds[:, j]
        if name == "peak_speed":
            return float(np.max(np.abs(qd))), ""
        if name == "final_angle":
            return float(q[-1]), ""
        hit = _crossing(trial.time, q, self.angle)
        if hit is None:
            return math.nan, f"{self.joint} never reaches {math.degrees(self.angle):g} deg"
        i, f = hit
        if name == "time_to":
            return float(trial.time[i] + f * (trial.time[min(i + 1, q.size - 1)]
                                              - trial.time[i])), ""
        return float(abs(qd[i] + f * (qd[min(i + 1, q.size - 1)] - qd[i]))), ""

    def shown(self, value: float) -> str:
        """``value`` as the summary prints it (angles and angular speeds in degrees)."""
        if not math.isfinite(value):
            return "undefined"
        if self.unit == "rad":
            return f"{math.degrees(value):.3f} deg"
        if self.unit == "rad/s":
            return f"{math.degrees(value):.2f} deg/s"
        if self.unit == "m":
            return f"{value * 100:.2f} cm"
        if self.unit == "s":
            return f"{value * 1000:.1f} ms"
        return f"{value:.5g}{' ' + self.unit if self.unit else ''}"


def parse_goal(text: str, model, *, maximise: bool, field: str = "goal") -> Goal:
    """A `Goal` from its written form (module docstring), checked against ``model``: the
    joint must exist, contact goals need a body on the ground. A `ModelError` on ``field``
    otherwise."""
    m = _SPEC.fullmatch(text)
    if not m or m.group(2) not in GOALS:
        raise ModelError(field, f"{text!r} is not a goal; allowed: {SYNTAX}")
    weight_text, name, joint, angle_text, unit = m.groups()
    needs_joint, needs_angle, _unit, needs_ground = GOALS[name]
    weight = 1.0
    if weight_text is not None:
        try:
            weight = float(weight_text)
        except ValueError:
            weight = math.nan
        if not (math.isfinite(weight) and weight > 0):
            raise ModelError(field, f"{text!r}: weight {weight_text!r}; allowed a number > 0 "
                             "before '*', e.g. 0.1*effort")
    if needs_joint != (joint is not None) or needs_angle != (angle_text is not None):
        form = name + (":JOINT" if needs_joint else "") + ("=ANGLE" if needs_angle else "")
        raise ModelError(field, f"{text!r}: allowed {form}, e.g. "
                         + {"peak_speed": "peak_speed:elbow", "speed_at": "speed_at:elbow=90deg",
                            "time_to": "time_to:elbow=90deg",
                            "final_angle": "final_angle:elbow"}.get(name, name))
    names = tuple(j.name for j in model.joints)
    if joint is not None and joint not in names:
        raise ModelError(field, f"{text!r}: no joint {joint!r}; allowed: {', '.join(names)}")
    if needs_ground and not model.contacts:
        raise ModelError(field, f"{text!r} needs a body on the ground (ground contacts); "
                         "this model has none; allowed: " + ", ".join(
                             k for k, v in GOALS.items() if not v[3]))
    angle = None
    if angle_text is not None:
        try:
            angle = float(angle_text)
        except ValueError:
            raise ModelError(field, f"{text!r}: {angle_text!r} is not an angle; allowed "
                             "e.g. 90deg or 1.57rad") from None
        if unit == "rad":
            check_range(f"{field}.{text.strip()}", angle, -2 * math.pi, 2 * math.pi,
                        unit="rad")
        else:
            angle = math.radians(check_range(f"{field}.{text.strip()}", angle, -360.0,
                                             360.0, unit="deg"))
        start = next(j.initial_angle for j in model.joints if j.name == joint)
        if abs(start - angle) <= 1e-9:
            raise ModelError(field, f"{text!r}: {joint} starts at {math.degrees(start):g} deg, "
                             "so the goal is met at t = 0; allowed: an angle the joint moves "
                             "to")
    return Goal(name, maximise, weight, joint, angle, label=text.strip())


@dataclass(frozen=True)
class Constraint:
    """A goal's value held within bounds: a candidate outside them is infeasible (the search
    ranks it below every feasible one, nearer ones first).

    Attributes
    ----------
    goal : Goal
        What is constrained (its direction and weight are not used).
    low, high : float
        Bounds in the goal's SI unit (`GOALS`: m, m/s, s, rad, rad/s); ±inf for none.
    """

    goal: Goal
    low: float = -math.inf
    high: float = math.inf

    def violation(self, value: float) -> float:
        """How far ``value`` lies outside the bounds, in units of their width (or of the
        bound's size, for one bound); 0 inside, inf for NaN."""
        if not math.isfinite(value):
            return math.inf
        width = self.high - self.low
        if not math.isfinite(width):
            width = max(abs(b) for b in (self.low, self.high) if math.isfinite(b)) or 1.0
        width = max(width, 1e-12)
        return max(self.low - value, value - self.high, 0.0) / width

    def shown(self) -> str:
        """The bounds as the summary prints them."""
        low = "" if self.low == -math.inf else self.goal.shown(self.low)
        high = "" if self.high == math.inf else self.goal.shown(self.high)
        return f"{low or '−∞'} to {high or '∞'}"


def parse_constraint(text: str, model, field: str = "constrain") -> Constraint:
    """``GOAL=LOW..HIGH`` (either bound may be left out: ``GOAL=..0.1``) → `Constraint`: GOAL
    as `parse_goal`, the bounds in its unit, degrees (deg/s) for angles (angular speeds), e.g.
    ``com_speed_x_at_takeoff=-0.1..0.1``, ``final_angle:elbow=..150``."""
    goal_text, eq, bounds = text.rpartition("=")
    low_text, dots, high_text = bounds.partition("..")
    example = "com_speed_x_at_takeoff=-0.1..0.1"
    if not eq or not dots or not goal_text.strip():
        raise ModelError(field, f"{text!r}: allowed GOAL=LOW..HIGH, e.g. {example}")
    goal = parse_goal(goal_text, model, maximise=False, field=field)
    scale = 1.0 if goal.unit not in ("rad", "rad/s") else math.pi / 180.0
    numbers = []
    for part, missing in ((low_text, -math.inf), (high_text, math.inf)):
        try:
            value = float(part) * scale if part.strip() else missing
        except ValueError:
            value = math.nan
        if math.isnan(value):
            raise ModelError(field, f"{text!r}: {part.strip()!r} is not a number; allowed "
                             f"GOAL=LOW..HIGH, e.g. {example}")
        numbers.append(value)
    low, high = numbers
    if not low < high:
        raise ModelError(field, f"{text!r}: allowed LOW < HIGH (or one bound left out)")
    return Constraint(goal, low, high)
