"""Fixed-step solvers, compiled, for any chain: monolithic RK4 and partitioned RK4 with every
coupling variant, the muscle part explicit (RK4) or implicit (SDIRK2, the IMEX technique).

The loops take the packed chain arrays (:class:`~torquesim.model.chain.PackedChain`), write
the state y = (q, q̇, θ_cc) at every step into ``out`` and fill a ``stats`` array (indices
below). All scratch arrays are allocated once per run; no Python work happens per step.

Stability guard: at the start of every step each unit's time constant τ = a·T_θ·|h'(ω_cc)|/k
is evaluated (from the slope the CE root finder ends with, so at no extra cost) and the
largest step/τ is recorded with its time and unit index; explicit RK4 is stable for
step/τ ≤ :data:`RK4_STABILITY_LIMIT`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..model.activation import activation
from ..model.chain import UNIT_DIRECTION, UNIT_JOINT
from .rates import (
    activations_at,
    body_rates,
    chain_rates,
    joint_muscle_torques,
    muscle_rates,
)
from .sdirk import unit_implicit_ce_velocity

# Indices of the stats array returned by the loops.
STATUS, STEPS, NFEV_BODY, NFEV_MUSCLE, WORST_RATIO, WORST_TIME, WORST_UNIT, SWEEPS, \
    UNIT_SOLVES = range(9)
STATS_SIZE = 9
# Status codes.
OK, NON_FINITE, DIVERGED = 0, 1, 2
#: |q̇| above this (rad/s) at any joint counts as divergence: no human joint turns at
#: 1000 rad/s.
DIVERGENCE_OMEGA = 1.0e3
#: Real-axis stability limit of classical RK4: |λ|·h ≤ 2.785 (the boundary of its region).
RK4_STABILITY_LIMIT = 2.785293563405282

# Coupling scheme array layout (see torquesim.solvers.coupling.Coupling).
ORDER, PREDICTOR, MUSCLE_SUBSTEPS, ITERATIONS, TOLERANCE, MUSCLE_SOLVER = range(6)
COUPLING_SIZE = 6
JACOBI, BODY_FIRST, MUSCLES_FIRST, EVERY_STAGE = 0, 1, 2, 3
HOLD, LINEAR = 0, 1
EXPLICIT_RK4, SDIRK2 = 0, 1
#: Diagonal coefficient γ = 1 − 1/√2 of the L-stable two-stage SDIRK method of order 2.
SDIRK_GAMMA = 1.0 - 1.0 / math.sqrt(2.0)


@njit(cache=True, error_model="numpy")
def _check_state(y, n):
    """OK, NON_FINITE or DIVERGED (|q̇| > DIVERGENCE_OMEGA at some joint)."""
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return NON_FINITE
    for k in range(n):
        if abs(y[n + k]) > DIVERGENCE_OMEGA:
            return DIVERGED
    return OK


@njit(cache=True, error_model="numpy", inline="always")
def _record_stiffness(stats, t, h_muscle, tau):
    """Update the largest step/τ seen (the stability guard) with the units' time constants
    τ (s) at time t."""
    for u in range(tau.shape[0]):
        ratio = h_muscle / tau[u]
        if ratio > stats[WORST_RATIO]:
            stats[WORST_RATIO] = ratio
            stats[WORST_TIME] = t
            stats[WORST_UNIT] = u


@njit(cache=True, error_model="numpy", inline="always")
def _predict(preceding, preceding_before, this_before):
    """Guess for a stage's CE velocity, rad/s: the value of the same stage one step earlier,
    shifted by the change of the preceding stage (stage 4 precedes stage 1) over that step.
    Within 1e-6 rad/s of the root on the default curl at 0.1 ms, so the root finder takes one
    step. The preceding stage's value while there is no history yet."""
    guess = this_before + (preceding - preceding_before)
    return guess if math.isfinite(guess) else preceding


@njit(cache=True, error_model="numpy")
def rk4_monolithic(y0, h, n_steps, seg, jnt, units, profiles, out, stats):
    """Classical RK4 on the whole state y = (q, q̇, θ_cc) (technique 2).

    Every stage evaluates body and muscles together. ``out`` has shape (n_steps + 1, len(y)).
    Activations are evaluated once per stage time. Each stage seeds the CE root finder with a
    prediction from the previous step (see :func:`_predict`).
    """
    n = seg.shape[0]
    nu = units.shape[0]
    size = y0.shape[0]
    y = y0.copy()
    out[0, :] = y
    half = 0.5 * h
    k1, k2, k3, k4 = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
    stage = np.empty(size)
    # CE velocities (rad/s) of stages 1-4 in this step, of the previous step, and of stage 4
    # two steps back: the history the predictions use (NaN: none yet).
    now = np.empty((4, nu))
    seen = np.full((4, nu), np.nan)
    seen4_before = np.full(nu, np.nan)
    guess = np.empty(nu)
    tau = np.empty(nu)
    a_now, a_mid, a_next = np.empty(nu), np.empty(nu), np.empty(nu)
    torque = np.empty(n)
    work = np.empty((n, n + 4))
    activations_at(0.0, profiles, a_now)
    for step in range(n_steps):
        t = step * h
        activations_at(t + half, profiles, a_mid)
        activations_at((step + 1) * h, profiles, a_next)
        for u in range(nu):
            guess[u] = _predict(seen[3, u], seen4_before[u], seen[0, u])
        chain_rates(y, a_now, guess, seg, jnt, units, torque, work, k1, now[0], tau)
        _record_stiffness(stats, t, h, tau)
        for i in range(size):
            stage[i] = y[i] + half * k1[i]
        for u in range(nu):
            guess[u] = _predict(now[0, u], seen[0, u], seen[1, u])
        chain_rates(stage, a_mid, guess, seg, jnt, units, torque, work, k2, now[1], tau)
        for i in range(size):
            stage[i] = y[i] + half * k2[i]
        for u in range(nu):
            guess[u] = _predict(now[1, u], seen[1, u], seen[2, u])
        chain_rates(stage, a_mid, guess, seg, jnt, units, torque, work, k3, now[2], tau)
        for i in range(size):
            stage[i] = y[i] + h * k3[i]
        for u in range(nu):
            guess[u] = _predict(now[2, u], seen[2, u], seen[3, u])
        chain_rates(stage, a_next, guess, seg, jnt, units, torque, work, k4, now[3], tau)
        for u in range(nu):
            seen4_before[u] = seen[3, u]
            for s in range(4):
                seen[s, u] = now[s, u]
            a_now[u] = a_next[u]
        w = h / 6.0
        for i in range(size):
            y[i] += w * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
        stats[NFEV_BODY] += 4
        stats[NFEV_MUSCLE] += 4
        out[step + 1, :] = y
        stats[STEPS] = step + 1
        status = _check_state(y, n)
        if status != OK:
            stats[STATUS] = status
            return
    stats[SWEEPS] = n_steps


@njit(cache=True, error_model="numpy")
def _body_rk4(y, n, h, torque0, torque_slope, seg, jnt, scratch, work, y_new):
    """One RK4 step of the body part (q, q̇) = y[:2n] with joint torques
    τ(s) = τ0 + slope·s/h over the step; the result into y_new[:2n]. ``scratch``: 6 rows of
    at least 2n."""
    half = 0.5 * h
    m = 2 * n
    torque = scratch[0]
    k1, k2, k3, k4, stage = scratch[1], scratch[2], scratch[3], scratch[4], scratch[5]
    body_rates(y, n, torque0, seg, jnt, work, k1)
    for j in range(n):
        torque[j] = torque0[j] + 0.5 * torque_slope[j]
    for i in range(m):
        stage[i] = y[i] + half * k1[i]
    body_rates(stage, n, torque, seg, jnt, work, k2)
    for i in range(m):
        stage[i] = y[i] + half * k2[i]
    body_rates(stage, n, torque, seg, jnt, work, k3)
    for j in range(n):
        torque[j] = torque0[j] + torque_slope[j]
    for i in range(m):
        stage[i] = y[i] + h * k3[i]
    body_rates(stage, n, torque, seg, jnt, work, k4)
    w = h / 6.0
    for i in range(m):
        y_new[i] = y[i] + w * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


@njit(cache=True, error_model="numpy")
def _muscle_rk4(t, theta_cc, h, substeps, q0, q_slope, start_rate, start_omega, units,
                profiles, scratch, out):
    """``substeps`` RK4 steps of the muscle part over [t, t + h] with joint angles
    q(s) = q0 + slope·s/h; activation is evaluated at every stage time. Result into ``out``.

    ``start_rate``/``start_omega`` are the muscle rates and CE velocities at (t, q0, θ_cc)
    already evaluated by the caller: the first stage of the first sub-step. Makes
    4·substeps − 1 muscle evaluations.
    """
    nu = units.shape[0]
    n = q0.shape[0]
    hs = h / substeps
    half = 0.5 * hs
    k1, k2, k3, k4 = scratch[0, :nu], scratch[1, :nu], scratch[2, :nu], scratch[3, :nu]
    w1, w2, w3, w4 = scratch[4, :nu], scratch[5, :nu], scratch[6, :nu], scratch[7, :nu]
    stage, levels, tau = scratch[8, :nu], scratch[9, :nu], scratch[10, :nu]
    q = scratch[11, :n]
    x = out
    for u in range(nu):
        x[u] = theta_cc[u]
        w4[u] = start_omega[u]  # the previous sub-step's last stage seeds the next first
    for sub in range(substeps):
        s = sub * hs
        ts = t + s
        if sub == 0:
            for u in range(nu):
                k1[u] = start_rate[u]
                w1[u] = start_omega[u]
        else:
            for j in range(n):
                q[j] = q0[j] + q_slope[j] / h * s
            activations_at(ts, profiles, levels)
            muscle_rates(q, x, levels, w4, units, k1, w1, tau)
        for j in range(n):
            q[j] = q0[j] + q_slope[j] / h * (s + half)
        activations_at(ts + half, profiles, levels)
        for u in range(nu):
            stage[u] = x[u] + half * k1[u]
        muscle_rates(q, stage, levels, w1, units, k2, w2, tau)
        for u in range(nu):
            stage[u] = x[u] + half * k2[u]
        muscle_rates(q, stage, levels, w2, units, k3, w3, tau)
        for j in range(n):
            q[j] = q0[j] + q_slope[j] / h * (s + hs)
        activations_at(ts + hs, profiles, levels)
        for u in range(nu):
            stage[u] = x[u] + hs * k3[u]
        muscle_rates(q, stage, levels, w3, units, k4, w4, tau)
        w = hs / 6.0
        for u in range(nu):
            x[u] += w * (k1[u] + 2.0 * (k2[u] + k3[u]) + k4[u])


@njit(cache=True, error_model="numpy")
def _muscle_sdirk2(t, theta_cc, h, substeps, q0, q_slope, start_omega, units, profiles,
                   scratch, stats, out):
    """``substeps`` steps of the muscle part over [t, t + h] by the L-stable two-stage SDIRK
    method of order 2 (γ = 1 − 1/√2; stages at t + γh and t + h; stiffly accurate), each
    unit's stage equation solved by :func:`~torquesim.solvers.sdirk.unit_implicit_ce_velocity`.
    Joint angles q(s) = q0 + slope·s/h. With this the muscle part has no step-size stability
    limit. Result into ``out``.

    ``start_omega`` (the explicit CE velocities at the step start) seeds Newton's method. Each
    unit residual evaluation is counted in ``stats[UNIT_SOLVES]``.
    """
    nu = units.shape[0]
    hs = h / substeps
    gh = SDIRK_GAMMA * hs
    guess = scratch[0]
    stage_x = scratch[1]
    x = out
    for u in range(nu):
        x[u] = theta_cc[u]
        guess[u] = start_omega[u]
    solves = 0
    for sub in range(substeps):
        s = sub * hs
        ts = t + s
        for u in range(nu):
            j = int(units[u, UNIT_JOINT])
            d = units[u, UNIT_DIRECTION]
            rate = q_slope[j] / h
            # Stage 1 at t + γh: θ_cc = θ_cc,n + γh·(dθ_cc/dt)_1.
            q1 = q0[j] + rate * (s + gh)
            w1, count = unit_implicit_ce_velocity(d * (x[u] - q1), x[u], d, gh,
                                                  activation(ts + gh, profiles[u]),
                                                  units[u], guess[u])
            solves += count
            # Stage 2 at t + h: θ_cc = θ_cc,n + (1 − γ)h·(dθ_cc/dt)_1 + γh·(dθ_cc/dt)_2.
            q2 = q0[j] + rate * (s + hs)
            stage_x[u] = x[u] + d * ((hs - gh) * w1)
            w2, count = unit_implicit_ce_velocity(d * (stage_x[u] - q2), stage_x[u], d, gh,
                                                  activation(ts + hs, profiles[u]),
                                                  units[u], w1)
            solves += count
            x[u] = stage_x[u] + d * (gh * w2)
            guess[u] = w2
    stats[UNIT_SOLVES] += solves


@njit(cache=True, error_model="numpy")
def _stage_exchange_step(t, y, h, start_omega, seg, jnt, units, profiles, scratch, work,
                         y_new):
    """One step with each part's own RK4 stages, exchanging values at every stage.

    The body stage sees the torque of the muscle stage state and the muscle stage sees the
    body stage angle: algebraically this is monolithic RK4, written through the two parts.
    ``start_omega`` (CE velocities at the step start) seeds the first stage's root finder.
    """
    n = seg.shape[0]
    size = y.shape[0]
    half = 0.5 * h
    k1, k2, k3, k4, stage = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    nu = units.shape[0]
    w1, w2, w3, w4 = scratch[5][:nu], scratch[6][:nu], scratch[7][:nu], scratch[8][:nu]
    levels, tau, torque = scratch[9][:nu], scratch[10][:nu], scratch[11][:n]
    activations_at(t, profiles, levels)
    chain_rates(y, levels, start_omega, seg, jnt, units, torque, work, k1, w1, tau)
    for i in range(size):
        stage[i] = y[i] + half * k1[i]
    activations_at(t + half, profiles, levels)
    chain_rates(stage, levels, w1, seg, jnt, units, torque, work, k2, w2, tau)
    for i in range(size):
        stage[i] = y[i] + half * k2[i]
    chain_rates(stage, levels, w2, seg, jnt, units, torque, work, k3, w3, tau)
    for i in range(size):
        stage[i] = y[i] + h * k3[i]
    activations_at(t + h, profiles, levels)
    chain_rates(stage, levels, w3, seg, jnt, units, torque, work, k4, w4, tau)
    w = h / 6.0
    for i in range(size):
        y_new[i] = y[i] + w * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


@njit(cache=True, error_model="numpy")
def rk4_partitioned(y0, h, n_steps, seg, jnt, units, profiles, coupling, out, stats):
    """Body and muscle parts each advanced by their own integrator, exchanging at step
    boundaries (technique 1), under the coupling scheme ``coupling`` (see ``Coupling``).

    Default scheme (Jacobi, hold, 1 sub-step, 1 sweep): the body integrates with the joint
    torques held at τ(y_n) and the muscles with the joint angles held at q_n (zero-order hold).
    Within a step each exchanged signal is affine in time: its step-start value plus a slope
    that is zero (hold), the previous step's change (linear extrapolation) or, once the other
    part has been advanced in this step, the change it produced (Gauss-Seidel / iteration).
    """
    order = int(coupling[ORDER])
    predictor = int(coupling[PREDICTOR])
    substeps = int(coupling[MUSCLE_SUBSTEPS])
    sweeps = int(coupling[ITERATIONS])
    tol = coupling[TOLERANCE]
    implicit_muscles = int(coupling[MUSCLE_SOLVER]) == SDIRK2
    n = seg.shape[0]
    nu = units.shape[0]
    size = y0.shape[0]
    width = max(size, n + 1)
    y = y0.copy()
    y1 = y0.copy()
    old = np.empty(size)
    out[0, :] = y
    scratch = np.empty((12, width))
    work = np.empty((n, n + 4))
    rate = np.empty(nu)
    omega = np.full(nu, np.nan)
    tau = np.empty(nu)
    levels = np.empty(nu)
    torque_n = np.empty(n)
    torque_prev = np.empty(n)
    torque_slope = np.empty(n)
    torque_end = np.empty(n)
    q_prev = y0[:n].copy()
    q_slope = np.empty(n)
    joint_muscle_torques(y[:n], y[2 * n:], units, torque_prev)
    hm = h / substeps
    for step in range(n_steps):
        t = step * h
        joint_muscle_torques(y[:n], y[2 * n:], units, torque_n)
        activations_at(t, profiles, levels)
        muscle_rates(y[:n], y[2 * n:], levels, omega, units, rate, omega, tau)
        stats[NFEV_MUSCLE] += 1
        _record_stiffness(stats, t, hm, tau)
        if order == EVERY_STAGE:
            _stage_exchange_step(t, y, h, omega, seg, jnt, units, profiles, scratch, work, y1)
            stats[NFEV_BODY] += 4
            stats[NFEV_MUSCLE] += 4
            stats[SWEEPS] += 1
        else:
            for j in range(n):
                if predictor == LINEAR and step > 0:
                    q_slope[j] = y[j] - q_prev[j]
                    torque_slope[j] = torque_n[j] - torque_prev[j]
                else:
                    q_slope[j] = 0.0
                    torque_slope[j] = 0.0
            for i in range(size):
                y1[i] = y[i]
            for sweep in range(sweeps):
                for i in range(size):
                    old[i] = y1[i]
                if order == MUSCLES_FIRST:
                    _muscle_step(t, y[2 * n:], h, substeps, y[:n], q_slope, rate, omega, units,
                                 profiles, implicit_muscles, scratch, stats, y1[2 * n:])
                    for j in range(n):
                        scratch[0, j] = y[j] + q_slope[j]
                    joint_muscle_torques(scratch[0, :n], y1[2 * n:], units, torque_end)
                    for j in range(n):
                        torque_slope[j] = torque_end[j] - torque_n[j]
                    _body_rk4(y, n, h, torque_n, torque_slope, seg, jnt, scratch[5:], work, y1)
                else:
                    _body_rk4(y, n, h, torque_n, torque_slope, seg, jnt, scratch[5:], work, y1)
                    if order == BODY_FIRST:
                        for j in range(n):
                            q_slope[j] = y1[j] - y[j]
                    _muscle_step(t, y[2 * n:], h, substeps, y[:n], q_slope, rate, omega, units,
                                 profiles, implicit_muscles, scratch, stats, y1[2 * n:])
                stats[NFEV_BODY] += 4
                stats[SWEEPS] += 1
                # Later sweeps see the other part's end-of-step values (waveform relaxation).
                joint_muscle_torques(y1[:n], y1[2 * n:], units, torque_end)
                for j in range(n):
                    q_slope[j] = y1[j] - y[j]
                    torque_slope[j] = torque_end[j] - torque_n[j]
                if sweep > 0 and tol > 0.0:
                    change = 0.0
                    for i in range(size):
                        scale = h if n <= i < 2 * n else 1.0
                        change = max(change, abs(y1[i] - old[i]) * scale)
                    if change <= tol:
                        break
        for j in range(n):
            q_prev[j] = y[j]
            torque_prev[j] = torque_n[j]
        for i in range(size):
            y[i] = y1[i]
        out[step + 1, :] = y
        stats[STEPS] = step + 1
        status = _check_state(y, n)
        if status != OK:
            stats[STATUS] = status
            return


@njit(cache=True, error_model="numpy")
def _muscle_step(t, theta_cc, h, substeps, q0, q_slope, start_rate, start_omega, units,
                 profiles, implicit, scratch, stats, out):
    """Advance the muscle part over one body step with explicit RK4 or implicit SDIRK2."""
    if implicit:
        _muscle_sdirk2(t, theta_cc, h, substeps, q0, q_slope, start_omega, units, profiles,
                       scratch, stats, out)
        return
    stats[NFEV_MUSCLE] += 4 * substeps - 1
    _muscle_rk4(t, theta_cc, h, substeps, q0, q_slope, start_rate, start_omega, units,
                profiles, scratch, out)


def new_stats() -> np.ndarray:
    """A zeroed stats array for the loops."""
    return np.zeros(STATS_SIZE)
