"""Inverse-dynamics initial guess for the fit, on any chain.

On a body on the ground (free base) the inverse dynamics holds the root segment's proximal
point where it stands while the body is on the ground (the foot planted: the ground supplies
whatever force the motion needs), and lets the body fly free (no contact force; the root's
angle then follows from the joint torques, so only the joints' equations are solved) where
the target's vertical ground reaction force is below 1 % of body weight. Without a force
target the body is taken to be on the ground throughout.

1. Smooth each scored joint's target (a smoothing spline, GCV) and differentiate: q, q̇, q̈.
   Joints without a target stay at their initial angle.
2. Net muscle torque per joint the motion needs: the body equation (docs/model.md §7) is
   affine in the joint muscle torques, q̈ = q̈₀(q, q̇) + B(q)·τ, so τ = B⁻¹(q̈ − q̈₀), with B's
   columns from n + 1 evaluations of `joint_accelerations`.
3. Quasi-static activations: each CE moves with its unit angle ψ (its joint's angle, or
   q_j + d·r·q_j2 for a two-joint unit; SE stretch changing slowly), so a unit of direction d
   carries a·T_θ(ψ + d·T/k)·h(d·ψ̇). Units with a rest level stay at it;
   the torque still needed is carried by the units of its direction that start from
   equilibrium (the agonists; all units of that direction if none does) at one common
   level, the others of that direction at 0 (or their rest level).
4. Ramps: the three-ramp profile of each unit closest (least squares) to its activation.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from ..model.activation import activation
from ..model.body import (
    body_kinds,
    body_work_size,
    joint_accelerations,
    single_segment_acceleration,
)
from ..model.chain import agonist_level
from ..model.torque_generator import ce_torque_velocity, torque_angle
from .objective import PROFILE_SIZE, pack_profile
from .parameters import PER_UNIT, RAMPS_PER_UNIT

#: Spacing of the inverse-dynamics grid, s.
GRID = 0.005
#: A body on the ground is in flight where the target's vertical GRF is below this fraction
#: of body weight.
FLIGHT_FORCE = 0.01
#: Height of the root in the flight equations, m: far above any contact.
FLIGHT_HEIGHT = 1.0e3


def _accelerations(y, n, torque, seg, joints, work) -> np.ndarray:
    """q̈ (n,) at the state ``y`` under the joint ``torque``: the one-segment division on a
    fixed pivot (so that an elbow fit compiles no chain solve), else the general solve."""
    if body_kinds(seg, n) is None:
        return np.array([single_segment_acceleration(y[0], torque[0], seg, joints)])
    joint_accelerations(y, n, torque, seg, joints, work)
    return work[n * n:n * n + n].copy()


def _torque_columns(y, n, actuated, seg, joints, work):
    """q̈₀ (the accelerations without muscle torque) and B's columns of the ``actuated``
    coordinates, (n,) and (n, len(actuated)), at the state ``y``."""
    free = _accelerations(y, n, np.zeros(n), seg, joints, work)
    columns = np.empty((n, len(actuated)))
    for c, j in enumerate(actuated):
        unit = np.zeros(n)
        unit[j] = 1.0
        columns[:, c] = _accelerations(y, n, unit, seg, joints, work) - free
    return free, columns


def flight_samples(model, target, t) -> np.ndarray:
    """Which grid times ``t`` (s from the target start) the body is in flight: a free base
    and the target's vertical ground reaction force below `FLIGHT_FORCE` of body weight."""
    if model.base != "free" or "grf_y" not in target.channels:
        return np.zeros(t.size, dtype=bool)
    return np.interp(t, target.elapsed, target.channels["grf_y"]) < FLIGHT_FORCE * model.weight


def required_torques(model, target, spacing: float = GRID):
    """(t, q, q̇, τ) on a regular grid (s from the target start): joint angles and speeds
    (n × samples) and the net muscle torque at each joint, N·m, that makes the body follow
    the smoothed target. ``model`` is the fit's chain (starting at the target); on a free
    base, see the module docstring (the root's torque is then 0)."""
    n, nb = model.n_joints, model.n_base
    t = np.linspace(0.0, target.duration, int(round(target.duration / spacing)) + 1)
    q = np.array([np.full(t.size, j.initial_angle) for j in model.joints])
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    names = [j.name for j in model.joints]
    for row, joint in enumerate(target.joints):
        spline = target.smoothed(row)
        k = names.index(joint)
        q[k], qd[k], qdd[k] = spline(t), spline.derivative(1)(t), spline.derivative(2)(t)
    seg, rows = model.segment_array(), model.joint_array()
    # on the ground: a free base's rows dropped, the fixed-base solve holds the root's
    # proximal point; in flight: every coordinate, the root high above the ground
    planted = rows[nb:].ravel()
    flying = rows.ravel()
    work = np.zeros(body_work_size(n + nb, seg))
    flight = flight_samples(model, target, t)
    torque = np.zeros_like(q)
    for i in range(t.size):
        if flight[i]:
            y = np.concatenate([[0.0, FLIGHT_HEIGHT], q[:, i], [0.0, 0.0], qd[:, i]])
            actuated = np.arange(nb + 1, nb + n)
            free, columns = _torque_columns(y, n + nb, actuated, seg, flying, work)
            torque[1:, i] = np.linalg.solve(columns[actuated], qdd[1:, i] - free[actuated])
        else:
            y = np.concatenate([q[:, i], qd[:, i]])
            free, columns = _torque_columns(y, n, np.arange(n), seg, planted, work)
            torque[:, i] = np.linalg.solve(columns, qdd[:, i] - free)
    return t, q, qd, torque


#: Most passes of `quasi_static_activations` on a model with two-joint units (each solves
#: every joint with the torque the two-joint units gave their second joints in the pass
#: before), and the change of that torque, N·m, at which they stop. The squat jump with
#: two-joint units settles in two: its start's score 32.65 after one, 30.38 after 2, 4 and 8.
TWO_JOINT_PASSES, TWO_JOINT_SETTLED = 8, 1e-3


def quasi_static_activations(model, q, qd, torque, rest_levels):
    """Activation (units × samples, 0–1) of every unit that produces the joint torques
    quasi-statically (module docstring). ``rest_levels[u]`` is None for units starting from
    equilibrium.

    A unit is solved at its own joint, with its unit angle ψ and speed ψ̇ (docs/model.md §7;
    the joint's for a one-joint unit). A two-joint unit's torque r·T at its second joint is
    taken off what that joint's units must carry, from the levels of the previous pass
    (`TWO_JOINT_PASSES`; one pass on a model without two-joint units)."""
    params = [u.parameters.to_array() for u in model.units]
    names = [j.name for j in model.joints]
    angle, speed = model.unit_angles(q.T).T, model.unit_angles(qd.T).T  # units × samples
    spanning = [(u, model.joint_index(unit.second_joint), unit.second_arm)
                for u, unit in enumerate(model.units) if unit.second_joint is not None]
    given = np.zeros_like(torque)  # torque the two-joint units give their second joints
    levels = np.zeros((model.n_units, q.shape[1]))

    def capacity(u, unit, i, torque_guess):
        """Torque of unit u at activation 1 and its SE stretch for ``torque_guess``."""
        p = params[u]
        d = unit.direction
        return ce_torque_velocity(d * speed[u, i], p, 0) * torque_angle(
            angle[u, i] + d * torque_guess / unit.parameters.se_stiffness, p, 0)

    for _ in range(TWO_JOINT_PASSES if spanning else 1):
        levels[:] = 0.0
        for k, joint in enumerate(names):
            members = [(u, unit) for u, unit in enumerate(model.units) if unit.joint == joint]
            for i in range(q.shape[1]):
                base = given[k, i]
                for u, unit in members:
                    rest = rest_levels[u]
                    if rest is not None:
                        cap = capacity(u, unit, i, rest * capacity(u, unit, i, 0.0))
                        base += unit.direction * rest * cap
                        levels[u, i] = rest
                remaining = torque[k, i] - base
                sign = 1 if remaining >= 0 else -1
                agonists = [(u, unit) for u, unit in members if unit.direction == sign
                            and rest_levels[u] is None] or \
                    [(u, unit) for u, unit in members if unit.direction == sign]
                if not agonists:
                    continue
                # agonists with a rest level give it up: their rest torque joins what they
                # carry
                need = abs(remaining) + sum(rest_levels[u] * capacity(u, unit, i, 0.0)
                                            for u, unit in agonists
                                            if rest_levels[u] is not None)
                caps = [capacity(u, unit, i, need / len(agonists)) for u, unit in agonists]
                level = agonist_level([lambda a, c=c: a * c for c in caps], need) \
                    if need > 0 and sum(caps) > 0 else (0.0 if need <= 0 else 1.0)
                for u, _unit in agonists:
                    levels[u, i] = level
        np.clip(levels, 0.0, 1.0, out=levels)
        before, given = given, np.zeros_like(torque)
        for u, k2, arm in spanning:
            unit = model.units[u]
            for i in range(q.shape[1]):
                tension = levels[u, i] * capacity(u, unit, i,
                                                  levels[u, i] * capacity(u, unit, i, 0.0))
                given[k2, i] += arm * tension
        if np.max(np.abs(given - before)) <= TWO_JOINT_SETTLED:
            break
    return levels


def fit_ramps(t, level, initial_level: float, lower, upper) -> np.ndarray:
    """The 9 ramp parameters (delay, duration, level × 3) whose profile from
    ``initial_level`` best matches ``level`` at times ``t`` (least squares, in bounds)."""
    packed = np.empty(PROFILE_SIZE)

    def residual(x):
        pack_profile(x, 0, initial_level, packed)
        return np.array([activation(ti, packed, 0) for ti in t]) - level

    best = None
    span = t[-1] - t[0]
    for split in (0.2, 0.35, 0.5):
        # ramps centred at split·span, 0.5·span and (1 − split)·span, levels sampled there
        centres = np.array([split, 0.5, 1.0 - split]) * span
        guess = []
        end = 0.0
        for c in centres:
            duration = 0.3 * span / RAMPS_PER_UNIT
            start = max(c - duration / 2, end)
            guess += [start - end, duration, float(np.interp(c + duration / 2, t, level))]
            end = start + duration
        x0 = np.clip(guess, lower, upper)
        fit = least_squares(residual, x0, bounds=(lower, upper), x_scale="jac")
        if best is None or fit.cost < best.cost:
            best = fit
    return best.x


def initial_guess(problem) -> np.ndarray:
    """A parameter vector from inverse dynamics (module docstring), inside the bounds; the
    searched model fields (if any) at the model's values."""
    model, space = problem.model, problem.space
    t, q, qd, torque = required_torques(model, problem.target)
    levels = quasi_static_activations(model, q, qd, torque, problem.initial_levels)
    lower, upper = np.array(space.lower), np.array(space.upper)
    parts = []
    for u in range(model.n_units):
        window = slice(u * PER_UNIT, (u + 1) * PER_UNIT)
        parts.append(fit_ramps(t, levels[u], problem.levels[u], lower[window], upper[window]))
    x = np.concatenate([*parts, space.field_values(model)])
    return space.clip(space.full(x[space.free], x))

