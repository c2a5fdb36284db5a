"""Right-hand sides of the two parts of a chain model, compiled (docs/model.md §1–§2).

State y = (q, q̇, θ_cc of every unit). Body part: (q, q̇) with input the joint muscle torques;
muscle part: θ_cc with input the joint angles q. Unit u acts on joint j = ``units[u, 18]``
with direction d = ``units[u, 19]`` (+1 flexor, −1 extensor):

    SE stretch s_u = d·(θ_cc,u − q_j),   unit torque T_u = k·max(s_u, 0),
    joint torque τ_j = Σ_u d·T_u,         dθ_cc,u/dt = d·ω_cc,u

with ω_cc,u the CE velocity solving the CE equation (positive = concentric). Each function is
one equation; the solvers combine them. ``guesses`` (rad/s) are a solver's predictions of the
CE velocities: they only seed the root finder (NaN: no guess). Arrays are written in place.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..model.activation import activation
from ..model.body import joint_accelerations
from ..model.chain import UNIT_DIRECTION, UNIT_JOINT
from ..model.torque_generator import unit_ce_velocity_and_time_constant, unit_torque


@njit(cache=True, error_model="numpy", inline="always")
def unit_stretch(q, theta_cc, units, u):
    """SE stretch of unit u, d·(θ_cc,u − q_j), rad."""
    return units[u, UNIT_DIRECTION] * (theta_cc - q[int(units[u, UNIT_JOINT])])


@njit(cache=True, error_model="numpy", inline="always")
def joint_muscle_torques(q, theta_cc, units, out):
    """τ_j = Σ_{units on j} d·k·max(s, 0), N·m (flexion positive), into ``out``."""
    for j in range(out.shape[0]):
        out[j] = 0.0
    for u in range(units.shape[0]):
        d = units[u, UNIT_DIRECTION]
        out[int(units[u, UNIT_JOINT])] += d * unit_torque(unit_stretch(q, theta_cc[u], units, u),
                                                           units[u])


@njit(cache=True, error_model="numpy", inline="always")
def activations_at(t, profiles, out):
    """Every unit's activation a_u(t) (packed profile rows), into ``out``."""
    for u in range(out.shape[0]):
        out[u] = activation(t, profiles[u])


@njit(cache=True, error_model="numpy", inline="always")
def muscle_rates(q, theta_cc, levels, guesses, units, rates, omega_cc, tau):
    """Muscle part: dθ_cc/dt (into ``rates``), the CE velocities ω_cc (rad/s) and each unit's
    time constant τ (s, the stability guard's input, from the root finder's last slope), for
    joint angles ``q`` and activations ``levels``."""
    for u in range(units.shape[0]):
        w, tau[u] = unit_ce_velocity_and_time_constant(
            unit_stretch(q, theta_cc[u], units, u), theta_cc[u], levels[u], units[u],
            guesses[u])
        omega_cc[u] = w
        rates[u] = units[u, UNIT_DIRECTION] * w


@njit(cache=True, error_model="numpy", inline="always")
def body_rates(y, n, torque, seg, jnt, work, dy):
    """Body part: dq/dt = q̇ and dq̇/dt = q̈ for joint muscle torques ``torque`` (into
    dy[:2n]). ``y`` holds q in y[:n] and q̇ in y[n:2n]."""
    for k in range(n):
        dy[k] = y[n + k]
    joint_accelerations(y[:n], y[n:2 * n], torque, seg, jnt, work, dy[n:2 * n])


@njit(cache=True, error_model="numpy", inline="always")
def chain_rates(y, levels, guesses, seg, jnt, units, torque, work, dy, omega_cc, tau):
    """dy/dt of the whole model at activations ``levels``: body and muscles together."""
    n = seg.shape[0]
    theta_cc = y[2 * n:]
    joint_muscle_torques(y[:n], theta_cc, units, torque)
    body_rates(y, n, torque, seg, jnt, work, dy)
    muscle_rates(y[:n], theta_cc, levels, guesses, units, dy[2 * n:], omega_cc, tau)


@njit(cache=True, error_model="numpy")
def chain_derivative(t, y, seg, jnt, units, profiles):
    """dy/dt at time t (s) as a new array: the right-hand side handed to SciPy's solvers."""
    n = seg.shape[0]
    nu = units.shape[0]
    dy = np.empty(y.shape[0])
    levels = np.empty(nu)
    activations_at(t, profiles, levels)
    chain_rates(y, levels, np.full(nu, np.nan), seg, jnt, units, np.empty(n),
                np.empty((n, n + 4)), dy, np.empty(nu), np.empty(nu))
    return dy
