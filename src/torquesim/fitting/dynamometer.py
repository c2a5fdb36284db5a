"""Dynamometer trials made by the model: a unit at full activation on a crank that holds an
angle, then turns at a set speed (the data `torquesim strength` is verified on, and the
shipped examples)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import check_range
from ..io.dynamometer import DynamometerTrial
from ..model.jit import njit
from ..model.torque_generator import TorqueGeneratorUnit, unit_ce_velocity
from .strength import NO_PASSIVE_TORQUE, PassiveTorque

#: Time step of the unit's integration (classical RK4), s; the unit's time constant at full
#: activation is tens of milliseconds, so the trial is exact to rounding at the sampling rate.
STEP = 1e-4
#: Duration of the crank's speed-up and slow-down (a smooth-step in velocity), s.
RAMP = 0.04


def crank_motion(start: float, end: float, speed: float, hold: float, time: np.ndarray):
    """Crank angle (rad) and velocity (rad/s) at ``time``: at ``start`` for ``hold`` s, then
    to ``end`` at ``speed`` (rad/s, > 0; 0 = isometric at ``start``), speeding up and slowing
    down over `RAMP` s with a smooth step, then held."""
    if speed == 0.0 or end == start:
        return np.full_like(time, start), np.zeros_like(time)
    sign = math.copysign(1.0, end - start)
    cruise = abs(end - start) / speed - RAMP  # time at full speed (ramps cover RAMP in total)
    if cruise <= 0.0:
        raise ValueError("the range is too short for the speed")

    def velocity(t):
        u = np.clip((t - hold) / RAMP, 0.0, 1.0)
        w = np.clip((t - hold - RAMP - cruise) / RAMP, 0.0, 1.0)
        up = u * u * (3 - 2 * u)
        down = w * w * (3 - 2 * w)
        return sign * speed * (up - down)

    fine = np.arange(0.0, time[-1] + STEP / 2, STEP / 4)
    v = velocity(fine)
    angle = start + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(fine))])
    return np.interp(time, fine, angle), velocity(time)


def simulate_trial(name: str, unit: TorqueGeneratorUnit, direction: int, start: float,
                   end: float, speed: float, *, hold: float = 0.3, after: float = 0.1,
                   rate: float = 100.0, noise: float = 0.0,
                   passive: PassiveTorque = NO_PASSIVE_TORQUE, activation: float = 1.0,
                   seed: int = 0) -> DynamometerTrial:
    """A maximal trial of the unit (pulling in ``direction``) on a crank (see `crank_motion`;
    angles in rad, ``speed`` in rad/s), sampled at ``rate`` Hz.

    The unit starts slack at full ``activation``; its CE angle follows dθ_cc/dt = δ·ω_cc with
    ω_cc solving the CE equation (docs/model.md §2.5), integrated by RK4 at `STEP`. The crank
    torque is δ·k·max(s, 0) + T_p(θ) plus Gaussian ``noise`` (N·m, standard deviation)."""
    check_range("rate", rate, 10.0, 1e4, unit="Hz")
    duration = hold + (abs(end - start) / speed if speed else 0.5) + after
    time = np.arange(0.0, duration, 1.0 / rate)
    p = unit.to_array()
    steps = int(math.ceil(duration / STEP))
    fine = np.arange(steps + 1) * STEP
    angle_fine, _ = crank_motion(start, end, speed, hold, fine)
    half = crank_motion(start, end, speed, hold, fine[:-1] + STEP / 2)[0]
    theta_cc = _unit_on_crank(start, angle_fine, half, float(direction), activation, p, STEP)
    angle, velocity = crank_motion(start, end, speed, hold, time)
    stretch = direction * (np.interp(time, fine, theta_cc) - angle)
    torque = direction * unit.se_stiffness * np.maximum(stretch, 0.0) + passive(angle)
    if noise:
        torque = torque + np.random.default_rng(seed).normal(0.0, noise, time.size)
    return DynamometerTrial(name, time, angle, velocity, torque, True)


@njit(cache=True, error_model="numpy")
def _unit_on_crank(start, angle, half, direction, activation, p, step):
    """θ_cc (rad) at every crank angle of ``angle`` (rad, one per step of ``step`` s; ``half``
    at the half steps) by classical RK4 on dθ_cc/dt = δ·ω_cc, the unit's CE starting at
    ``start``."""
    theta_cc = np.empty(angle.size)
    theta_cc[0] = start
    for i in range(angle.size - 1):
        c, q0, qh, q1 = theta_cc[i], angle[i], half[i], angle[i + 1]
        k1 = direction * unit_ce_velocity(direction * (c - q0), c, activation, p)
        c2 = c + 0.5 * step * k1
        k2 = direction * unit_ce_velocity(direction * (c2 - qh), c2, activation, p)
        c3 = c + 0.5 * step * k2
        k3 = direction * unit_ce_velocity(direction * (c3 - qh), c3, activation, p)
        c4 = c + step * k3
        k4 = direction * unit_ce_velocity(direction * (c4 - q1), c4, activation, p)
        theta_cc[i + 1] = c + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return theta_cc


def simulate_passive_trial(name: str, start: float, end: float, passive: PassiveTorque, *,
                           speed: float = math.radians(30.0), rate: float = 100.0,
                           noise: float = 0.0, seed: int = 0) -> DynamometerTrial:
    """A relaxed limb moved slowly from ``start`` to ``end``: the torque is T_p(θ) plus
    ``noise``."""
    duration = 0.2 + abs(end - start) / speed + 0.1
    time = np.arange(0.0, duration, 1.0 / rate)
    angle, velocity = crank_motion(start, end, speed, 0.2, time)
    torque = passive(angle) + np.random.default_rng(seed).normal(0.0, noise, time.size) \
        if noise else passive(angle)
    return DynamometerTrial(name, time, angle, velocity, torque, True)
