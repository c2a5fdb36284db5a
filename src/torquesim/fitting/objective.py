"""The fit's objective, compiled: simulate candidates in parallel and return their residuals.

The residual vector r of a candidate (all angles in degrees, times in s) has, for every scored
joint j with weight w_j (weights sum to 1) and target sample k = 1…K,

    angle      √(w_j/K) · (q_j(t_k) − q*_j(t_k))
    velocity   w_ω · √(w_j/K) · (q̇_j(t_k) − q̇*_j(t_k)) · 1 s                  (w_ω > 0)
    end        w_end · √w_j · (q_j(T) − q*_j(T)),  w_end · √w_j · (q̇_j(T) − q̇*_j(T)) · 1 s
    effort     √(w_a/K) · max(a_u(t_k) − rest_u, 0)  for every unit u         (w_a > 0)
    channel    s_c/√K · (y_c(t_k) − y*_c(t_k))  for every target channel c of a body on the
               ground: total GRF in N with s_c = w_grf/(m·g), centre of mass in m with
               s_c = w_com (`torquesim.model.body.ground_outputs`, linear between steps)

so that ‖r‖² = Σ_j w_j·MSE_j + w_ω²·(velocity MSE) + w_end²·(end errors²) + w_a·Σ_u mean_k
(a_u − rest_u)₊² + Σ_c s_c²·MSE_c. With every weight 0 and one joint, ‖r‖ is the RMS angle
error. The score is ‖r‖ (degrees). A run that goes non-finite, diverges, exceeds the RK4
stability limit anywhere in a ground contact (explicit in every technique) or, with explicit
muscle solvers, in a unit fails: its residuals are all FAILED_SCORE/√R, score
`FAILED_SCORE`, so it can never win.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..model.body import body_work_size, ground_outputs
from ..solvers import fixed_step as fs
from ..solvers.rates import unit_excitation
from .parameters import PER_UNIT, RAMPS_PER_UNIT

#: Score of a candidate whose simulation failed or broke the stability guard, deg.
FAILED_SCORE = 1.0e4
PROFILE_SIZE = 2 + 3 * RAMPS_PER_UNIT
DEG = 180.0 / math.pi


@njit(cache=True, error_model="numpy")
def pack_profile(x, offset, initial_level, out):
    """Write the packed activation profile [a_0, n, (t_on, r, level) × n] of the ramps
    x[offset : offset + 9] (delay, duration, level each) into ``out``."""
    out[0] = initial_level
    out[1] = RAMPS_PER_UNIT
    t = 0.0
    for i in range(RAMPS_PER_UNIT):
        start = t + x[offset + 3 * i]
        out[2 + 3 * i] = start
        out[3 + 3 * i] = x[offset + 3 * i + 1]
        out[4 + 3 * i] = x[offset + 3 * i + 2]
        t = start + x[offset + 3 * i + 1]


#: What became of a candidate's run (`run_status`), and why a run that failed is unusable.
RUN_OK, RUN_NON_FINITE, RUN_DIVERGED, RUN_UNSTABLE_MUSCLE, RUN_UNSTABLE_CONTACT = range(5)
RUN_REASONS = ("", "non-finite state", "diverged", "step beyond explicit RK4's stability "
               "limit in a unit", "step beyond RK4's stability limit in a ground contact")


@njit(cache=True, error_model="numpy")
def run_status(stats, explicit_muscles):
    """RUN_OK, or the first reason the run with these loop ``stats`` is unusable:
    non-finite, diverged, a unit beyond the RK4 stability limit (only when the muscles are
    explicit), a ground contact beyond it (explicit in every technique)."""
    if stats[fs.STATUS] == fs.NON_FINITE:
        return RUN_NON_FINITE
    if stats[fs.STATUS] != fs.OK:
        return RUN_DIVERGED
    if explicit_muscles and stats[fs.WORST_RATIO] > fs.RK4_STABILITY_LIMIT:
        return RUN_UNSTABLE_MUSCLE
    if stats[fs.CONTACT_RATIO] > fs.RK4_STABILITY_LIMIT:
        return RUN_UNSTABLE_CONTACT
    return RUN_OK


@njit(cache=True, error_model="numpy")
def sample_joint(states, step, times, joint, n, theta_out, omega_out):
    """Joint ``joint``'s q and q̇ at ``times`` (s from the start) from fixed-step states
    (columns q then q̇ of n joints): cubic Hermite in q (q̇ as its derivative), linear in q̇."""
    last = states.shape[0] - 1
    for k in range(times.shape[0]):
        s = times[k] / step
        i = min(int(s), last - 1)
        u = s - i
        th0, th1 = states[i, joint], states[i + 1, joint]
        om0, om1 = states[i, n + joint], states[i + 1, n + joint]
        u2 = u * u
        u3 = u2 * u
        theta_out[k] = ((2 * u3 - 3 * u2 + 1) * th0 + (u3 - 2 * u2 + u) * step * om0
                        + (-2 * u3 + 3 * u2) * th1 + (u3 - u2) * step * om1)
        omega_out[k] = (1.0 - u) * om0 + u * om1


@njit(cache=True, error_model="numpy")
def simulate_candidate(x, loop, coupling, y0, step, n_steps, seg, joints, units, levels,
                       explicit_muscles, times, scored, theta_out, omega_out, profiles,
                       channels, channel_out):
    """Simulate the ramp vector ``x`` (9 per unit) on the packed chain with the step loop the
    switches ``loop`` choose (a tuple, `fixed_step.step_loop_switches`), unit u starting at
    ``levels[u]``; fill q, q̇ of the ``scored`` coordinates at ``times`` (rows of
    ``theta_out``, ``omega_out``), the ground outputs ``channels`` (indices into
    `GROUND_OUTPUTS`; rows of ``channel_out``) and the packed ``profiles``. True if the run
    is usable (finite, not diverged, contacts within the RK4 stability limit, and units too
    when explicit).

    The parameter arrays are copied first: candidates run in parallel threads, and the step
    loops' reference counting on arrays shared between threads would contend (measured: the
    population scored 2.3x slower).
    """
    seg, joints, units, y0, coupling = seg.copy(), joints.copy(), units.copy(), y0.copy(), \
        coupling.copy()
    n = joints.shape[0]  # coordinates (the joint array has a row per coordinate)
    for u in range(levels.shape[0]):
        pack_profile(x, u * PER_UNIT, levels[u], profiles[u])
    states = np.empty((n_steps + 1, y0.shape[0]))
    stats = np.zeros(fs.STATS_SIZE)
    fs.run_step_loop(*loop, y0, step, n_steps, seg, joints, units, profiles, coupling, states,
                     stats)
    if run_status(stats, explicit_muscles) != RUN_OK:
        return False
    for r in range(scored.shape[0]):
        sample_joint(states, step, times, scored[r], n, theta_out[r], omega_out[r])
    if channels.shape[0] > 0:
        sample_ground_outputs(states, step, times, n, seg, joints, channels, channel_out,
                              loop[fs.SWITCH_FREE_BASE], loop[fs.SWITCH_TREE])
    return True


@njit(cache=True, error_model="numpy")
def sample_ground_outputs(states, step, times, n, seg, joints, channels, out, free_base, tree):
    """The ground outputs ``channels`` (`GROUND_OUTPUTS` indices) at ``times`` (s from the
    start) from fixed-step states, linear between the values at the steps around each time
    (``joints``: the 2-D joint rows). ``free_base`` and ``tree``: the body's switches
    (`body_switches`); with free_base None (no ground) nothing is compiled or done."""
    if free_base is not None:
        joints = joints.ravel()
        work = np.zeros(body_work_size(n, seg))
        torque = np.zeros(n)
        before = np.empty(4)
        after = np.empty(4)
        last = states.shape[0] - 1
        for k in range(times.shape[0]):
            s = times[k] / step
            i = min(int(s), last - 1)
            u = s - i
            ground_outputs(states[i], n, seg, joints, torque, work, before, tree)
            ground_outputs(states[i + 1], n, seg, joints, torque, work, after, tree)
            for r in range(channels.shape[0]):
                c = channels[r]
                out[r, k] = (1.0 - u) * before[c] + u * after[c]


@njit(cache=True, error_model="numpy")
def fill_residual(theta, omega, target_theta, target_omega, weights, weight_velocity,
                  weight_end, weight_effort, profiles, rests, times, channel_values,
                  target_channels, channel_scales, out):
    """The residual vector of one simulated candidate (module docstring) into ``out``."""
    n_rows, n_samples = theta.shape
    i = 0
    scale = 1.0 / math.sqrt(n_samples)
    for r in range(n_rows):
        w = math.sqrt(weights[r]) * DEG
        for k in range(n_samples):
            out[i] = w * scale * (theta[r, k] - target_theta[r, k])
            i += 1
        if weight_velocity > 0.0:
            for k in range(n_samples):
                out[i] = weight_velocity * w * scale * (omega[r, k] - target_omega[r, k])
                i += 1
        if weight_end > 0.0:
            last = n_samples - 1
            out[i] = weight_end * w * (theta[r, last] - target_theta[r, last])
            out[i + 1] = weight_end * w * (omega[r, last] - target_omega[r, last])
            i += 2
    if weight_effort > 0.0:
        w = math.sqrt(weight_effort) * scale
        flat = profiles.ravel()
        for u in range(rests.shape[0]):
            for k in range(n_samples):
                out[i] = w * max(unit_excitation(times[k], flat, PROFILE_SIZE, u) - rests[u],
                                 0.0)
                i += 1
    for r in range(channel_values.shape[0]):
        w = channel_scales[r] * scale
        for k in range(n_samples):
            out[i] = w * (channel_values[r, k] - target_channels[r, k])
            i += 1


def residual_size(n_rows: int, n_samples: int, n_units: int, weight_velocity: float,
                  weight_end: float, weight_effort: float, n_channels: int = 0) -> int:
    """Length of the residual vector (module docstring)."""
    per_row = n_samples * (1 + (weight_velocity > 0)) + 2 * (weight_end > 0)
    return n_rows * per_row + (n_units * n_samples if weight_effort > 0 else 0) \
        + n_channels * n_samples


@njit(cache=True, parallel=True, error_model="numpy")
def residual_population(population, loop, coupling, y0, step, n_steps, seg, joints, units,
                        levels, rests, explicit_muscles, times, scored, target_theta,
                        target_omega, weights, weight_velocity, weight_end, weight_effort,
                        channels, target_channels, channel_scales, residuals, failed):
    """Residuals (rows of ``residuals``) and failure flags of every row of ``population``
    (m × 9U), simulated in parallel threads with the step loop chosen by the switches ``loop``
    (`fixed_step.step_loop_switches`): only that loop is compiled into this function."""
    n_rows, n_samples = target_theta.shape
    failed_value = FAILED_SCORE / math.sqrt(residuals.shape[1])
    for j in prange(population.shape[0]):
        theta = np.empty((n_rows, n_samples))
        omega = np.empty((n_rows, n_samples))
        profiles = np.zeros((levels.shape[0], PROFILE_SIZE))
        values = np.empty((channels.shape[0], n_samples))
        ok = simulate_candidate(population[j], loop, coupling, y0, step, n_steps, seg, joints,
                                units, levels, explicit_muscles, times, scored, theta, omega,
                                profiles, channels, values)
        if ok:
            fill_residual(theta, omega, target_theta, target_omega, weights, weight_velocity,
                          weight_end, weight_effort, profiles, rests, times, values,
                          target_channels, channel_scales, residuals[j])
            failed[j] = False
        else:
            residuals[j, :] = failed_value
            failed[j] = True
