"""The implicit body part (issue 33): ROS2, linearly implicit in the forces of the end stops
and the ground contacts, and the technique ``imex-ros2`` that runs it beside the implicit
muscles. Its order on the smooth cases is measured with every registered technique
(tests/test_techniques.py); here: the method's algebra, the Jacobian it linearises with
against finite differences, and the jump past the explicit contacts' stability limit."""

import cmath

import numpy as np
import pytest

import torquesim as ts
from torquesim.model.body import (
    SEG_COUNT_COLUMN,
    SEG_PARENT_COLUMN,
    body_jacobian_size,
    body_work_size,
    force_jacobians,
    joint_accelerations,
)
from torquesim.solvers.tableaus import ROS2_GAMMA, ros2_amplification


def test_ros2_is_order_two_with_any_jacobian_and_l_stable_with_the_exact_one():
    """A W-method: one step of y' = λy agrees with exp(λh) to O(h³) whatever J (here μ = λ,
    0, −5λ, 3iλ), not to O(h⁴); with J exact |R| ≤ 1 on the left half-plane and R(−∞) = 0."""
    for ratio in (1.0, 0.0, -5.0, 3j):
        defects = [abs(ros2_amplification(z, ratio * z) - cmath.exp(z))
                   for z in (-1e-2, -5e-3)]
        assert 7.0 < defects[0] / defects[1] < 9.0, (ratio, defects)  # h³: halving gives /8
    for x in np.linspace(0.0, 1e4, 2001):
        for angle in np.linspace(np.pi / 2, 3 * np.pi / 2, 31):
            z = x * cmath.exp(1j * angle)
            assert abs(ros2_amplification(z, z)) <= 1.0 + 1e-12, z
    assert abs(ros2_amplification(-1e12, -1e12)) < 1e-10
    assert ROS2_GAMMA == pytest.approx(1.0 + 2.0**-0.5)


def _accelerations(model, y):
    seg, joints = model.segment_array(), model.pack()[1]
    n = model.n_coordinates
    work = np.empty(body_work_size(n, seg))
    joint_accelerations(y, n, np.zeros(n), seg, joints.ravel(), work)
    return work[n * n: n * n + n].copy(), work


def test_the_linearised_forces_are_the_contacts_and_end_stops_derivatives():
    """At the squat jump's start (at rest on the ground, the knees against their stops'
    tails): P⁻¹·M⁻¹·G·P, the model of ∂q̈/∂q̇, equals the finite-difference derivative (at rest
    the velocity terms have none), and P⁻¹·M⁻¹·S·P carries the stiff part of ∂q̈/∂q (gravity
    and the change of M and of the contacts' lever arms, left out, stay below 0.5 % of the
    largest entry)."""
    model = ts.load_model("builtin:squat-jump")
    seg, joints = model.segment_array(), model.pack()[1].ravel()
    n = model.n_coordinates
    y = model.initial_state().state[: 2 * n].copy()
    _, work = _accelerations(model, y)
    jac = np.empty(body_jacobian_size(n))
    force_jacobians(y, n, seg, joints, work, jac)
    mass, stiffness, damping = (jac[k * n * n:(k + 1) * n * n].reshape(n, n) for k in range(3))
    nb = n - int(seg[0, SEG_COUNT_COLUMN])
    to_absolute = np.eye(n)  # P: φ_k = q_k + φ_parent
    for k in range(n - nb):
        parent = int(seg[k, SEG_PARENT_COLUMN])
        if parent >= 0:
            to_absolute[nb + k] += to_absolute[nb + parent]
    model_dq, model_dv = (np.linalg.solve(to_absolute, np.linalg.solve(mass, m @ to_absolute))
                          for m in (stiffness, damping))
    numeric_dq, numeric_dv = np.empty((n, n)), np.empty((n, n))
    for j in range(n):
        for target, offset, delta in ((numeric_dq, 0, 1e-7), (numeric_dv, n, 1e-6)):
            plus, minus = y.copy(), y.copy()
            plus[offset + j] += delta
            minus[offset + j] -= delta
            target[:, j] = (_accelerations(model, plus)[0]
                            - _accelerations(model, minus)[0]) / (2 * delta)
    assert np.abs(model_dv).max() > 100.0  # the contacts' damping and friction are there
    np.testing.assert_allclose(model_dv, numeric_dv, rtol=1e-5, atol=1e-5 * np.abs(
        numeric_dv).max())
    assert np.abs(model_dq).max() > 1e4
    np.testing.assert_allclose(model_dq, numeric_dq, atol=5e-3 * np.abs(numeric_dq).max())


def test_imex_ros2_runs_the_jump_past_the_contacts_limit():
    """At 1 ms IMEX breaks explicit RK4's limit in the contacts (0.36 ms on the jump);
    imex-ros2 does not, stays within 0.15° of a monolithic run at 1/80 of the step, and its
    error falls as h² (order 2, measured between 0.25 and 0.125 ms)."""
    model = ts.load_model("builtin:squat-jump")
    fine = ts.simulate(model, "monolithic", 1.25e-5)
    imex = ts.simulate(model, "imex", 1e-3, check=False, advise=False, tolerance=None)
    assert imex.stability.exceeded and imex.stability.in_contact
    errors = {}
    for h in (1e-3, 2.5e-4, 1.25e-4):
        run = ts.simulate(model, "imex-ros2", h, advise=False, tolerance=None)
        assert run.success and not run.stability.exceeded, run.message
        assert run.cost.lu_decompositions == run.cost.steps
        assert run.cost.rhs_body == 2 * run.cost.steps
        stride = round(h / fine.step)
        errors[h] = np.degrees(np.abs(run.q - fine.q[::stride]).max())
    assert errors[1e-3] < 0.15, errors
    order = np.log2(errors[2.5e-4] / errors[1.25e-4])
    assert 1.5 < order < 2.5, errors
