"""Right-hand sides of the two parts of a chain model, compiled (docs/model.md §1–§2).

State y = (q, q̇, every unit's own states; `torquesim.model.state`). Body part: (q, q̇) with
input the joint muscle torques; muscle part: the units' states (θ_cc, and a with activation
dynamics) with input the joint angles q. Unit u acts on joint j with direction d
(+1 flexor, −1 extensor) and, a two-joint unit, on the adjacent joint j2 with the signed
moment arm r (its row of the moment-arm matrix: d at j, r at j2; `model.unit_row`):

    unit angle ψ_u = q_j + d·r·q_j2,      SE stretch s_u = d·(θ_cc,u − ψ_u),
    unit torque T_u = k·max(s_u, 0),       joint torques τ_j += d·T_u, τ_j2 += r·T_u,
    dθ_cc,u/dt = d·ω_cc,u

(r = 0 for a one-joint unit: ψ = q_j and nothing is added at a second joint, so its
arithmetic is the one-joint formulation's, bit for bit).

with ω_cc,u the CE velocity solving the CE equation (positive = concentric). ``guess`` (rad/s)
is a solver's prediction of a CE velocity: it only seeds the root finder (NaN: no guess).

The per-unit functions are loop-free and inlined into the solvers' step loops, which loop over
units and joints themselves: Numba cannot prune the reference counting of array arguments
around a compiled function that contains loops, which cost more than the whole model when the
loops sat in helpers (measured: 2.6x slower elbow steps). The arrays are flat, as the solvers
pass them: ``units`` holds the units' rows of `UNIT_ROW_SIZE` one
after another, ``profiles`` the activation rows of ``width``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.extending import overload

from ..model.activation import activation, activation_rate, activation_time_constant
from ..model.body import (
    body_switches,
    body_work_size,
    single_segment_acceleration,
    switched_body,
    tree_accelerations,
)
from ..model.state import has_activation_state, unit_state
from ..model.torque_generator import unit_ce_velocity_and_time_constant, unit_torque
from ..model.unit_row import (
    UNIT_ACTIVATION_TIME,
    UNIT_DEACTIVATION_TIME,
    UNIT_DIRECTION,
    UNIT_JOINT,
    UNIT_ROW_SIZE,
    UNIT_SECOND_ARM,
    UNIT_SECOND_JOINT,
)
from .run_stats import STATS_SIZE, record_stiffness


@njit(cache=True, error_model="numpy", inline="always")
def unit_joints(units, u):
    """(j, j2): the indices of the coordinates unit u acts on (j2 = j: one joint)."""
    o = u * UNIT_ROW_SIZE
    return int(units[o + UNIT_JOINT]), int(units[o + UNIT_SECOND_JOINT])


@njit(cache=True, error_model="numpy", inline="always")
def unit_angle(q_joint, q_second, units, u):
    """Unit u's angle ψ = q_j + d·r·q_j2, rad, from the angles of its joint and of its second
    joint (the first again for a one-joint unit: r = 0, ψ = q_j). The branch on r = 0 keeps
    one-joint units on their former arithmetic (measured: the elbow's step 1.01× with it,
    1.06× computing d·r·q_j2 = 0 always)."""
    o = u * UNIT_ROW_SIZE
    r = units[o + UNIT_SECOND_ARM]
    if r == 0.0:
        return q_joint
    return q_joint + units[o + UNIT_DIRECTION] * r * q_second


@njit(cache=True, error_model="numpy", inline="always")
def unit_angle_at(q, units, u):
    """`unit_angle` read from the coordinates ``q`` (a state or any array indexed as y)."""
    j, j2 = unit_joints(units, u)
    return unit_angle(q[j], q[j2], units, u)


@njit(cache=True, error_model="numpy", inline="always")
def unit_stretch(psi, theta_cc, units, u):
    """SE stretch of unit u at CE angle ``theta_cc`` and unit angle ``psi`` (`unit_angle`; the
    joint angle for a one-joint unit): d·(θ_cc − ψ), rad."""
    return units[u * UNIT_ROW_SIZE + UNIT_DIRECTION] * (theta_cc - psi)


@njit(cache=True, error_model="numpy", inline="always")
def add_unit_torque(torque, psi, theta_cc, units, u):
    """Add unit u's torque T = k·max(s, 0) to the joint torques (N·m, flexion positive) by its
    row of the moment-arm matrix: d·T at its joint, r·T at its second joint (none for a
    one-joint unit, r = 0)."""
    o = u * UNIT_ROW_SIZE
    j, j2 = unit_joints(units, u)
    tension = unit_torque(unit_stretch(psi, theta_cc, units, u), units, o)
    torque[j] += units[o + UNIT_DIRECTION] * tension
    r = units[o + UNIT_SECOND_ARM]
    if r != 0.0:
        torque[j2] += r * tension


@njit(cache=True, error_model="numpy", inline="always")
def unit_excitation(t, profiles, width, u):
    """e_u(t), the value of unit u's packed profile row at time t (s): its activation when it
    has no activation dynamics, its excitation (the input of its dynamics) when it has."""
    return activation(t, profiles, u * width)


@njit(cache=True, error_model="numpy", inline="always")
def unit_rates(psi, y, i, excitation, guess, units, u, dynamics):
    """The rates of unit u whose states start at y[i] (θ_cc; then a, with activation
    dynamics), at unit angle ``psi`` (`unit_angle`) and profile value ``excitation``:
    (dθ_cc/dt, da/dt, ω_cc, τ) in rad/s, 1/s, rad/s, s.

    This is the one place a unit's activation is read: its profile value e(t) without
    activation dynamics, its state y[i + 1] with (da/dt is then `activation_rate`, else 0 and
    not a state). ``dynamics``: True when some unit of the model has activation dynamics,
    None when none has (a compile-time constant: the activation-state code is then not
    compiled, `check_unit_kinds`). τ is the unit's shortest time constant (the stability
    guard's input): its CE's, from the root finder's last slope, or with dynamics
    `activation_time_constant` if that is shorter."""
    o = u * UNIT_ROW_SIZE
    theta_cc = y[i]
    level = excitation if dynamics is None else unit_level(excitation, y, i, units, u)
    w, tau = unit_ce_velocity_and_time_constant(unit_stretch(psi, theta_cc, units, u),
                                                theta_cc, level, units, guess, o)
    level_rate = 0.0
    if dynamics is not None:
        if has_activation_state(units, u):
            t_act, t_deact = units[o + UNIT_ACTIVATION_TIME], units[o + UNIT_DEACTIVATION_TIME]
            level_rate = activation_rate(excitation, level, t_act, t_deact)
            tau = min(tau, activation_time_constant(excitation, level, t_act, t_deact))
    return units[o + UNIT_DIRECTION] * w, level_rate, w, tau


@njit(cache=True, error_model="numpy")
def check_unit_kinds(units, n_units, dynamics):
    """Raise unless ``dynamics`` (True or None, see `unit_rates`) matches the flat packed
    ``units``: None with a unit that has activation dynamics would ignore its state."""
    if dynamics is None:
        for u in range(n_units):
            if has_activation_state(units, u):
                raise ValueError("a unit has activation dynamics: the loop needs dynamics=True")


@njit(cache=True, error_model="numpy", inline="always")
def unit_level(excitation, y, i, units, u):
    """The activation unit u's CE sees: its state y[i + 1] with activation dynamics, else
    its profile value (`unit_rates` and the outputs read it here)."""
    return y[i + 1] if has_activation_state(units, u) else excitation


@njit(cache=True, error_model="numpy")
def flat_arrays(seg, joints, units, profiles):
    """(n coordinates, n units, profile row width, flat units, flat joints, flat profiles) of
    the 2-D packed arrays of `PackedChain`, as the loops read them (the joint array has a row
    per coordinate)."""
    return (joints.shape[0], units.shape[0], profiles.shape[1], units.ravel(), joints.ravel(),
            profiles.ravel())


@njit(cache=True, error_model="numpy")
def joint_muscle_torques(q, x, units, n_units, out, n_joints):
    """τ = Σ_u (row u of the moment-arm matrix)·T_u, N·m, into out[:n_joints], at joint angles
    q and unit states from the state vector x (θ_cc,u = x[unit_state(n, units, u)]).
    (Outside the step loops; the loops add `add_unit_torque` themselves.)"""
    for j in range(n_joints):
        out[j] = 0.0
    for u in range(n_units):
        add_unit_torque(out, unit_angle_at(q, units, u), x[unit_state(n_joints, units, u)],
                        units, u)


def _tree_solve(y, n, torque, seg, joints, work, free_base, tree):
    """`tree_accelerations` for the body the switches name; see `_tree_solve_for_body`."""


@overload(_tree_solve, inline="always")
def _tree_solve_for_body(y, n, torque, seg, joints, work, free_base, tree):
    """Choose the solve by the switches' types while compiling, so that a caller types and
    compiles one copy of it (fixed or free base, serial chain or tree), not four behind
    constant branches (the same run time, a quarter of the compile time)."""
    free, serial = switched_body(free_base, tree)
    nb = 2 if free else 0

    def solve(y, n, torque, seg, joints, work, free_base, tree):
        tree_accelerations(y, n, nb, serial, torque, seg, joints, work)
    return solve


@njit(cache=True, error_model="numpy", inline="always")
def general_accelerations(y, n, torque, seg, joints, work, dy, row, free_base, tree):
    """q̈ of a body of two or more coordinates into dy[row, n:2n] (the general mass-matrix
    solve, `tree_accelerations`, inlined); ``free_base`` and ``tree`` True or None
    (compile-time switches, so a loop holds the solve of its own body only: free base or
    fixed, tree or serial chain)."""
    _tree_solve(y, n, torque, seg, joints, work, free_base, tree)
    for k in range(n):
        dy[row, n + k] = work[n * n + k]


@njit(cache=True, error_model="numpy", inline="always")
def predict(preceding, preceding_before, this_before):
    """Guess for a stage's CE velocity, rad/s: the value of the same stage one step earlier,
    shifted by the change of the preceding stage (stage 4 precedes stage 1) over that step.
    Within 1e-6 rad/s of the root on the default curl at 0.1 ms, so the root finder takes one
    step. The preceding stage's value while there is no history yet (NaN: no guess)."""
    guess = this_before + (preceding - preceding_before)
    return guess if math.isfinite(guess) else preceding


@njit(cache=True, error_model="numpy", inline="always")
def system_rates(y, excitations, at, seen, seen4_before, dy, row, omegas, torque, work, stats,
                 t, guard_step, n, nu, seg, joints, units, general_body, dynamics, free_base,
                 tree):
    """The whole right-hand side dy/dt of y = (q, q̇, the units' states) into dy[row]
    (docs/model.md §1–§2): the joint torques τ = Σ_u (row u of the moment-arm matrix)·T_u
    into ``torque``, each unit's rates (`unit_rates` at its profile value
    excitations[at, u], its CE velocity into omegas[row, u]), then dq/dt = q̇ and q̈ from
    the body's equations (the general solve leaves its work, contact forces included, in
    ``work``). At stage 0 each unit's ratio guard_step/τ to its shortest time constant
    updates the stability guard in ``stats`` at time t (`record_stiffness`; guard_step 0:
    no update).

    ``row`` is the RK4 stage (0–3): the CE root finder of a unit is seeded by `predict` from
    the same stage's velocity one step earlier (seen[row, u]), the preceding stage's now
    (omegas[row − 1, u]; stage 1 is preceded by stage 4 of the previous step, seen[3, u]) and
    a step earlier (seen[row − 1, u]; seen4_before[u]). NaN histories give the preceding
    stage's value, all NaN no seed.

    The one assembly of the right-hand side: the fixed-step loops call it at every stage of
    the whole state, SciPy's solvers through `compiled_derivative`. The switches (True or
    None) as in `rk4_monolithic`. Inlined. Its cost against the same code written out in the
    monolithic stage loop (d7711db), per step, median of 21 paired interleaved runs: elbow
    1.01×, squat jump 0.99×, a 6-segment chain of 12 units 1.04–1.07× (Numba's reference
    counting of the arrays passed in, it seems). A whole RK4 step as one inlined function
    cost more (elbow 1.12–1.16×, 6-segment chain 1.10–1.22×): the loops keep their stage loop
    written out."""
    for j in range(n):
        torque[j] = 0.0
    for u in range(nu):
        i = unit_state(n, units, u)
        psi = unit_angle_at(y, units, u)
        add_unit_torque(torque, psi, y[i], units, u)
        if row == 0:
            guess = predict(seen[3, u], seen4_before[u], seen[0, u])
        else:
            guess = predict(omegas[row - 1, u], seen[row - 1, u], seen[row, u])
        dy[row, i], level_rate, omegas[row, u], tau = unit_rates(
            psi, y, i, excitations[at, u], guess, units, u, dynamics)
        if row == 0:
            record_stiffness(stats, t, guard_step / tau, u)
        if dynamics is not None:
            if has_activation_state(units, u):
                dy[row, i + 1] = level_rate
    for j in range(n):
        dy[row, j] = y[n + j]
    if general_body is not None:
        general_accelerations(y, n, torque, seg, joints, work, dy, row, free_base, tree)
    else:
        dy[row, 1] = single_segment_acceleration(y[0], torque[0], seg, joints)


def chain_derivative(t, y, seg, joints, units, profiles):
    """dy/dt at time t (s) as a new array, for SciPy's solvers; takes the 2-D packed arrays of
    `PackedChain` (`compiled_derivative` with the body's switches)."""
    return compiled_derivative(t, y, seg, joints, units, profiles,
                               *body_switches(seg, joints.shape[0]))


@njit(cache=True, error_model="numpy")
def compiled_derivative(t, y, seg, joints, units, profiles, general_body, free_base, tree):
    """`chain_derivative` with the body's switches (`body_switches`), so that only that
    body's solve is compiled: `system_rates` at time t, with no root-finder seed."""
    n, nu, width, units, joints, profiles = flat_arrays(seg, joints, units, profiles)
    dy = np.empty((1, y.shape[0]))
    excitations = np.empty((1, nu))
    seen = np.empty((4, nu))
    for u in range(nu):
        excitations[0, u] = unit_excitation(t, profiles, width, u)
        seen[3, u] = np.nan
    system_rates(y, excitations, 0, seen, seen[3], dy, 0, np.empty((1, nu)), np.empty(n),
                 np.empty(body_work_size(n, seg)), np.zeros(STATS_SIZE), t, 0.0, n, nu, seg,
                 joints, units, general_body, True, free_base, tree)
    return dy[0]
