"""A unit kind with a state of its own: Hill units with first-order activation dynamics
(Thelen 2003). The law, its implicit stage and time constant are checked against their
definitions; runs against an independent integration of the activation ODE, against Radau,
in the limit of instant dynamics, and through the stability guard and the model file. The
measured order of every technique on a model with these units is in test_techniques.py."""

import dataclasses
import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

import torquesim as ts
from torquesim.io.model_file import model_from_dict, model_to_toml
from torquesim.model.activation import (
    activation_rate,
    activation_time_constant,
    implicit_activation,
)

from .conftest import activation_dynamics_case, order_reference


def thelen_rate(e, a, t_act, t_deact):
    """Thelen 2003, eq. (1)–(2), written here from the paper: da/dt = (u − a)/τ(u, a)."""
    tau = t_act * (0.5 + 1.5 * a) if e > a else t_deact / (0.5 + 1.5 * a)
    return (e - a) / tau


def with_dynamics(model, dynamics=None, only=None):
    dynamics = dynamics or ts.ActivationDynamics()
    return model.replace(units=tuple(
        dataclasses.replace(u, activation_dynamics=dynamics)
        if only is None or u.name == only else u for u in model.units))


# Activations and excitations: subnormal numbers are no activation (e − a would underflow the
# rate to zero, which the sign test below would misread)
unit_interval = st.floats(0.0, 1.0, allow_subnormal=False)
times = st.floats(1e-3, 0.2)


@given(unit_interval, unit_interval, times, times)
def test_rate_is_thelens_law(e, a, t_act, t_deact):
    rate = activation_rate(e, a, t_act, t_deact)
    assert rate == pytest.approx(thelen_rate(e, a, t_act, t_deact), rel=1e-12, abs=1e-12)
    assert np.sign(rate) == np.sign(e - a)  # towards the excitation, at rest where a = e


@given(unit_interval, unit_interval, times, times)
def test_time_constant_is_the_inverse_slope_of_the_rate(e, a, t_act, t_deact):
    d = 1e-7
    if abs(e - a) < 1e-5 or not 1e-5 < a < 1 - 1e-5:
        return  # the rate has a kink at a = e
    slope = (activation_rate(e, a + d, t_act, t_deact)
             - activation_rate(e, a - d, t_act, t_deact)) / (2 * d)
    assert activation_time_constant(e, a, t_act, t_deact) == pytest.approx(1 / abs(slope),
                                                                            rel=1e-5)


@settings(max_examples=300)
@given(unit_interval, unit_interval, st.floats(1e-6, 0.5), times, times)
def test_implicit_stage_solves_its_equation(known, e, gamma_h, t_act, t_deact):
    a = implicit_activation(known, e, gamma_h, t_act, t_deact)
    residual = a - known - gamma_h * thelen_rate(e, a, t_act, t_deact)
    assert abs(residual) <= 1e-12 * (1 + abs(known) + gamma_h / min(t_act, t_deact))
    assert min(known, e) - 1e-12 <= a <= max(known, e) + 1e-12  # between start and target


def test_activation_follows_an_independent_solution_of_its_ode():
    """On the default curl with dynamics on both units, each activation state equals the
    Thelen ODE driven by that unit's profile, integrated separately by SciPy."""
    model = with_dynamics(ts.default_model().to_chain())
    run = ts.simulate(model, "monolithic", 1e-4)
    start = model.initial_state()
    cols = run.columns()
    assert np.ptp(cols["activation_state_elbow_flexor"]) > 0.1  # the curl's ramps move it
    for u, unit in enumerate(model.units):
        dyn = unit.activation_dynamics

        def rhs(t, a, unit=unit, level=start.levels[u], dyn=dyn):
            e = float(unit.activation([t], level)[0])
            return [thelen_rate(e, a[0], dyn.activation_time, dyn.deactivation_time)]

        ode = solve_ivp(rhs, (0, model.duration), [start.levels[u]], method="Radau",
                        rtol=1e-10, atol=1e-12, t_eval=run.time[::100], max_step=1e-3)
        state = cols[f"activation_state_{unit.name}"][::100]
        assert np.max(np.abs(state - ode.y[0])) < 1e-7
        np.testing.assert_allclose(cols[f"activation_{unit.name}"],
                                   np.maximum(cols[f"activation_state_{unit.name}"], 0.01))
        np.testing.assert_allclose(cols[f"excitation_{unit.name}"],
                                   unit.activation(run.time, start.levels[u]))


@pytest.mark.parametrize("extensor_dynamics", [True, False], ids=["both", "mixed kinds"])
def test_fixed_step_techniques_agree_with_radau(extensor_dynamics):
    model, y0 = activation_dynamics_case(extensor_dynamics)
    ref = order_reference(model, y0)
    for method, h, tol in (("monolithic", 2.5e-4, 1e-9), ("imex", 2.5e-4, 1e-6)):
        run = ts.simulate(model, method, h, initial_state=y0)
        assert np.max(np.abs(run.q[::40] - ref.q)) < tol, method
        assert np.max(np.abs(run.states[::40] - ref.states)) < 100 * tol, method


def test_instant_dynamics_recover_the_model_without():
    """As τ_act, τ_deact → 0 the activation follows the excitation and the motion tends to
    that of the plain model, the gap shrinking in proportion to τ."""
    plain = ts.default_model().to_chain()
    base = ts.simulate(plain, "imex", 1e-4)
    gaps = []
    for tau in (1e-3, 1e-4):
        fast = with_dynamics(plain, ts.ActivationDynamics(tau, tau))
        gaps.append(np.max(np.abs(ts.simulate(fast, "imex", 1e-4).q - base.q)))
    assert gaps[1] < 0.02
    assert 5 < gaps[0] / gaps[1] < 20, gaps


def test_stability_guard_sees_the_activation_time_constant():
    model, y0 = activation_dynamics_case()
    quick = with_dynamics(model, ts.ActivationDynamics(2e-4, 2e-4))
    plain = ts.simulate(model, "monolithic", 2e-3, initial_state=y0)
    assert not plain.stability.exceeded
    fast = ts.simulate(quick, "monolithic", 2e-3, initial_state=y0, check=False)
    assert fast.stability.exceeded
    assert fast.stability.max_step_ratio == pytest.approx(
        2e-3 / (2e-4 / (0.5 + 1.5 * 0.65 + 1.5 * 0.05)), rel=0.05)  # the flexor at t = 0
    assert ts.simulate(quick, "imex", 2e-3, initial_state=y0).success  # implicit: no limit


def test_model_file_round_trip_and_bad_values():
    model = with_dynamics(ts.default_model().to_chain(), ts.ActivationDynamics(0.01, 0.04),
                          only="elbow_flexor")
    text = model_to_toml(model)
    assert "[units.activation_dynamics]" in text
    assert model_from_dict(tomllib.loads(text)) == model
    assert model.layout.size == 5 and model.state_names()[3] == "activation_state_elbow_flexor"
    data = tomllib.loads(text)
    data["units"][0]["activation_dynamics"]["activation_time"] = 0.0
    with pytest.raises(ts.ModelError, match=r"units\[0\]\.activation_dynamics\.activation_time"
                       r".*\(0, 1\]"):
        model_from_dict(data)
    data["units"][0]["activation_dynamics"] = {"tau": 0.01}
    with pytest.raises(ts.ModelError, match=r"activation_dynamics\.tau.*unknown key"):
        model_from_dict(data)


def test_equilibrium_start_holds_with_dynamics():
    """At rest the activation state equals the level that holds the start, and nothing moves
    while the excitation stays there."""
    model = with_dynamics(ts.default_model().to_chain())
    still = model.replace(units=tuple(
        dataclasses.replace(u, activation=ts.ActivationProfile(u.activation.initial_level))
        for u in model.units), duration=0.2)
    start = still.initial_state()
    for u in range(still.n_units):
        assert start.state[still.layout.activation_state(u)] == start.levels[u]
    run = ts.simulate(still, "monolithic", 1e-4)
    assert np.max(np.abs(run.states - start.state)) < 1e-9
    assert math.isfinite(run.stability.max_step_ratio)


def test_time_constants_are_parameter_paths():
    from torquesim.model.paths import get_parameter, set_parameter

    model = with_dynamics(ts.default_model().to_chain(), only="elbow_flexor")
    assert get_parameter(model, "flexor.activation_time") == 0.015
    changed = set_parameter(model, "elbow_flexor.deactivation_time", 0.08)
    assert changed.units[0].activation_dynamics.deactivation_time == 0.08
    with pytest.raises(ts.ModelError, match="elbow_extensor has no activation dynamics"):
        get_parameter(model, "extensor.activation_time")
    with pytest.raises(ts.ModelError, match=r"flexor\.activation_time.*invalid.*\(0, 1\]"):
        set_parameter(model, "flexor.activation_time", -1)
