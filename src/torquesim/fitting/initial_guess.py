"""Inverse-dynamics initial guess for the fit.

1. Smooth the target (a smoothing spline, GCV) and differentiate: θ, ω, α.
2. Net muscle torque the motion needs (body equation solved for T_net):
   T_net = I_E·α − T_p(θ) + G·sin θ.
3. Quasi-static activations: each CE moves with the joint (SE stretch changing slowly), so
   a unit's torque is a·T_θ(θ_cc)·h(ω_cc) with ω_cc,F = ω, ω_cc,E = −ω and θ_cc from the SE
   stretch. The extensor stays at its rest level while the flexor pulls; when the motion
   needs more extension torque than that, the flexor drops to zero and the extensor supplies it.
4. Ramps: the three-ramp profile of each unit closest (least squares) to its activation.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from ..model.activation import activation
from ..model.body import single_segment_acceleration
from ..model.elbow import ElbowModel
from ..model.torque_generator import ce_torque_velocity, torque_angle
from .objective import PROFILE_SIZE, pack_profile
from .parameters import PER_UNIT, RAMPS_PER_UNIT, ParameterSpace
from .target import Target


def required_torque(model: ElbowModel, target: Target, spacing: float = 0.005):
    """(t, θ, ω, T_net) on a regular grid (s from the target start): the net muscle torque,
    N·m, that makes the body follow the smoothed target."""
    spline = target.smoothed()
    t = np.linspace(0.0, target.duration, int(round(target.duration / spacing)) + 1)
    theta, omega, alpha = spline(t), spline.derivative(1)(t), spline.derivative(2)(t)
    chain = model.to_chain()
    seg, joints = chain.segment_array(), chain.joint_array().ravel()
    inertia = model.body.elbow_inertia
    free = np.array([single_segment_acceleration(x, 0.0, seg, joints) for x in theta])
    return t, theta, omega, inertia * (alpha - free)


def quasi_static_activations(model: ElbowModel, theta, omega, net_torque,
                             extensor_rest: float):
    """Flexor and extensor activation (0–1) that produce ``net_torque`` quasi-statically."""
    pf, pe = model.flexor.to_array(), model.extensor.to_array()
    k_f, k_e = model.flexor.se_stiffness, model.extensor.se_stiffness
    a_f = np.empty_like(theta)
    a_e = np.empty_like(theta)
    for i, (th, om, torque) in enumerate(zip(theta, omega, net_torque, strict=True)):
        cap_e = ce_torque_velocity(-om, pe)
        torque_e = extensor_rest * cap_e * torque_angle(th, pe)
        torque_e = extensor_rest * cap_e * torque_angle(th - torque_e / k_e, pe)
        torque_f = torque + torque_e
        cap_f = ce_torque_velocity(om, pf)
        if torque_f > 0.0 and cap_f > 0.0:
            a_f[i] = torque_f / (cap_f * torque_angle(th + torque_f / k_f, pf))
            a_e[i] = extensor_rest
        else:  # the motion needs extension beyond the extensor's rest torque
            a_f[i] = 0.0
            need = -torque
            a_e[i] = need / (cap_e * torque_angle(th - need / k_e, pe)) if cap_e > 0 else 1.0
    return np.clip(a_f, 0.0, 1.0), np.clip(a_e, 0.0, 1.0)


def fit_ramps(t, level, initial_level: float, lower, upper) -> np.ndarray:
    """The 9 ramp parameters (delay, duration, level × 3) whose profile from
    ``initial_level`` best matches ``level`` at times ``t`` (least squares, in bounds)."""
    packed = np.empty(PROFILE_SIZE)

    def residual(x):
        pack_profile(x, 0, initial_level, packed)
        return np.array([activation(ti, packed) for ti in t]) - level

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


def initial_guess(model: ElbowModel, target: Target, space: ParameterSpace) -> np.ndarray:
    """An 18-vector from inverse dynamics (module docstring), inside the bounds. ``model``
    is the fit's model, already starting at the target's first angle."""
    t, theta, omega, torque = required_torque(model, target)
    a_f, a_e = quasi_static_activations(model, theta, omega, torque, space.extensor_rest)
    start = model.initial_state()
    lower, upper = np.array(space.lower), np.array(space.upper)
    x = np.concatenate([
        fit_ramps(t, a_f, start.flexor_level, lower[:PER_UNIT], upper[:PER_UNIT]),
        fit_ramps(t, a_e, space.extensor_rest, lower[PER_UNIT:], upper[PER_UNIT:]),
    ])
    return space.clip(space.full(x[space.free], x))
