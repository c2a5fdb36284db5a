"""Solvers: golden trajectory, agreement with the reference, physics, order, guard."""

import math

import numpy as np
import pytest

import torquesim as ts

from .conftest import ce_power, chain_energy, max_angle_error

# MODEL.md §3: converged default curl, θ (deg) at t = 0, 0.5, ..., 3.0 s.
GOLDEN_DEG = [10.0000, 37.5343, 105.9319, 137.8826, 109.2625, 38.6858, 11.8909]


def test_reference_reproduces_model_md(reference):
    got = np.degrees(reference.theta[::500])
    assert got == pytest.approx(GOLDEN_DEG, abs=1e-4)
    peak, t_peak = reference.peak()
    assert math.degrees(peak) == pytest.approx(138.74, abs=0.01)
    assert t_peak == pytest.approx(1.42, abs=0.01)


def test_monolithic_default_reproduces_model_md(model):
    result = ts.simulate(model)
    assert np.degrees(result.theta[::5000]) == pytest.approx(GOLDEN_DEG, abs=1e-4)
    assert result.cost.steps == 30000
    assert result.cost.rhs_body == result.cost.rhs_muscle == 4 * 30000
    assert not result.stability.exceeded


def test_monolithic_agrees_with_reference(model, reference):
    result = ts.simulate(model, "monolithic", 5e-5)
    assert max_angle_error(result, reference) < 1e-7


def test_partitioned_is_first_order_accurate_and_wrong_by_model_md_amount(model, reference):
    e1 = max_angle_error(ts.simulate(model, "partitioned", 1e-4), reference)
    e2 = max_angle_error(ts.simulate(model, "partitioned", 5e-5), reference)
    assert 0.10 < e1 < 0.18  # MODEL.md §5: about 0.14 rad
    assert 0.05 < e2 < 0.10  # about 0.075 rad
    assert 1.6 < e1 / e2 < 2.4  # first order


@pytest.mark.parametrize("method", ["monolithic", "partitioned", "reference"])
def test_static_equilibrium_stays_put(method):
    """Held in equilibrium, nothing moves (to 1e-9). Radau rests on the force-velocity
    relation's kink at ω_cc = 0 and chatters there (12 891 steps, 21 s for 1 s of rest), so
    the reference is held for 0.2 s."""
    m = ts.default_model().replace(flexor_activation=ts.ActivationProfile(None),
                                   extensor_activation=ts.ActivationProfile(0.1),
                                   initial_angle=math.radians(70),
                                   duration=0.2 if method == "reference" else 1.0)
    result = ts.simulate(m, method, 1e-4)
    assert np.max(np.abs(result.states - result.states[0])) < 1e-9


def test_energy_balance_on_the_default_curl(model):
    """d/dt(total energy) = CE power T_F·ω_F + T_E·ω_E (the only non-conservative work)."""
    result = ts.simulate(model, "monolithic", 5e-5)
    energy = chain_energy(result)
    power = ce_power(result)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1])
                                            * np.diff(result.time))])
    swing = np.ptp(energy)
    assert swing > 10.0  # the curl lifts the dumbbell: the check is not vacuous
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-4 * swing


def test_passive_swing_is_a_damped_pendulum():
    """Activations at the floor, compliant SEs, no end stops: a lightly damped pendulum."""
    weak = ts.TorqueGeneratorUnit.flexor_default()
    weak = weak.__class__(**{**weak.as_dict(), "se_stiffness": 2.0})
    m = ts.default_model().replace(
        body=ts.BodyParameters(endstop_torque=0.0), flexor=weak,
        extensor=weak, flexor_activation=ts.ActivationProfile(0.0),
        extensor_activation=ts.ActivationProfile(0.0), duration=6.0)
    amplitude = 0.3
    y0 = [amplitude, 0.0, amplitude, amplitude]
    result = ts.simulate(m, "monolithic", 1e-4, initial_state=y0)
    theta, t = result.theta, result.time
    peaks = [i for i in range(1, len(theta) - 1) if theta[i - 1] < theta[i] >= theta[i + 1]]
    assert len(peaks) >= 3
    period = np.mean(np.diff(t[peaks]))
    small = 2 * np.pi * math.sqrt(m.body.elbow_inertia / m.body.gravity_torque_coefficient)
    assert period == pytest.approx(small * (1 + amplitude**2 / 16), rel=0.03)
    heights = theta[peaks]
    assert np.all(np.diff(heights) < 0)  # damped
    assert heights[-1] > 0.2 * amplitude  # lightly
    assert chain_energy(result)[-1] < chain_energy(result)[0]


def test_every_stage_exchange_runs_monolithic_rk4_with_its_guard_at_the_whole_step(model):
    """Exchanging at every stage is monolithic RK4 (docs/model.md §4): the same loop, so the
    same states and work, bit for bit. Muscle sub-steps do not apply to it, so its stability
    guard measures the whole step: before, with muscle_substeps=4 it reported a quarter of
    the step/τ the run really had (0.79 at 1 ms, where monolithic's 3.17 is beyond the limit;
    only the step-halving accuracy check warned)."""
    for step in (2e-4, 1e-3):
        mono = ts.simulate(model, "monolithic", step)
        stage = ts.simulate(model, "partitioned", step,
                            coupling=ts.Coupling(order="every-stage", muscle_substeps=4))
        assert np.array_equal(mono.states, stage.states)
        assert (stage.cost.rhs_body, stage.cost.rhs_muscle) == \
            (mono.cost.rhs_body, mono.cost.rhs_muscle)
        assert stage.stability.max_step_ratio == mono.stability.max_step_ratio
        assert stage.stability.exceeded == mono.stability.exceeded == (step == 1e-3)


def test_stability_guard_flags_large_steps(model, reference):
    bad = ts.simulate(model, "monolithic", 1e-3)
    assert bad.stability.exceeded
    assert max_angle_error(bad, reference) > 0.05  # it really is wrong
    assert "stability limit" in bad.message
    assert bad.stability.largest_safe_step <= 0.5e-3
    good = ts.simulate(model, "monolithic", 2.5e-4)
    assert not good.stability.exceeded
    assert max_angle_error(good, reference) < 1e-6
    # the guard's τ agrees with the time constants along the motion
    taus = good.time_constants()
    assert good.stability.max_step_ratio == pytest.approx(
        2.5e-4 / min(tau.min() for tau in taus.values()), rel=0.05)


def test_blow_up_is_reported_with_time_and_advice(model):
    with pytest.raises(ts.SimulationError, match=r"t = .* use a step ≤"):
        ts.simulate(model, "monolithic", 0.1)
    failed = ts.simulate(model, "monolithic", 0.1, check=False)
    assert failed.status == "failed" and failed.time[-1] < model.duration


@pytest.mark.parametrize("step", [7e-4, 0.0, -1e-4, 5.0, math.nan])
def test_step_must_divide_duration(model, step):
    with pytest.raises(ts.ModelError) as info:
        ts.simulate(model, "monolithic", step)
    assert info.value.field == "step"


def test_unknown_method(model):
    with pytest.raises(ts.ModelError, match="method"):
        ts.simulate(model, "euler")


def test_adaptive_cost_counts_every_call(model):
    r = ts.simulate(model, "scipy:RK45", rtol=1e-6, atol=1e-9, tolerance=None)
    assert r.cost.steps > 0 and r.cost.rhs_body >= 6 * r.cost.steps


def test_imex_is_stable_and_accurate_where_explicit_rk4_fails(model, reference):
    """Implicit muscles remove the stiff limit: at 5 ms (step/τ ≈ 30) IMEX is within 0.5° of
    the reference while monolithic RK4 is off by tens of degrees; at 1 ms within 1e-4 rad."""
    coarse = ts.simulate(model, "imex", 5e-3)
    assert coarse.stability.max_step_ratio > 10 and not coarse.stability.exceeded
    assert max_angle_error(coarse, reference) < math.radians(0.5)
    assert max_angle_error(ts.simulate(model, "monolithic", 5e-3, check=False),
                           reference) > math.radians(10)
    assert max_angle_error(ts.simulate(model, "imex", 1e-3), reference) < 1e-4


def test_imex_keeps_the_static_equilibrium():
    m = ts.default_model().replace(flexor_activation=ts.ActivationProfile(None),
                                   extensor_activation=ts.ActivationProfile(0.1),
                                   initial_angle=math.radians(70), duration=1.0)
    result = ts.simulate(m, "imex", 5e-3)
    assert np.max(np.abs(result.states - result.states[0])) < 1e-9


def test_imex_needs_an_implicit_muscle_solver(model):
    with pytest.raises(ts.ModelError, match="muscle_solver"):
        ts.simulate(model, "imex", 1e-3, coupling=ts.Coupling())


def test_ce_damping_bounds_the_stiffness_so_rk4_is_stable_at_1ms():
    """Millard et al. (2013) remedy: with β = 0.3 N·m·s/rad (τ ≥ β/k) monolithic RK4 at 1 ms
    stays within the guard and agrees with the reference; without it, it is wrong by ~1 rad."""
    from dataclasses import replace

    m = ts.default_model()
    damped = m.replace(flexor=replace(m.flexor, ce_damping=0.3),
                       extensor=replace(m.extensor, ce_damping=0.3))
    ref = ts.simulate(damped, "reference", rtol=1e-11, atol=1e-13)
    run = ts.simulate(damped, "monolithic", 1e-3)
    assert not run.stability.exceeded
    assert max_angle_error(run, ref) < 1e-6
    assert min(tau.min() for tau in ref.time_constants().values()) >= \
        0.3 / m.flexor.se_stiffness


def test_a_step_too_coarse_for_the_activation_ramps_is_reported(model):
    """IMEX is stable at any step, but a 0.1 s step cannot follow 0.3 s ramps: say so."""
    coarse = ts.simulate(model, "imex", 0.1)
    assert "activation is not resolved" in coarse.message and "≤ 30 ms" in coarse.message
    assert ts.simulate(model, "imex", 0.02).message == ""


def test_the_coupling_jump_is_the_exchange_error_and_shrinks_as_it_is_iterated():
    """The recorded jumps between what one part assumed of the other over a step and what the
    other gave: zero angle jump when the muscles see the body's new angle (body first), a
    torque jump that iterating the exchange drives towards zero."""
    model = ts.default_model().replace(duration=0.5)

    def jumps(**coupling):
        run = ts.simulate(model, "partitioned", 1e-4, coupling=ts.Coupling(**coupling),
                          tolerance=None)
        return run.settings["coupling_jump"]

    plain, iterated = jumps(), jumps(iterations=3)
    assert plain["torque_jump_integral_nms"] > 0 and plain["angle_jump_sum_rad"] > 0
    assert iterated["torque_jump_integral_nms"] < 1e-2 * plain["torque_jump_integral_nms"]
    assert jumps(order="body-first")["angle_jump_sum_rad"] == 0.0
    assert 0 < plain["largest_at_s"] <= 0.5
