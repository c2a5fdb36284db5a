"""Right-hand sides of the two parts of a chain model, compiled (docs/model.md §1–§2).

State y = (q, q̇, θ_cc of every unit). Body part: (q, q̇) with input the joint muscle torques;
muscle part: θ_cc with input the joint angles q. Unit u acts on joint j with direction d
(+1 flexor, −1 extensor):

    SE stretch s_u = d·(θ_cc,u − q_j),   unit torque T_u = k·max(s_u, 0),
    joint torque τ_j = Σ_u d·T_u,         dθ_cc,u/dt = d·ω_cc,u

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

import numpy as np
from numba import njit

from ..model.activation import activation
from ..model.body import body_work_size, joint_accelerations, single_segment_acceleration
from ..model.chain import UNIT_DIRECTION, UNIT_JOINT, UNIT_ROW_SIZE
from ..model.state import unit_state, unit_states_start
from ..model.torque_generator import unit_ce_velocity_and_time_constant, unit_torque


@njit(cache=True, error_model="numpy", inline="always")
def unit_joint(units, u):
    """Index of the joint unit u acts on."""
    return int(units[u * UNIT_ROW_SIZE + UNIT_JOINT])


@njit(cache=True, error_model="numpy", inline="always")
def unit_stretch(q_joint, theta_cc, units, u):
    """SE stretch of unit u at CE angle ``theta_cc`` and joint angle ``q_joint`` (of the
    joint it acts on): d·(θ_cc − q_j), rad."""
    return units[u * UNIT_ROW_SIZE + UNIT_DIRECTION] * (theta_cc - q_joint)


@njit(cache=True, error_model="numpy", inline="always")
def unit_joint_torque(q_joint, theta_cc, units, u):
    """Unit u's torque at its joint, d·k·max(s, 0), N·m (flexion positive)."""
    o = u * UNIT_ROW_SIZE
    return units[o + UNIT_DIRECTION] * unit_torque(unit_stretch(q_joint, theta_cc, units, u),
                                                   units, o)


@njit(cache=True, error_model="numpy", inline="always")
def unit_rate(q_joint, theta_cc, level, guess, units, u):
    """(dθ_cc/dt, ω_cc, τ) of unit u at joint angle ``q_joint``, CE angle ``theta_cc`` and
    activation ``level``: its CE angle rate (rad/s), CE velocity (rad/s) and time constant
    (s, the stability guard's input, from the root finder's last slope)."""
    o = u * UNIT_ROW_SIZE
    w, tau = unit_ce_velocity_and_time_constant(unit_stretch(q_joint, theta_cc, units, u),
                                                theta_cc, level, units, guess, o)
    return units[o + UNIT_DIRECTION] * w, w, tau


@njit(cache=True, error_model="numpy", inline="always")
def unit_activation(t, profiles, width, u):
    """a_u(t) of unit u's packed profile row."""
    return activation(t, profiles, u * width)


@njit(cache=True, error_model="numpy")
def flat_arrays(seg, joints, units, profiles):
    """(n joints, n units, profile row width, flat units, flat joints, flat profiles) of the
    2-D packed arrays of `PackedChain`, as the loops read them."""
    return (seg.shape[0], units.shape[0], profiles.shape[1], units.ravel(), joints.ravel(),
            profiles.ravel())


@njit(cache=True, error_model="numpy")
def joint_muscle_torques(q, x, x_off, units, n_units, out, n_joints):
    """τ_j = Σ_{units on j} d·k·max(s, 0), N·m, into out[:n_joints]; θ_cc,u = x[x_off + u].
    (Outside the step loops; the loops sum `unit_joint_torque` themselves.)"""
    for j in range(n_joints):
        out[j] = 0.0
    for u in range(n_units):
        j = unit_joint(units, u)
        out[j] += unit_joint_torque(q[j], x[x_off + u], units, u)


@njit(cache=True, error_model="numpy")
def chain_derivative(t, y, seg, joints, units, profiles):
    """dy/dt at time t (s) as a new array, for SciPy's solvers; takes the 2-D packed arrays of
    `PackedChain`."""
    n, nu, width, units, joints, profiles = flat_arrays(seg, joints, units, profiles)
    dy = np.empty(y.shape[0])
    torque = np.empty(n)
    joint_muscle_torques(y, y, unit_states_start(n), units, nu, torque, n)
    for k in range(n):
        dy[k] = y[n + k]
    if n == 1:
        dy[1] = single_segment_acceleration(y[0], torque[0], seg, joints)
    else:
        work = np.empty(body_work_size(n))
        joint_accelerations(y, n, torque, seg, joints, work)
        for k in range(n):  # a loop: a slice assignment compiles a shape check (1.6 s cold)
            dy[n + k] = work[n * n + k]
    for u in range(nu):
        dy[unit_state(n, u)] = unit_rate(y[unit_joint(units, u)], y[unit_state(n, u)],
                                  unit_activation(t, profiles, width, u), np.nan, units, u)[0]
    return dy
