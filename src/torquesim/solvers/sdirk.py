"""A unit's implicit stage, for the SDIRK2 muscle solver (IMEX): `unit_implicit_stage`.

A diagonally implicit Runge-Kutta stage asks for the CE velocity w at the stage state it
produces itself: θ_cc = θ_cc,known + d·γh·w, s = s_known + γh·w. This module solves that
scalar equation (`unit_implicit_ce_velocity`); the CE equation itself lives in
`torquesim.model.torque_generator`.
"""

from __future__ import annotations

from ..model.activation import implicit_activation
from ..model.jit import njit
from ..model.state import has_activation_state
from ..model.torque_generator import (
    ACTIVATION_FLOOR,
    CE_DAMPING,
    K_SE,
    OMEGA_MAX,
    ce_torque_velocity,
    ce_torque_velocity_slope,
    torque_angle,
    torque_angle_slope,
)
from ..model.unit_row import (
    UNIT_ACTIVATION_TIME,
    UNIT_DEACTIVATION_TIME,
    UNIT_DIRECTION,
    UNIT_ROW_SIZE,
)

#: An update of the CE velocity below this fraction of ω_max counts as within Newton's
#: quadratic convergence (where the error left is far below the update), for the stage-state
#: tolerance of `unit_implicit_ce_velocity`: a larger one may still be far from the root when
#: γh is small, though it moves the state little.
QUADRATIC_REGIME = 0.01


@njit(cache=True, error_model="numpy", inline="always")
def _implicit_residual(w, stretch_known, theta_cc_known, sign, gamma_h, capacity_activation, p,
                       o=0):
    """Residual G(w) and dG/dw of the implicit CE equation (see unit_implicit_ce_velocity)."""
    x = theta_cc_known + sign * gamma_h * w
    t_theta = torque_angle(x, p, o)
    t_theta_slope = torque_angle_slope(x, p, o) * sign * gamma_h  # d T_θ / d w
    stretch = stretch_known + gamma_h * w
    h_value = ce_torque_velocity(w, p, o)
    g = capacity_activation * t_theta * h_value - p[o + CE_DAMPING] * w
    slope = capacity_activation * (t_theta_slope * h_value
                                   + t_theta * ce_torque_velocity_slope(w, p, o)) \
        - p[o + CE_DAMPING]
    if stretch > 0.0:
        g -= p[o + K_SE] * stretch
        slope -= p[o + K_SE] * gamma_h
    return g, slope


@njit(cache=True, error_model="numpy", _nrt=False)
def unit_implicit_ce_velocity(stretch_known, theta_cc_known, sign, gamma_h, activation, p,
                              guess, o=0, state_tolerance=0.0):
    """CE velocity w (rad/s) of one implicit (diagonally implicit Runge-Kutta) stage.

    The stage state is θ_cc = θ_cc,known + sign·γh·w (sign d: +1 flexor, −1 extensor, whose CE
    angle moves against its shortening velocity) and its SE stretch s = s_known + γh·w; w must
    satisfy the CE equation of docs/model.md §2.5 at that state:

        G(w) = max(a, 0.01)·T_θ(θ_cc)·h(w) − β·w − k·max(s, 0) = 0,    w ∈ [−ω_max, ω_max]

    (β = ``ce_damping``, 0 in the abstract's model).

    G(ω_max) ≤ 0 always; if G(−ω_max) ≤ 0 the eccentric clamp holds and w = −ω_max, as in the
    explicit equation. Otherwise G has one root (h decreasing, the SE term non-increasing),
    found by Newton's method from ``guess``, safeguarded by bisection on the bracket
    [−ω_max, ω_max]; a Newton step that would cross the kink of T_ω at w = 0 is stopped at
    w = 0, so every later step stays on one smooth branch. G(−ω_max) is evaluated only when
    the iteration would leave the bracket below (or close on its lower end): away from the
    clamp an iterate with G > 0 proves the root above −ω_max, and the iterates are those of
    checking the clamp first, one residual evaluation fewer. The iteration stops once an update
    is below 1e-12·(1 + |w|) rad/s, or moves the stage state θ_cc by at most
    ``state_tolerance`` (rad; 0, the default, iterates to round-off) while being below
    `QUADRATIC_REGIME`·ω_max: there Newton's convergence is quadratic, so the update returned
    is far more accurate than the tolerance. Returns (w, residual evaluations).
    """
    wmax = p[o + OMEGA_MAX]
    cap_a = max(activation, ACTIVATION_FLOOR)
    evaluations = 0
    lower_checked = False  # G(−ω_max) > 0 shown (the clamp does not hold)
    lo, hi = -wmax, wmax
    w = min(max(guess, -wmax), wmax)
    for _ in range(100):
        g, slope = _implicit_residual(w, stretch_known, theta_cc_known, sign, gamma_h, cap_a, p, o)
        evaluations += 1
        if g == 0.0:
            return w, evaluations
        if g > 0.0:
            lo = w
            lower_checked = True
        else:
            hi = w
        w_new = w - g / slope if slope < 0.0 else 0.5 * (lo + hi)
        closed = hi - lo <= 1e-14 * (1.0 + abs(w))
        if not lower_checked and (closed or not (lo < w_new < hi)):
            g_low, _ = _implicit_residual(-wmax, stretch_known, theta_cc_known, sign, gamma_h,
                                          cap_a, p, o)
            evaluations += 1
            if g_low <= 0.0:
                return -wmax, evaluations
            lower_checked = True
        if closed:
            return w, evaluations
        if not (lo < w_new < hi):
            w_new = 0.5 * (lo + hi)
        if (w_new > 0.0) != (w > 0.0) and w != 0.0 and lo < 0.0 < hi:
            w = 0.0  # evaluate at the kink next: it splits the bracket into smooth branches
            continue
        if abs(w_new - w) <= max(1e-12 * (1.0 + abs(w)),
                                 min(state_tolerance / gamma_h, QUADRATIC_REGIME * wmax)):
            return w_new, evaluations
        w = w_new
    return w, evaluations


@njit(cache=True, error_model="numpy", inline="always")
def unit_implicit_stage(psi, stage, i, excitation, gamma_h, guess, units, u, dynamics,
                        state_tolerance, rates):
    """The implicit stage of unit u, whose known stage states start at stage[i] (the step's
    states plus the earlier stages' part), at unit angle ``psi`` and profile value
    ``excitation``: its stage rates into rates[i:], as `unit_rates` gives explicit ones.
    With activation dynamics the stage activation first, in closed form
    (`implicit_activation`: it does not depend on θ_cc), then the CE velocity at it
    (`unit_implicit_ce_velocity`, seeded with ``guess``, its Newton tolerance
    ``state_tolerance``). ``dynamics`` as for `unit_rates`. Returns (w, residual
    evaluations)."""
    o = u * UNIT_ROW_SIZE
    level = excitation
    if dynamics is not None:
        if has_activation_state(units, u):
            stage_a = implicit_activation(stage[i + 1], excitation, gamma_h,
                                          units[o + UNIT_ACTIVATION_TIME],
                                          units[o + UNIT_DEACTIVATION_TIME])
            rates[i + 1] = (stage_a - stage[i + 1]) / gamma_h
            level = stage_a
    d = units[o + UNIT_DIRECTION]
    w, count = unit_implicit_ce_velocity(d * (stage[i] - psi), stage[i], d, gamma_h, level,
                                         units, guess, o, state_tolerance)
    rates[i] = d * w
    return w, count
