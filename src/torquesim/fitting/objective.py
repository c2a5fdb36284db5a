"""The fit's objective, compiled: simulate each candidate and score it against the target.

Score (degrees) = RMS angle error + w_ω·RMS angular-velocity error (deg/s × 1 s)
+ w_end·(|end angle error| + |end velocity error| × 1 s). A run that goes non-finite,
diverges, or (explicit muscle solvers) exceeds the RK4 stability limit anywhere scores
:data:`FAILED_SCORE`: its motion cannot be trusted, so it must not win.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..solvers import fixed_step as fs
from .parameters import PER_UNIT, RAMPS_PER_UNIT

#: Score of a candidate whose simulation failed or broke the stability guard, deg.
FAILED_SCORE = 1.0e4
MONOLITHIC, PARTITIONED = 0, 1
PROFILE_SIZE = 2 + 3 * RAMPS_PER_UNIT


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


@njit(cache=True, error_model="numpy")
def sample_motion(states, step, times, theta_out, omega_out):
    """θ and ω at ``times`` (s from the start) from fixed-step states: cubic Hermite in θ
    (using ω as its derivative), linear in ω."""
    last = states.shape[0] - 1
    for k in range(times.shape[0]):
        s = times[k] / step
        i = min(int(s), last - 1)
        u = s - i
        th0, th1 = states[i, 0], states[i + 1, 0]
        om0, om1 = states[i, 1], states[i + 1, 1]
        u2 = u * u
        u3 = u2 * u
        theta_out[k] = ((2 * u3 - 3 * u2 + 1) * th0 + (u3 - 2 * u2 + u) * step * om0
                        + (-2 * u3 + 3 * u2) * th1 + (u3 - u2) * step * om1)
        omega_out[k] = (1.0 - u) * om0 + u * om1


@njit(cache=True, error_model="numpy")
def score_motion(theta, omega, target_theta, target_omega, weight_velocity, weight_end):
    """Score in degrees (module docstring) and the max angle error, deg."""
    n = theta.shape[0]
    sq, sq_w, worst = 0.0, 0.0, 0.0
    for k in range(n):
        e = theta[k] - target_theta[k]
        sq += e * e
        worst = max(worst, abs(e))
        ew = omega[k] - target_omega[k]
        sq_w += ew * ew
    deg = 180.0 / math.pi
    score = deg * math.sqrt(sq / n)
    if weight_velocity > 0.0:
        score += weight_velocity * deg * math.sqrt(sq_w / n)
    if weight_end > 0.0:
        score += weight_end * deg * (abs(theta[n - 1] - target_theta[n - 1])
                                     + abs(omega[n - 1] - target_omega[n - 1]))
    return score, deg * worst


@njit(cache=True, error_model="numpy")
def simulate_candidate(x, method, coupling, y0, step, n_steps, seg, joints, units, level_f,
                       level_e, explicit_muscles, times, theta_out, omega_out):
    """Simulate the 18-vector ``x`` on the elbow chain (packed ``seg``, ``joints``, ``units``:
    flexor then extensor); fill θ, ω at ``times``. Returns True if the run is usable (finite,
    not diverged, within the RK4 stability limit when explicit).

    The parameter arrays are copied first: candidates run in parallel threads, and the step
    loops' reference counting on arrays shared between threads would contend (measured: the
    population scored 2.3x slower).
    """
    seg, joints, units, y0, coupling = seg.copy(), joints.copy(), units.copy(), y0.copy(), \
        coupling.copy()
    profiles = np.empty((2, PROFILE_SIZE))
    pack_profile(x, 0, level_f, profiles[0])
    pack_profile(x, PER_UNIT, level_e, profiles[1])
    states = np.empty((n_steps + 1, 4))
    stats = np.zeros(fs.STATS_SIZE)
    if method == MONOLITHIC:
        fs.rk4_monolithic(y0, step, n_steps, seg, joints, units, profiles, states, stats)
    else:
        fs.rk4_partitioned(y0, step, n_steps, seg, joints, units, profiles, coupling, states,
                           stats)
    if stats[fs.STATUS] != fs.OK:
        return False
    if explicit_muscles and stats[fs.WORST_RATIO] > fs.RK4_STABILITY_LIMIT:
        return False
    sample_motion(states, step, times, theta_out, omega_out)
    return True


@njit(cache=True, parallel=True, error_model="numpy")
def score_population(population, method, coupling, y0, step, n_steps, seg, joints, units,
                     level_f, level_e, explicit_muscles, times, target_theta, target_omega,
                     weight_velocity, weight_end, scores, failed):
    """Score every row of ``population`` (m × 18) in parallel threads."""
    for j in prange(population.shape[0]):
        theta = np.empty(times.shape[0])
        omega = np.empty(times.shape[0])
        ok = simulate_candidate(population[j], method, coupling, y0, step, n_steps, seg, joints,
                                units, level_f, level_e, explicit_muscles, times, theta, omega)
        if ok:
            scores[j], _ = score_motion(theta, omega, target_theta, target_omega,
                                        weight_velocity, weight_end)
            failed[j] = False
        else:
            scores[j] = FAILED_SCORE
            failed[j] = True
