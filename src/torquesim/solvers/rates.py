"""Right-hand sides of the two parts of the model, compiled (MODEL.md §2, §4).

Body part: (θ, ω) with input T_net.  Muscle part: (θ_cc,F, θ_cc,E) with input θ.
Each function is one equation; the solvers combine them. The muscle rates take a solver's
prediction of the CE velocities as ``guess_f``, ``guess_e`` (rad/s, positive = concentric):
they only seed the root finder of the CE equation (NaN: no guess). The ``*_at``
forms take the activations a_F, a_E instead of the time and the activation profiles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..model.activation import activation
from ..model.body import angular_acceleration
from ..model.torque_generator import (
    unit_ce_velocity,
    unit_ce_velocity_and_time_constant,
    unit_torque,
)


@njit(cache=True, error_model="numpy", inline="always")
def flexor_stretch(theta, theta_cc):
    """Flexor SE stretch s_F = θ_cc,F − θ, rad."""
    return theta_cc - theta


@njit(cache=True, error_model="numpy", inline="always")
def extensor_stretch(theta, theta_cc):
    """Extensor SE stretch s_E = θ − θ_cc,E, rad."""
    return theta - theta_cc


@njit(cache=True, error_model="numpy", inline="always")
def net_muscle_torque(theta, theta_cc_f, theta_cc_e, pf, pe):
    """T_net = T_F − T_E, N·m, from the two SE stretches (flexion positive)."""
    return (unit_torque(flexor_stretch(theta, theta_cc_f), pf)
            - unit_torque(extensor_stretch(theta, theta_cc_e), pe))


@njit(cache=True, error_model="numpy", inline="always")
def flexor_rate(theta, theta_cc, activation_level, pf, guess=np.nan):
    """dθ_cc,F/dt = ω_F, rad/s (flexor shortening moves its CE angle towards flexion), at
    activation a_F = ``activation_level``."""
    return unit_ce_velocity(flexor_stretch(theta, theta_cc), theta_cc, activation_level, pf,
                            guess)


@njit(cache=True, error_model="numpy", inline="always")
def extensor_rate(theta, theta_cc, activation_level, pe, guess=np.nan):
    """dθ_cc,E/dt = −ω_E, rad/s (extensor shortening moves its CE angle towards extension), at
    activation a_E = ``activation_level``."""
    return -unit_ce_velocity(extensor_stretch(theta, theta_cc), theta_cc, activation_level, pe,
                             guess)


@njit(cache=True, error_model="numpy", inline="always")
def body_rates(theta, omega, net_torque, b):
    """(dθ/dt, dω/dt) of the body part for a given net muscle torque."""
    return omega, angular_acceleration(theta, net_torque, b)


@njit(cache=True, error_model="numpy", inline="always")
def muscle_rates_at(a_f, a_e, theta, theta_cc_f, theta_cc_e, pf, pe, guess_f=np.nan,
                    guess_e=np.nan):
    """(dθ_cc,F/dt, dθ_cc,E/dt) of the muscle part for a given joint angle and activations
    a_F = ``a_f``, a_E = ``a_e`` (a solver that evaluates a(t) once per stage time)."""
    return (flexor_rate(theta, theta_cc_f, a_f, pf, guess_f),
            extensor_rate(theta, theta_cc_e, a_e, pe, guess_e))


@njit(cache=True, error_model="numpy", inline="always")
def muscle_rates_and_time_constants_at(a_f, a_e, theta, theta_cc_f, theta_cc_e, pf, pe,
                                       guess_f, guess_e):
    """:func:`muscle_rates_at`, and the time constants (τ_F, τ_E) of the two units at that
    state, s (the stability guard's input, at no extra cost)."""
    w_f, tau_f = unit_ce_velocity_and_time_constant(flexor_stretch(theta, theta_cc_f),
                                                    theta_cc_f, a_f, pf, guess_f)
    w_e, tau_e = unit_ce_velocity_and_time_constant(extensor_stretch(theta, theta_cc_e),
                                                    theta_cc_e, a_e, pe, guess_e)
    return (w_f, -w_e), (tau_f, tau_e)


@njit(cache=True, error_model="numpy", inline="always")
def muscle_rates(t, theta, theta_cc_f, theta_cc_e, pf, pe, af, ae, guess_f=np.nan,
                 guess_e=np.nan):
    """(dθ_cc,F/dt, dθ_cc,E/dt) of the muscle part for a given joint angle, at time t (s)."""
    return muscle_rates_at(activation(t, af), activation(t, ae), theta, theta_cc_f,
                           theta_cc_e, pf, pe, guess_f, guess_e)


@njit(cache=True, error_model="numpy", inline="always")
def elbow_rates_at(a_f, a_e, theta, omega, theta_cc_f, theta_cc_e, b, pf, pe, guess_f=np.nan,
                   guess_e=np.nan):
    """dy/dt of the whole model, y = (θ, ω, θ_cc,F, θ_cc,E), at activations a_F, a_E."""
    d_theta, d_omega = body_rates(
        theta, omega, net_muscle_torque(theta, theta_cc_f, theta_cc_e, pf, pe), b)
    d_f, d_e = muscle_rates_at(a_f, a_e, theta, theta_cc_f, theta_cc_e, pf, pe, guess_f,
                               guess_e)
    return d_theta, d_omega, d_f, d_e


@njit(cache=True, error_model="numpy", inline="always")
def elbow_rates(t, theta, omega, theta_cc_f, theta_cc_e, b, pf, pe, af, ae, guess_f=np.nan,
                guess_e=np.nan):
    """dy/dt of the whole model, y = (θ, ω, θ_cc,F, θ_cc,E), at time t (s): body and muscles
    together."""
    return elbow_rates_at(activation(t, af), activation(t, ae), theta, omega, theta_cc_f,
                          theta_cc_e, b, pf, pe, guess_f, guess_e)
