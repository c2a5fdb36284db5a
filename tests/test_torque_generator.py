"""Torque/velocity, differential activation, torque/angle and the CE inversion."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import torquesim as ts
from torquesim.model import torque_generator as tg
from torquesim.model.unit_row import UNIT_DIRECTION, UNIT_ROW_SIZE
from torquesim.solvers.rates import unit_rates
from torquesim.solvers.sdirk import unit_implicit_ce_velocity

FLEXOR = ts.TorqueGeneratorUnit.flexor_default()
PF = FLEXOR.to_array()
PE = ts.TorqueGeneratorUnit.extensor_default().to_array()


def test_derived_constants_match_model_md():
    assert PF[tg.T_C] == pytest.approx(22.916667, abs=1e-6)
    assert PF[tg.C_CONC] == pytest.approx(538.541667, abs=1e-6)
    assert PF[tg.OMEGA_E] == pytest.approx(0.342900, abs=1e-6)
    assert PF[tg.E_ECC] == pytest.approx(-9.001113, abs=1e-6)


@pytest.mark.parametrize("omega, expected", [(0, 71.25), (1, 59.2214), (-1, 86.2196),
                                             (5, 28.3729)])
def test_h_table_of_model_md(omega, expected):
    assert tg.ce_torque_velocity(float(omega), PF) == pytest.approx(expected, abs=5e-5)


@pytest.mark.parametrize("p", [PF, PE])
def test_tetanic_curve_limits_and_kink(p):
    t0, eps = p[tg.T0], 1e-7
    assert tg.tetanic_torque_velocity(0.0, p) == pytest.approx(t0, rel=1e-15)
    # continuous at 0
    assert tg.tetanic_torque_velocity(-1e-12, p) == pytest.approx(t0, rel=1e-10)
    # slope jumps by the eccentric slope ratio 4.3
    right = (tg.tetanic_torque_velocity(eps, p) - t0) / eps
    left = (t0 - tg.tetanic_torque_velocity(-eps, p)) / eps
    assert left / right == pytest.approx(4.3, rel=1e-5)
    # zero at ω_max and beyond; eccentric plateau T_max far out
    assert tg.tetanic_torque_velocity(p[tg.OMEGA_MAX], p) == 0.0
    assert tg.tetanic_torque_velocity(p[tg.OMEGA_MAX] * (1 - 1e-12), p) == pytest.approx(
        0.0, abs=1e-9)
    assert tg.tetanic_torque_velocity(-1e9, p) == pytest.approx(p[tg.T_MAX], rel=1e-9)


@pytest.mark.parametrize("p", [PF, PE])
def test_h_strictly_decreasing_and_slope_consistent(p):
    w = np.linspace(-p[tg.OMEGA_MAX], p[tg.OMEGA_MAX], 20001)
    h = np.array([tg.ce_torque_velocity(x, p) for x in w])
    assert np.all(np.diff(h) < 0)
    for x in (-7.3, -0.2, 0.3, 4.0, 12.0):
        numeric = (tg.ce_torque_velocity(x + 1e-6, p) - tg.ce_torque_velocity(x - 1e-6, p)) / 2e-6
        assert tg.ce_torque_velocity_slope(x, p) == pytest.approx(numeric, rel=1e-6)


def test_differential_activation_limits():
    assert tg.differential_activation(-1e3, PF) == pytest.approx(0.9)
    assert tg.differential_activation(1e3, PF) == pytest.approx(1.0)
    assert tg.differential_activation(0.0, PF) == pytest.approx(0.95)


def test_torque_angle_peak_and_floor():
    assert tg.torque_angle(1.66, PF) == 1.0
    assert tg.torque_angle(1.66 + 0.5, PF) == pytest.approx(1 - 0.23 * 0.25)
    assert tg.torque_angle(1.66 + 10.0, PF) == 0.01
    assert tg.torque_angle(1.66 - 10.0, PF) == 0.01


@settings(max_examples=400, deadline=None)
@given(fraction=st.floats(1e-9, 1 - 1e-12), unit=st.sampled_from([0, 1]))
def test_inversion_round_trip(fraction, unit):
    p = (PF, PE)[unit]
    target = fraction * p[tg.H_ECC_LIMIT]
    w = tg.ce_velocity(target, p)
    assert -p[tg.OMEGA_MAX] <= w <= p[tg.OMEGA_MAX]
    assert tg.ce_torque_velocity(w, p) == pytest.approx(target, rel=1e-12, abs=1e-12)


@settings(max_examples=400, deadline=None)
@given(fraction=st.floats(1e-9, 1 - 1e-12), unit=st.sampled_from([0, 1]),
       guess=st.one_of(st.floats(-30.0, 30.0), st.just(math.nan)))
def test_inversion_root_does_not_depend_on_the_guess(fraction, unit, guess):
    """The solvers seed the CE root finder with their previous CE velocity: any seed, on
    either branch, outside [−ω_max, ω_max] or none, gives the same root, to 1e-13 or to the
    root's own conditioning (a round-off in h moves the root by eps·|target|/|h'|, large
    next to the eccentric limit where h flattens: found by hypothesis at 1 − 1e-12)."""
    p = (PF, PE)[unit]
    target = fraction * p[tg.H_ECC_LIMIT]
    w = tg.ce_velocity(target, p, guess)
    unseeded, slope = tg.ce_velocity_and_slope(target, p, math.nan, 0.0)
    conditioning = 8 * np.finfo(float).eps * abs(target) / abs(slope)
    assert w == pytest.approx(unseeded, rel=1e-13, abs=1e-13 + conditioning)
    assert tg.ce_torque_velocity(w, p) == pytest.approx(target, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("p", [PF, PE])
def test_inversion_clamps(p):
    wmax = p[tg.OMEGA_MAX]
    assert tg.ce_velocity(0.0, p) == wmax
    assert tg.ce_velocity(-3.0, p) == wmax
    assert tg.ce_velocity(p[tg.H_ECC_LIMIT], p) == -wmax
    assert tg.ce_velocity(10 * p[tg.T_MAX], p) == -wmax
    assert tg.ce_velocity(p[tg.H_ISOMETRIC], p) == 0.0
    # continuity across the kink
    assert abs(tg.ce_velocity(p[tg.H_ISOMETRIC] * (1 + 1e-12), p)) < 1e-9
    assert abs(tg.ce_velocity(p[tg.H_ISOMETRIC] * (1 - 1e-12), p)) < 1e-9


def test_unit_torque_cannot_push():
    assert tg.unit_torque(-0.1, PF) == 0.0
    assert tg.unit_torque(0.01, PF) == pytest.approx(6.0)
    # slack SE: the CE shortens at its fastest
    assert tg.unit_ce_velocity(-0.01, 1.0, 0.5, PF) == PF[tg.OMEGA_MAX]


PF_DAMPED = FLEXOR.__class__(**{**FLEXOR.as_dict(), "ce_damping": 0.4}).to_array()


@pytest.mark.parametrize("p", [PF, PF_DAMPED], ids=["abstract", "damped"])
@pytest.mark.parametrize("omega", [-3.0, -0.1, 0.5, 6.0])
def test_time_constant_is_the_linearised_rate(omega, p):
    """τ = (a·T_θ·|h'| + β)/k equals −1/(∂ω_cc/∂θ_cc) at θ_cc = θ_opt (where T_θ' = 0)."""
    a, theta_cc = 0.3, p[tg.THETA_OPT]
    stretch = (a * tg.ce_torque_velocity(omega, p) - p[tg.CE_DAMPING] * omega) / p[tg.K_SE]
    theta = theta_cc - stretch
    assert tg.unit_ce_velocity(stretch, theta_cc, a, p) == pytest.approx(omega, abs=1e-9)
    eps = 1e-8
    d = (tg.unit_ce_velocity(theta_cc + eps - theta, theta_cc + eps, a, p)
         - tg.unit_ce_velocity(theta_cc - eps - theta, theta_cc - eps, a, p)) / (2 * eps)
    tau = tg.unit_time_constant(omega, theta_cc, a, p)
    assert -1.0 / d == pytest.approx(tau, rel=1e-5)
    assert tau >= p[tg.CE_DAMPING] / p[tg.K_SE]
    assert math.isinf(tg.unit_time_constant(p[tg.OMEGA_MAX], theta_cc, a, p))


@settings(max_examples=300, deadline=None)
@given(stretch=st.floats(-0.02, 0.3), theta_cc=st.floats(-0.5, 3.0), a=st.floats(0.0, 1.0),
       unit=st.sampled_from([0, 1, 2]), guess=st.one_of(st.floats(-20.0, 20.0),
                                                         st.just(math.nan)))
def test_guard_time_constant_from_the_root_finder_is_the_closed_form(stretch, theta_cc, a,
                                                                     unit, guess):
    """The stability guard takes τ from the slope the root finder ends with (`unit_rates`,
    the loops' unit rates): it must be the closed-form τ at the returned CE velocity (inf
    where the velocity is clamped)."""
    p = (PF, PE, PF_DAMPED)[unit]
    row = np.zeros(UNIT_ROW_SIZE)  # a flexor on joint 0, θ_cc at y[2], no dynamics
    row[:p.shape[0]] = p
    row[UNIT_DIRECTION] = 1.0
    y = np.array([0.0, 0.0, theta_cc])
    psi = theta_cc - stretch
    stretch = theta_cc - psi  # the stretch unit_rates sees (d = 1), rounded as it is
    rates = np.empty(3)
    w, tau = unit_rates(psi, y, 2, a, guess, row, 0, None, rates)
    rate = rates[2]
    assert rate == w
    assert w == pytest.approx(tg.unit_ce_velocity(stretch, theta_cc, a, p), rel=1e-12,
                              abs=1e-12)
    if abs(w) == p[tg.OMEGA_MAX] and math.isfinite(tau):
        return  # a root that rounds to ±ω_max: the closed form calls it clamped (τ = inf)
    expected = tg.unit_time_constant(w, theta_cc, a, p)
    if math.isinf(expected):
        assert math.isinf(tau)
    else:
        assert tau == pytest.approx(expected, rel=1e-5)


def test_ce_damping_makes_a_slack_unit_shorten_at_a_finite_speed():
    """With β > 0 a slack SE no longer sends the CE to ω_max: a·T_θ·h(ω) = β·ω instead."""
    w = tg.unit_ce_velocity(-0.01, 1.0, 0.5, PF_DAMPED)
    assert 0.0 < w < PF_DAMPED[tg.OMEGA_MAX]
    cap = 0.5 * tg.torque_angle(1.0, PF_DAMPED)
    assert cap * tg.ce_torque_velocity(w, PF_DAMPED) == pytest.approx(0.4 * w, rel=1e-9)


def test_non_monotone_h_is_rejected():
    with pytest.raises(ts.ModelError, match="not strictly decreasing"):
        FLEXOR.__class__(**{**FLEXOR.as_dict(), "min_differential_activation": 0.0,
                            "differential_activation_rate": 0.05})


@pytest.mark.parametrize("field, value", [
    ("isometric_torque", 0.0), ("isometric_torque", -1.0), ("eccentric_torque_max", 70.0),
    ("max_velocity", 0.0), ("velocity_constant", -1.0), ("min_differential_activation", 1.5),
    ("differential_activation_rate", 0.0), ("differential_activation_midpoint", 30.0),
    ("angle_curvature", -0.1), ("se_stiffness", 0.0), ("se_stiffness", math.nan),
    ("se_stiffness", math.inf), ("optimal_angle", 10.0)])
def test_bad_unit_parameters_name_the_field(field, value):
    with pytest.raises(ts.ModelError) as info:
        FLEXOR.__class__(**{**FLEXOR.as_dict(), field: value})
    assert info.value.field == field
    assert "allowed" in str(info.value)


@settings(max_examples=300, deadline=None)
@given(stretch=st.floats(-0.05, 0.6), theta_cc=st.floats(-0.5, 2.5), a=st.floats(0.0, 1.0),
       gamma_h=st.floats(1e-6, 0.02), sign=st.sampled_from([1.0, -1.0]),
       guess=st.floats(-30.0, 30.0), flexor=st.booleans())
def test_implicit_stage_solves_the_ce_equation_at_its_own_state(stretch, theta_cc, a, gamma_h,
                                                                 sign, guess, flexor):
    """w from the implicit stage solve is the explicit CE velocity at the stage state
    θ_cc + sign·γh·w, stretch + γh·w (clamps included), whatever the Newton guess."""
    p = PF if flexor else PE
    w, evaluations = unit_implicit_ce_velocity(stretch, theta_cc, sign, gamma_h, a, p, guess)
    assert -p[tg.OMEGA_MAX] <= w <= p[tg.OMEGA_MAX] and evaluations < 60
    explicit = tg.unit_ce_velocity(stretch + gamma_h * w, theta_cc + sign * gamma_h * w, a, p)
    # compare in torque units: the CE equation's residual, relative to the isometric torque
    cap = max(a, tg.ACTIVATION_FLOOR) * tg.torque_angle(theta_cc + sign * gamma_h * w, p)
    if abs(w) < p[tg.OMEGA_MAX]:
        assert cap * tg.ce_torque_velocity(w, p) == pytest.approx(
            p[tg.K_SE] * max(stretch + gamma_h * w, 0.0), abs=1e-9 * p[tg.T0])
    else:
        assert explicit == pytest.approx(w, abs=1e-6)


def _clamp_first_solve(stretch, theta_cc, sign, gamma_h, a, p, guess):
    """The implicit stage solve as it was written before: G(−ω_max) checked first, then the
    same safeguarded Newton iteration (a transcription, for the test below)."""
    from torquesim.solvers.sdirk import _implicit_residual

    wmax = p[tg.OMEGA_MAX]
    cap = max(a, tg.ACTIVATION_FLOOR)
    if _implicit_residual(-wmax, stretch, theta_cc, sign, gamma_h, cap, p)[0] <= 0.0:
        return -wmax, 1
    evaluations, lo, hi = 1, -wmax, wmax
    w = min(max(guess, -wmax), wmax)
    for _ in range(100):
        g, slope = _implicit_residual(w, stretch, theta_cc, sign, gamma_h, cap, p)
        evaluations += 1
        if g == 0.0:
            return w, evaluations
        lo, hi = (w, hi) if g > 0.0 else (lo, w)
        if hi - lo <= 1e-14 * (1.0 + abs(w)):
            return w, evaluations
        w_new = w - g / slope if slope < 0.0 else 0.5 * (lo + hi)
        if not (lo < w_new < hi):
            w_new = 0.5 * (lo + hi)
        if (w_new > 0.0) != (w > 0.0) and w != 0.0 and lo < 0.0 < hi:
            w = 0.0
            continue
        if abs(w_new - w) <= 1e-12 * (1.0 + abs(w)):
            return w_new, evaluations
        w = w_new
    return w, evaluations


@settings(max_examples=300, deadline=None)
@given(stretch=st.floats(-0.05, 0.6), theta_cc=st.floats(-0.5, 2.5), a=st.floats(0.0, 1.0),
       gamma_h=st.floats(1e-6, 0.02), sign=st.sampled_from([1.0, -1.0]),
       guess=st.floats(-30.0, 30.0), flexor=st.booleans())
def test_the_clamp_checked_on_demand_gives_the_same_velocity_with_fewer_evaluations(
        stretch, theta_cc, a, gamma_h, sign, guess, flexor):
    """Checking the eccentric clamp only where the iteration needs it leaves every iterate
    as it was: the same w to the last bit. Away from the clamp it never costs more (one
    residual evaluation fewer unless a Newton step left the bracket below, where the check
    is made as before); at the clamp, −ω_max itself, after the few Newton steps taken
    before the iteration leaves the bracket (at most 4 more evaluations in 20 000 random
    draws of these ranges, nearly always 1)."""
    p = PF if flexor else PE
    w, evaluations = unit_implicit_ce_velocity(stretch, theta_cc, sign, gamma_h, a, p, guess)
    w_before, evaluations_before = _clamp_first_solve(stretch, theta_cc, sign, gamma_h, a, p,
                                                      guess)
    assert w == w_before
    if w == -p[tg.OMEGA_MAX]:
        assert evaluations <= evaluations_before + 5
    else:
        assert evaluations <= evaluations_before


@settings(max_examples=300, deadline=None)
@given(stretch=st.floats(-0.05, 0.6), theta_cc=st.floats(-0.5, 2.5), a=st.floats(0.0, 1.0),
       gamma_h=st.floats(1e-6, 0.02), sign=st.sampled_from([1.0, -1.0]),
       guess=st.floats(-30.0, 30.0), flexor=st.booleans(),
       tolerance=st.sampled_from([1e-3, 1e-5, 1e-7]))
def test_a_state_tolerance_stops_early_within_it(stretch, theta_cc, a, gamma_h, sign, guess,
                                                 flexor, tolerance):
    """With a tolerance on the stage state (the error-controlled loop's 0.1·atol) the solve
    stops once an update moves θ_cc by at most that: its stage state is then within the
    tolerance of the solve to round-off's (Newton's quadratic convergence makes it far
    closer), in at most as many residual evaluations."""
    p = PF if flexor else PE
    exact, evaluations = unit_implicit_ce_velocity(stretch, theta_cc, sign, gamma_h, a, p,
                                                   guess)
    w, early = unit_implicit_ce_velocity(stretch, theta_cc, sign, gamma_h, a, p, guess, 0,
                                         tolerance)
    assert early <= evaluations
    assert gamma_h * abs(w - exact) <= tolerance


def test_a_state_tolerance_saves_iterations_from_a_close_guess():
    """From a guess 1e-3 rad/s off the root (the error-controlled loop's seeds are of this
    kind), a tolerance of 1e-6 rad at γh = 0.3 ms takes one residual evaluation and lands
    within 1e-10 rad of the root's stage state; to round-off takes 3."""
    gamma_h = 0.3e-3
    exact, _ = unit_implicit_ce_velocity(0.05, 1.0, 1.0, gamma_h, 0.6, PF, 0.0)
    assert 0.0 < exact < PF[tg.OMEGA_MAX]  # a root inside the bracket, not a clamp
    guess = exact + 1e-3
    _, evaluations = unit_implicit_ce_velocity(0.05, 1.0, 1.0, gamma_h, 0.6, PF, guess)
    w, early = unit_implicit_ce_velocity(0.05, 1.0, 1.0, gamma_h, 0.6, PF, guess, 0, 1e-6)
    assert (early, evaluations) == (1, 3)
    assert gamma_h * abs(w - exact) < 1e-10


def test_implicit_stage_tends_to_the_explicit_velocity_for_a_tiny_step():
    for stretch in (0.0005, 0.05, 0.2, 0.4):
        explicit = tg.unit_ce_velocity(stretch, 0.3, 0.3, PF)
        implicit, _ = unit_implicit_ce_velocity(stretch, 0.3, 1.0, 1e-12, 0.3, PF, 0.0)
        assert implicit == pytest.approx(explicit, rel=1e-7, abs=1e-9)


@pytest.mark.parametrize("theta_cc", [-2.0, 0.5, 1.66, 2.4, 4.0])
def test_torque_angle_slope_is_its_derivative(theta_cc):
    eps = 1e-7
    numeric = (tg.torque_angle(theta_cc + eps, PF)
               - tg.torque_angle(theta_cc - eps, PF)) / (2 * eps)
    assert tg.torque_angle_slope(theta_cc, PF) == pytest.approx(numeric, abs=1e-6)
