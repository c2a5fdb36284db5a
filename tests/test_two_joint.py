"""Two-joint units: a unit spanning two adjacent joints acts through its row of the
moment-arm matrix (d at its joint, r at the second; docs/model.md §7), unit angle
ψ = q_j + d·r·q_j2, SE stretch s = d·(θ_cc − ψ)."""

import math
from dataclasses import replace

import numpy as np
import pytest

import torquesim as ts
from torquesim.errors import ModelError
from torquesim.io.model_file import load_model, model_to_toml

from .conftest import ce_power, chain_energy

TECHNIQUES = [("monolithic", 1e-4, None), ("imex", 1e-3, None), ("partitioned", 1e-4, None),
              ("partitioned", 1e-4, ts.Coupling(order="every-stage")),
              ("partitioned", 1e-4, ts.Coupling(order="muscles-first", predictor="linear"))]


def _arm(second_arm: float, duration: float = 0.6):
    """The arm raise with its elbow flexor spanning the shoulder too (``second_arm`` there),
    at the level the preset's equilibrium gives it, and the preset's start state."""
    arm = ts.load_model("builtin:arm-raise").replace(duration=duration)
    start = arm.initial_state()
    u = next(i for i, unit in enumerate(arm.units) if unit.joint == "elbow"
             and unit.direction == 1)
    profile = replace(arm.units[u].activation, initial_level=float(start.levels[u]))
    units = list(arm.units)
    units[u] = replace(units[u], activation=profile, second_joint="shoulder",
                       second_arm=second_arm)
    return arm, arm.replace(units=tuple(units)), start.state, u


@pytest.mark.parametrize("method, step, coupling", TECHNIQUES)
def test_a_zero_second_arm_is_the_one_joint_unit(method, step, coupling):
    """Spanning the shoulder with r = 0 changes nothing: every technique's trajectory and the
    output columns equal the one-joint unit's to 1e-12 (the kernel adds r·T = 0 and
    ψ = q_j + 0)."""
    arm, spanning, y0, _ = _arm(0.0)
    one = ts.simulate(arm, method, step, coupling=coupling, initial_state=y0, check=False)
    two = ts.simulate(spanning, method, step, coupling=coupling, initial_state=y0,
                      check=False)
    assert np.max(np.abs(one.states - two.states)) <= 1e-12
    a, b = one.columns(), two.columns()
    for name in a:
        assert np.max(np.abs(a[name] - b[name])) <= 1e-12 * max(1.0, np.max(np.abs(a[name]))), \
            name


def test_a_zero_second_arm_is_the_one_joint_unit_for_scipy():
    arm, spanning, y0, _ = _arm(0.0, duration=0.2)
    from torquesim.solvers.rates import chain_derivative

    for t, y in ((0.0, y0), (0.1, y0 + 0.01)):
        assert np.array_equal(chain_derivative(t, y, *arm.pack()),
                              chain_derivative(t, y, *spanning.pack()))


def test_joint_torques_are_the_derivative_of_the_spring_energy():
    """Independent of the kernel's placement of torques: τ_j = −∂E_SE/∂q_j with
    E_SE = ½·k·max(s, 0)² and s = d·(θ_cc − q_j − d·r·q_j2), by central differences."""
    from torquesim.solvers.rates import joint_muscle_torques

    _, spanning, y0, u = _arm(0.7)
    units = spanning.unit_array().ravel()
    n = spanning.n_joints
    unit = spanning.units[u]
    y = y0.copy()
    y[spanning.layout.unit_state(u)] += 0.05  # stretched more: a clear torque
    j, j2 = spanning.joint_index(unit.joint), spanning.joint_index(unit.second_joint)

    def spring_energy(q):
        total = 0.0
        for i, other in enumerate(spanning.units):
            psi = q[spanning.joint_index(other.joint)]
            if other.second_joint is not None:
                psi = psi + other.direction * other.second_arm \
                    * q[spanning.joint_index(other.second_joint)]
            s = other.direction * (y[spanning.layout.unit_state(i)] - psi)
            total += 0.5 * other.parameters.se_stiffness * max(s, 0.0) ** 2
        return total

    torque = np.empty(n)
    joint_muscle_torques(y, y, units, spanning.n_units, torque, n)
    q, eps = y[:n].copy(), 1e-6
    for k in (j, j2):
        up, down = q.copy(), q.copy()
        up[k] += eps
        down[k] -= eps
        assert torque[k] == pytest.approx(-(spring_energy(up) - spring_energy(down)) / (2 * eps),
                                          rel=1e-7)
    assert abs(torque[j2]) > 1.0  # the shoulder feels the elbow flexor


def test_energy_balance_with_a_two_joint_unit():
    """d/dt(kinetic + gravity + SE + end-stop energy) = Σ T_u·ω_cc,u: the unit's tension
    does work at both joints, and its power there is what its CE and SE give up."""
    _, spanning, y0, u = _arm(0.7)
    run = ts.simulate(spanning, "monolithic", 5e-5, initial_state=y0)
    energy = chain_energy(run)
    power = ce_power(run)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1])
                                            * np.diff(run.time))])
    swing = np.ptp(energy)
    assert swing > 5.0
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-4 * swing
    # and the unit's own power at the joints: T·(d·ψ̇) = Σ_j τ_j,u·q̇_j
    c = run.columns()
    unit = spanning.units[u]
    tension = c[f"torque_{unit.name}"]
    qd = run.qd
    j, j2 = spanning.joint_index(unit.joint), spanning.joint_index(unit.second_joint)
    at_joints = unit.direction * tension * qd[:, j] + unit.second_arm * tension * qd[:, j2]
    psi_rate = np.gradient(spanning.unit_angles(run.q)[:, u], run.time)
    assert np.max(np.abs(at_joints - unit.direction * tension * psi_rate)) < \
        1e-3 * np.max(np.abs(at_joints))


def test_a_two_joint_unit_moves_the_second_joint():
    """With r ≠ 0 the shoulder's path changes (the elbow flexor now also flexes the
    shoulder) and the reference and the fixed-step techniques agree on it."""
    arm, spanning, y0, _ = _arm(0.7)
    one = ts.simulate(arm, "monolithic", 1e-4, initial_state=y0)
    two = ts.simulate(spanning, "monolithic", 1e-4, initial_state=y0)
    shoulder = arm.joint_index("shoulder")
    assert np.max(np.abs(one.q[:, shoulder] - two.q[:, shoulder])) > math.radians(1.0)
    reference = ts.simulate(spanning, "reference", initial_state=y0)
    for method, step, coupling in TECHNIQUES[:2]:
        run = ts.simulate(spanning, method, step, coupling=coupling, initial_state=y0)
        k = int(round(1e-3 / step))
        assert np.max(np.abs(run.q[::k] - reference.q)) < 1e-3


def test_the_model_file_round_trips_a_two_joint_unit(tmp_path):
    _, spanning, _, u = _arm(-0.45)
    path = tmp_path / "arm.toml"
    path.write_text(model_to_toml(spanning))
    again = load_model(path)
    assert again.units[u].second_joint == "shoulder" and again.units[u].second_arm == -0.45
    assert again == spanning


@pytest.mark.parametrize("change, field, words", [
    (dict(second_joint="elbow"), "second_joint", "is the unit's joint"),
    (dict(second_arm=0.5), "second_arm", "without a second_joint"),
    (dict(second_joint="shoulder", second_arm=2.5), "second_arm", "[-2, 2]"),
])
def test_a_bad_span_is_refused_by_name(change, field, words):
    arm = ts.load_model("builtin:arm-raise")
    unit = next(x for x in arm.units if x.joint == "elbow")
    with pytest.raises(ModelError) as caught:
        replace(unit, **change)
    assert caught.value.field == field and words in str(caught.value)


def test_a_span_must_be_adjacent_and_have_a_given_level():
    jump = ts.load_model("builtin:squat-jump")
    i = next(k for k, x in enumerate(jump.units) if x.joint == "ankle")
    far = replace(jump.units[i], second_joint="hip", second_arm=0.5,
                  activation=ts.ActivationProfile(0.1))
    with pytest.raises(ModelError) as caught:
        jump.replace(units=(*jump.units[:i], far, *jump.units[i + 1:]))
    assert caught.value.field == f"units[{i}].second_joint" and "allowed: knee" in \
        str(caught.value)
    level = replace(jump.units[i], second_joint="knee", second_arm=0.5,
                    activation=ts.ActivationProfile(None))
    with pytest.raises(ModelError) as caught:
        jump.replace(units=(*jump.units[:i], level, *jump.units[i + 1:]))
    assert caught.value.field == f"units[{i}].activation.initial_level"


def test_the_fit_s_quasi_static_start_carries_the_torques_through_the_moment_arms():
    """The fit's inverse-dynamics start (`quasi_static_activations`) on the squat jump with
    two-joint units: at its levels, each unit's torque solved exactly from
    T = a·T_θ(ψ + d·T/k)·h(d·ψ̇) (an independent fixed point), summed through the moment-arm
    matrix (d at the unit's joint, r at its second), gives the required joint torques within
    3 % + 1 N·m wherever no unit is at full activation (the start guesses each SE stretch
    from the torque it needs). Without the two-joint units' torque at
    their second joints (the first pass alone) the knee and hip are off by far more."""
    from torquesim.fitting.initial_guess import quasi_static_activations
    from torquesim.model.torque_generator import ce_torque_velocity, torque_angle

    model = ts.load_model("builtin:squat-jump-biarticular")
    n = model.n_joints
    rng = np.random.default_rng(3)
    samples = 40
    q = np.array([j.initial_angle for j in model.joints])[:, None] \
        + rng.uniform(-0.3, 0.3, (n, samples))
    qd = rng.uniform(-2.0, 2.0, (n, samples))
    torque = rng.uniform(-150.0, 150.0, (n, samples))
    angle, speed = model.unit_angles(q.T).T, model.unit_angles(qd.T).T
    rests = [None] * model.n_units

    def produced(levels):
        out = np.zeros_like(torque)
        for u, unit in enumerate(model.units):
            p, d, k = unit.parameters.to_array(), unit.direction, unit.parameters.se_stiffness
            for i in range(samples):
                tension = 0.0
                for _ in range(200):  # T = a·T_θ(ψ + d·T/k)·h(d·ψ̇), a contraction here
                    tension = levels[u, i] * ce_torque_velocity(d * speed[u, i], p, 0) \
                        * torque_angle(angle[u, i] + d * tension / k, p, 0)
                out[model.joint_index(unit.joint), i] += d * tension
                if unit.second_joint is not None:
                    out[model.joint_index(unit.second_joint), i] += unit.second_arm * tension
        return out

    torque[0] = 0.0  # the foot on the ground: no unit at the root joint
    levels = quasi_static_activations(model, q, qd, torque, rests)
    unsaturated = np.all(levels < 1.0, axis=0)
    assert unsaturated.sum() >= 10
    error = np.abs(produced(levels) - torque)[:, unsaturated]
    assert np.all(error <= 0.03 * np.abs(torque[:, unsaturated]) + 1.0), error.max()
    import torquesim.fitting.initial_guess as guess

    one_pass = guess.TWO_JOINT_PASSES
    try:
        guess.TWO_JOINT_PASSES = 1
        first = quasi_static_activations(model, q, qd, torque, rests)
    finally:
        guess.TWO_JOINT_PASSES = one_pass
    assert np.abs(produced(first) - torque)[:, unsaturated].max() > 10 * error.max()
