"""Fixed-step classical RK4 solvers, compiled: monolithic and partitioned (MODEL.md §4).

Both loops take plain float arrays, write the state at every step into ``out`` and return a
``stats`` array (indices below). No Python work happens per step.

Stability guard: at the start of every step each unit's time constant τ = a·T_θ·|h'(ω_cc)|/k
is evaluated (closed form, from the slope the CE root finder ends with, so at no extra cost)
and the largest step/τ is recorded with its time and unit; explicit RK4 is stable for
step/τ ≤ 2.785 (:data:`~torquesim.model.torque_generator.RK4_STABILITY_LIMIT`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..model.activation import activation
from ..model.torque_generator import unit_implicit_ce_velocity
from .rates import (
    body_rates,
    elbow_rates_at,
    muscle_rates,
    muscle_rates_and_time_constants_at,
    net_muscle_torque,
)

# Indices of the stats array returned by the loops.
STATUS, STEPS, NFEV_BODY, NFEV_MUSCLE, WORST_RATIO, WORST_TIME, WORST_UNIT, SWEEPS, \
    UNIT_SOLVES = range(9)
STATS_SIZE = 9
# Status codes.
OK, NON_FINITE, DIVERGED = 0, 1, 2
#: |ω| above this (rad/s) counts as divergence: no elbow moves at 1000 rad/s.
DIVERGENCE_OMEGA = 1.0e3

# Coupling scheme array layout (see torquesim.solvers.coupling.Coupling).
ORDER, PREDICTOR, MUSCLE_SUBSTEPS, ITERATIONS, TOLERANCE, MUSCLE_SOLVER = range(6)
COUPLING_SIZE = 6
JACOBI, BODY_FIRST, MUSCLES_FIRST, EVERY_STAGE = 0, 1, 2, 3
HOLD, LINEAR = 0, 1
EXPLICIT_RK4, SDIRK2 = 0, 1
#: Diagonal coefficient γ = 1 − 1/√2 of the L-stable two-stage SDIRK method of order 2.
SDIRK_GAMMA = 1.0 - 1.0 / math.sqrt(2.0)


@njit(cache=True, error_model="numpy")
def _check_state(theta, omega, theta_cc_f, theta_cc_e):
    if not (math.isfinite(theta) and math.isfinite(omega) and math.isfinite(theta_cc_f)
            and math.isfinite(theta_cc_e)):
        return NON_FINITE
    if abs(omega) > DIVERGENCE_OMEGA:
        return DIVERGED
    return OK


@njit(cache=True, error_model="numpy")
def _record_stiffness(stats, t, h_muscle, tau_f, tau_e):
    """Update the largest step/τ seen (the stability guard) with the units' time constants
    τ_F, τ_E (s) at time t."""
    ratio_f = h_muscle / tau_f
    ratio_e = h_muscle / tau_e
    if ratio_f > stats[WORST_RATIO]:
        stats[WORST_RATIO] = ratio_f
        stats[WORST_TIME] = t
        stats[WORST_UNIT] = 0.0
    if ratio_e > stats[WORST_RATIO]:
        stats[WORST_RATIO] = ratio_e
        stats[WORST_TIME] = t
        stats[WORST_UNIT] = 1.0


@njit(cache=True, error_model="numpy", inline="always")
def _predict(preceding, preceding_before, this_before):
    """Guess for a stage's CE velocity, rad/s: the value of the same stage one step earlier,
    shifted by the change of the preceding stage (stage 4 precedes stage 1) over that step.
    Within 1e-6 rad/s of the root on the default curl at 0.1 ms, so the root finder takes one
    step. The preceding stage's value while there is no history yet."""
    guess = this_before + (preceding - preceding_before)
    return guess if math.isfinite(guess) else preceding


@njit(cache=True, error_model="numpy")
def rk4_monolithic(y0, h, n_steps, b, pf, pe, af, ae, out, stats):
    """Classical RK4 on the whole state y = (θ, ω, θ_cc,F, θ_cc,E) (technique 2).

    Every stage evaluates body and muscles together. ``out`` has shape (n_steps + 1, 4).
    Activations are evaluated once per stage time. Each stage seeds the CE root finder with a
    prediction from the previous step (see :func:`_predict`).
    """
    th, om, tf, te = y0[0], y0[1], y0[2], y0[3]
    out[0, 0], out[0, 1], out[0, 2], out[0, 3] = th, om, tf, te
    half = 0.5 * h
    # CE velocities (rad/s; flexor, extensor) of stages 1-4 in the previous step, and of
    # stage 4 two steps back: the history the predictions use (NaN: none yet).
    seen = np.full((4, 2), np.nan)
    seen4_before = np.full(2, np.nan)
    a_f, a_e = activation(0.0, af), activation(0.0, ae)
    for n in range(n_steps):
        t = n * h
        t_next = (n + 1) * h
        a_f_mid, a_e_mid = activation(t + half, af), activation(t + half, ae)
        a_f_next, a_e_next = activation(t_next, af), activation(t_next, ae)
        muscle1, tau = muscle_rates_and_time_constants_at(
            a_f, a_e, th, tf, te, pf, pe, _predict(seen[3, 0], seen4_before[0], seen[0, 0]),
            _predict(seen[3, 1], seen4_before[1], seen[0, 1]))
        k1 = body_rates(th, om, net_muscle_torque(th, tf, te, pf, pe), b) + muscle1
        _record_stiffness(stats, t, h, tau[0], tau[1])
        k2 = elbow_rates_at(a_f_mid, a_e_mid, th + half * k1[0], om + half * k1[1],
                            tf + half * k1[2], te + half * k1[3], b, pf, pe,
                            _predict(k1[2], seen[0, 0], seen[1, 0]),
                            _predict(-k1[3], seen[0, 1], seen[1, 1]))
        k3 = elbow_rates_at(a_f_mid, a_e_mid, th + half * k2[0], om + half * k2[1],
                            tf + half * k2[2], te + half * k2[3], b, pf, pe,
                            _predict(k2[2], seen[1, 0], seen[2, 0]),
                            _predict(-k2[3], seen[1, 1], seen[2, 1]))
        k4 = elbow_rates_at(a_f_next, a_e_next, th + h * k3[0], om + h * k3[1],
                            tf + h * k3[2], te + h * k3[3], b, pf, pe,
                            _predict(k3[2], seen[2, 0], seen[3, 0]),
                            _predict(-k3[3], seen[2, 1], seen[3, 1]))
        seen4_before[0], seen4_before[1] = seen[3, 0], seen[3, 1]
        seen[0, 0], seen[0, 1] = k1[2], -k1[3]
        seen[1, 0], seen[1, 1] = k2[2], -k2[3]
        seen[2, 0], seen[2, 1] = k3[2], -k3[3]
        seen[3, 0], seen[3, 1] = k4[2], -k4[3]
        a_f, a_e = a_f_next, a_e_next
        w = h / 6.0
        th += w * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
        om += w * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
        tf += w * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2])
        te += w * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
        stats[NFEV_BODY] += 4
        stats[NFEV_MUSCLE] += 4
        out[n + 1, 0], out[n + 1, 1], out[n + 1, 2], out[n + 1, 3] = th, om, tf, te
        stats[STEPS] = n + 1
        status = _check_state(th, om, tf, te)
        if status != OK:
            stats[STATUS] = status
            return
    stats[SWEEPS] = n_steps


@njit(cache=True, error_model="numpy")
def _body_rk4(th, om, h, torque0, torque_slope, b):
    """One RK4 step of the body part with net torque T(s) = T0 + slope·s/h over the step."""
    half = 0.5 * h
    t_mid = torque0 + 0.5 * torque_slope
    k1 = body_rates(th, om, torque0, b)
    k2 = body_rates(th + half * k1[0], om + half * k1[1], t_mid, b)
    k3 = body_rates(th + half * k2[0], om + half * k2[1], t_mid, b)
    k4 = body_rates(th + h * k3[0], om + h * k3[1], torque0 + torque_slope, b)
    w = h / 6.0
    return (th + w * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]),
            om + w * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]))


@njit(cache=True, error_model="numpy")
def _muscle_rk4(t, tf, te, h, substeps, theta0, theta_slope, start_rate, pf, pe, af, ae):
    """``substeps`` RK4 steps of the muscle part over [t, t + h] with joint angle
    θ(s) = θ0 + slope·s/h; activation is evaluated at every stage time.

    ``start_rate`` is the muscle rate at (t, θ0, θ_cc) already evaluated by the caller: it is
    the first stage of the first sub-step. Makes 4·substeps − 1 muscle evaluations.
    """
    hs = h / substeps
    half = 0.5 * hs
    rate = theta_slope / h
    k4 = start_rate  # the previous sub-step's last stage: seeds the next first stage
    for j in range(substeps):
        s = j * hs
        ts = t + s
        if j == 0:
            k1 = start_rate
        else:
            k1 = muscle_rates(ts, theta0 + rate * s, tf, te, pf, pe, af, ae, k4[0], -k4[1])
        th_mid = theta0 + rate * (s + half)
        k2 = muscle_rates(ts + half, th_mid, tf + half * k1[0], te + half * k1[1],
                          pf, pe, af, ae, k1[0], -k1[1])
        k3 = muscle_rates(ts + half, th_mid, tf + half * k2[0], te + half * k2[1],
                          pf, pe, af, ae, k2[0], -k2[1])
        k4 = muscle_rates(ts + hs, theta0 + rate * (s + hs), tf + hs * k3[0],
                          te + hs * k3[1], pf, pe, af, ae, k3[0], -k3[1])
        w = hs / 6.0
        tf += w * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
        te += w * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
    return tf, te


@njit(cache=True, error_model="numpy")
def _muscle_sdirk2(t, tf, te, h, substeps, theta0, theta_slope, start_rate, pf, pe, af, ae,
                   stats):
    """``substeps`` steps of the muscle part over [t, t + h] by the L-stable two-stage SDIRK
    method of order 2 (γ = 1 − 1/√2; stages at t + γh and t + h; stiffly accurate), each
    unit's stage equation solved by :func:`unit_implicit_ce_velocity`. Joint angle
    θ(s) = θ0 + slope·s/h. With this the muscle part has no step-size stability limit.

    ``start_rate`` (the explicit rates at the step start) seeds Newton's method. Each unit
    residual evaluation is counted in ``stats[UNIT_SOLVES]``.
    """
    hs = h / substeps
    gh = SDIRK_GAMMA * hs
    rate = theta_slope / h
    guess_f, guess_e = start_rate[0], -start_rate[1]
    solves = 0
    for j in range(substeps):
        s = j * hs
        ts = t + s
        # Stage 1 at t + γh: θ_cc = θ_cc,n + γh·(dθ_cc/dt)_1.
        th1 = theta0 + rate * (s + gh)
        w_f1, n_f = unit_implicit_ce_velocity(tf - th1, tf, 1.0, gh, activation(ts + gh, af),
                                              pf, guess_f)
        w_e1, n_e = unit_implicit_ce_velocity(th1 - te, te, -1.0, gh, activation(ts + gh, ae),
                                              pe, guess_e)
        solves += n_f + n_e
        # Stage 2 at t + h: θ_cc = θ_cc,n + (1 − γ)h·(dθ_cc/dt)_1 + γh·(dθ_cc/dt)_2.
        th2 = theta0 + rate * (s + hs)
        xf = tf + (hs - gh) * w_f1
        xe = te - (hs - gh) * w_e1
        w_f2, n_f = unit_implicit_ce_velocity(xf - th2, xf, 1.0, gh, activation(ts + hs, af),
                                              pf, w_f1)
        w_e2, n_e = unit_implicit_ce_velocity(th2 - xe, xe, -1.0, gh, activation(ts + hs, ae),
                                              pe, w_e1)
        solves += n_f + n_e
        tf = xf + gh * w_f2
        te = xe - gh * w_e2
        guess_f, guess_e = w_f2, w_e2
    stats[UNIT_SOLVES] += solves
    return tf, te


@njit(cache=True, error_model="numpy")
def _muscle_step(t, tf, te, h, substeps, theta0, theta_slope, start_rate, pf, pe, af, ae,
                 implicit, stats):
    """Advance the muscle part over one body step with explicit RK4 or implicit SDIRK2."""
    if implicit:
        return _muscle_sdirk2(t, tf, te, h, substeps, theta0, theta_slope, start_rate,
                              pf, pe, af, ae, stats)
    stats[NFEV_MUSCLE] += 4 * substeps - 1
    return _muscle_rk4(t, tf, te, h, substeps, theta0, theta_slope, start_rate, pf, pe, af, ae)


@njit(cache=True, error_model="numpy")
def _stage_exchange_step(t, th, om, tf, te, h, start_rate, b, pf, pe, af, ae):
    """One step with each part's own RK4 stages, exchanging values at every stage.

    The body stage sees the torque of the muscle stage state and the muscle stage sees the
    body stage angle: algebraically this is monolithic RK4, written through the two parts.
    ``start_rate`` (muscle rates at the step start) seeds the first stage's CE root finder.
    """
    half = 0.5 * h
    kb1 = body_rates(th, om, net_muscle_torque(th, tf, te, pf, pe), b)
    km1 = muscle_rates(t, th, tf, te, pf, pe, af, ae, start_rate[0], -start_rate[1])
    th2, om2, tf2, te2 = th + half * kb1[0], om + half * kb1[1], tf + half * km1[0], \
        te + half * km1[1]
    kb2 = body_rates(th2, om2, net_muscle_torque(th2, tf2, te2, pf, pe), b)
    km2 = muscle_rates(t + half, th2, tf2, te2, pf, pe, af, ae, km1[0], -km1[1])
    th3, om3, tf3, te3 = th + half * kb2[0], om + half * kb2[1], tf + half * km2[0], \
        te + half * km2[1]
    kb3 = body_rates(th3, om3, net_muscle_torque(th3, tf3, te3, pf, pe), b)
    km3 = muscle_rates(t + half, th3, tf3, te3, pf, pe, af, ae, km2[0], -km2[1])
    th4, om4, tf4, te4 = th + h * kb3[0], om + h * kb3[1], tf + h * km3[0], te + h * km3[1]
    kb4 = body_rates(th4, om4, net_muscle_torque(th4, tf4, te4, pf, pe), b)
    km4 = muscle_rates(t + h, th4, tf4, te4, pf, pe, af, ae, km3[0], -km3[1])
    w = h / 6.0
    return (th + w * (kb1[0] + 2.0 * (kb2[0] + kb3[0]) + kb4[0]),
            om + w * (kb1[1] + 2.0 * (kb2[1] + kb3[1]) + kb4[1]),
            tf + w * (km1[0] + 2.0 * (km2[0] + km3[0]) + km4[0]),
            te + w * (km1[1] + 2.0 * (km2[1] + km3[1]) + km4[1]))


@njit(cache=True, error_model="numpy")
def rk4_partitioned(y0, h, n_steps, b, pf, pe, af, ae, coupling, out, stats):
    """Body and muscle parts each advanced by their own RK4, exchanging at step boundaries
    (technique 1), under the coupling scheme ``coupling`` (see ``Coupling``).

    Default scheme (Jacobi, hold, 1 sub-step, 1 sweep): the body integrates with T_net held at
    T_net(y_n) and the muscles with θ held at θ_n (zero-order hold).
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
    th, om, tf, te = y0[0], y0[1], y0[2], y0[3]
    out[0, 0], out[0, 1], out[0, 2], out[0, 3] = th, om, tf, te
    th_prev = th
    torque_prev = net_muscle_torque(th, tf, te, pf, pe)
    hm = h / substeps
    rate = (np.nan, np.nan)
    for n in range(n_steps):
        t = n * h
        torque_n = net_muscle_torque(th, tf, te, pf, pe)
        rate, tau = muscle_rates_and_time_constants_at(activation(t, af), activation(t, ae),
                                                       th, tf, te, pf, pe, rate[0], -rate[1])
        stats[NFEV_MUSCLE] += 1
        _record_stiffness(stats, t, hm, tau[0], tau[1])
        if order == EVERY_STAGE:
            th1, om1, tf1, te1 = _stage_exchange_step(t, th, om, tf, te, h, rate,
                                                      b, pf, pe, af, ae)
            stats[NFEV_BODY] += 4
            stats[NFEV_MUSCLE] += 4
            stats[SWEEPS] += 1
        else:
            if predictor == LINEAR and n > 0:
                theta_slope = th - th_prev
                torque_slope = torque_n - torque_prev
            else:
                theta_slope = 0.0
                torque_slope = 0.0
            th1, om1, tf1, te1 = th, om, tf, te
            for sweep in range(sweeps):
                old = (th1, om1, tf1, te1)
                if order == MUSCLES_FIRST:
                    tf1, te1 = _muscle_step(t, tf, te, h, substeps, th, theta_slope, rate,
                                            pf, pe, af, ae, implicit_muscles, stats)
                    torque_slope = net_muscle_torque(th + theta_slope, tf1, te1, pf, pe) \
                        - torque_n
                    th1, om1 = _body_rk4(th, om, h, torque_n, torque_slope, b)
                else:
                    th1, om1 = _body_rk4(th, om, h, torque_n, torque_slope, b)
                    if order == BODY_FIRST:
                        theta_slope = th1 - th
                    tf1, te1 = _muscle_step(t, tf, te, h, substeps, th, theta_slope, rate,
                                            pf, pe, af, ae, implicit_muscles, stats)
                stats[NFEV_BODY] += 4
                stats[SWEEPS] += 1
                # Later sweeps see the other part's end-of-step values (waveform relaxation).
                theta_slope = th1 - th
                torque_slope = net_muscle_torque(th1, tf1, te1, pf, pe) - torque_n
                if sweep > 0 and tol > 0.0:
                    change = max(abs(th1 - old[0]), abs(om1 - old[1]) * h,
                                 abs(tf1 - old[2]), abs(te1 - old[3]))
                    if change <= tol:
                        break
        th_prev, torque_prev = th, torque_n
        th, om, tf, te = th1, om1, tf1, te1
        out[n + 1, 0], out[n + 1, 1], out[n + 1, 2], out[n + 1, 3] = th, om, tf, te
        stats[STEPS] = n + 1
        status = _check_state(th, om, tf, te)
        if status != OK:
            stats[STATUS] = status
            return


def new_stats() -> np.ndarray:
    """A zeroed stats array for the loops."""
    return np.zeros(STATS_SIZE)
