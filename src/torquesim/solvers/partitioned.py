"""Technique 1, partitioned: the body part (q, q̇) and the muscle part (the units' states) each
advanced by its own solver, exchanging under a coupling scheme (`Coupling`; docs/model.md
§4). The muscle part runs its solver's tableau, explicit RK4 or the L-stable SDIRK2 of the
IMEX techniques (`_muscle_part`); the body part RK4 (`_body_rk4`) or ROS2, linearly implicit in
its stiff forces (`_body_ros2`, ``imex-ros2``). The error-controlled loop (`error_control`)
steps the same parts."""

from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import overload

from ..model.body import (
    SEG_COUNT_COLUMN,
    SEG_INERTIA_COLUMN,
    SEG_PARENT_COLUMN,
    body_jacobian_size,
    body_work_size,
    force_jacobians,
    passive_stiffness,
    single_segment_acceleration,
    tree_accelerations,
)
from ..model.jit import njit
from ..model.state import unit_state, unit_states_start
from . import tableaus  # the module: coupling_layout's SDIRK2 is the muscle solver's code
from .coupling_layout import (
    BODY_FIRST,
    BODY_SOLVER,
    EVERY_STAGE,
    ITERATIONS,
    LINEAR,
    MUSCLE_SOLVER,
    MUSCLE_SUBSTEPS,
    MUSCLES_FIRST,
    ORDER,
    PREDICTOR,
    ROS2,
    SDIRK2,
    TOLERANCE,
)
from .fixed_step import (
    _RK4_C,
    BODY_JACOBIANS,
    COUPLING_ANGLE,
    COUPLING_TIME,
    COUPLING_TORQUE,
    COUPLING_TORQUE_MAX,
    IMPLICIT_SOLVES,
    NEWTON_ITERATIONS,
    NFEV_BODY,
    NFEV_MUSCLE,
    OK,
    STATUS,
    STEPS,
    SWEEPS,
    _check_state,
    _record_contacts,
    _record_stiffness,
    check_body,
    rk4_increment,
    rk4_stage_offset,
)
from .rates import (
    add_unit_torque,
    check_unit_kinds,
    flat_arrays,
    joint_muscle_torques,
    unit_angle,
    unit_angle_at,
    unit_excitation,
    unit_joints,
    unit_rates,
)
from .sdirk import unit_implicit_stage

#: The muscle part's two solvers as their tableaus (A, b, c), arrays frozen into the
#: compiled loop (`_muscle_part`): explicit RK4 and the L-stable SDIRK2 of the IMEX technique.
_RK4_A, _RK4_B = np.array(tableaus.RK4.a), np.array(tableaus.RK4.b)
_SDIRK2_A, _SDIRK2_B, _SDIRK2_C = (np.array(tableaus.SDIRK2.a), np.array(tableaus.SDIRK2.b),
                                   np.array(tableaus.SDIRK2.c))
#: γ of the implicit body part's two-stage Rosenbrock (W-) method ROS2 (`_body_ros2`).
ROS2_GAMMA = tableaus.ROS2_GAMMA
#: Rows of the scratch array of the partitioned loop (each row as long as the state).
(_K1, _K2, _K3, _K4, _STAGE, _Q, _TORQUE, _TORQUE0, _TORQUE_SLOPE, _Q_SLOPE, _RATE, _OMEGA,
 _OLD, _MUSCLE_STAGE, _W) = range(15)
_SCRATCH_ROWS = 15


@njit(cache=True, error_model="numpy", _nrt=False)
def _body_rk4(body_arrays, t, y, h, b, y_new, stats, body):
    """One RK4 step of the body part (q, q̇) = y[:2n] with joint torques
    τ(s) = τ0 + slope·s/h over the step (τ0 = b[_TORQUE0], slope = b[_TORQUE_SLOPE]); the
    result into y_new[:2n]. ``body_arrays`` = (n, segments, flat joints, work array, the
    implicit body part's scratch, unused here), ``b`` the partitioned loop's scratch array,
    ``body`` its kinds as for `rk4_monolithic`."""
    n = body_arrays[0]
    m = unit_states_start(n)  # q and q̇: the body part
    for s in range(4):
        if s == 0:
            for i in range(m):
                b[_STAGE, i] = y[i]
        else:
            factor = rk4_stage_offset(s, h)
            for i in range(m):
                b[_STAGE, i] = y[i] + factor * b[_K1 + s - 1, i]
        fraction = _RK4_C[s]
        for j in range(n):
            b[_TORQUE, j] = b[_TORQUE0, j] + fraction * b[_TORQUE_SLOPE, j] if s > 0 \
                else b[_TORQUE0, j]
        if body is None:
            _pivot_stage_rates(body_arrays, b, _K1 + s)
        else:
            _body_stage_rates(body_arrays, t, h, b, _K1 + s, stats, body, s == 0)
    for i in range(m):
        y_new[i] = y[i] + rk4_increment(b[_K1, i], b[_K2, i], b[_K3, i], b[_K4, i], h)


@njit(cache=True, error_model="numpy", inline="always")
def _body_stage_rates(body_arrays, t, h, b, row, stats, body, at_start):
    """The body part's rates at the state b[_STAGE] with the joint torques b[_TORQUE] into
    b[row, :2n] (q̇, q̈), for both body solvers; ``at_start`` (the step's first stage, time
    t): the contacts' time constant into the guard too (it leaves the factorisation of M and
    the contacts' forces in the work array). ``body`` None (one segment on a fixed pivot)
    is `_pivot_stage_rates`: the solvers branch on it themselves, so that Numba prunes the
    general solve there before inlining it (`check_body`)."""
    n, seg, joints, work, _ = body_arrays
    for j in range(n):
        b[row, j] = b[_STAGE, n + j]
    tree_accelerations(b[_STAGE], n, body, b[_TORQUE], seg, joints, work)
    for k in range(n):
        b[row, n + k] = work[n * n + k]
    if at_start and seg.shape[0] > int(seg[0, SEG_COUNT_COLUMN]):
        _record_contacts(stats, t, h, b[_STAGE], n, seg, work, body.free_base)


@njit(cache=True, error_model="numpy", inline="always")
def _pivot_stage_rates(body_arrays, b, row):
    """`_body_stage_rates` of one segment on a fixed pivot (q̇, q̈ into b[row, :2])."""
    seg, joints = body_arrays[1], body_arrays[2]
    b[row, 0] = b[_STAGE, 1]
    b[row, 1] = single_segment_acceleration(b[_STAGE, 0], b[_TORQUE, 0], seg, joints)


@njit(cache=True, error_model="numpy", _nrt=False)
def _linearise_body(body_arrays, b, body):
    """The linearisation of the body's stiff forces at b[_STAGE], right after
    `_body_stage_rates` there: M, S, G into the scratch ``jac`` (`force_jacobians`; one
    segment: M = A_1, S = T_p'(q), G = 0)."""
    n, seg, joints, work, jac = body_arrays
    if body is not None:
        force_jacobians(b[_STAGE], n, seg, joints, work, jac)
    else:
        jac[0] = seg[0, SEG_INERTIA_COLUMN]
        jac[1] = passive_stiffness(b[_STAGE, 0], joints, 0)
        jac[2] = 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def _factor_iteration_matrix(n, gh, jac):
    """W = M − γh·G − (γh)²·S (`force_jacobians`' matrices in ``jac``) into jac[3n²:4n²],
    factorised in place as P·W = L·U by Gaussian elimination with partial pivoting (the
    row swaps in jac[4n² + 2n:], as floats)."""
    nn = n * n
    w = 3 * nn
    pivots = 4 * nn + 2 * n
    for i in range(nn):
        jac[w + i] = jac[i] - gh * jac[2 * nn + i] - gh * gh * jac[nn + i]
    for k in range(n):
        best = k
        for i in range(k + 1, n):
            if abs(jac[w + i * n + k]) > abs(jac[w + best * n + k]):
                best = i
        jac[pivots + k] = best
        if best != k:
            for j in range(n):
                swap = jac[w + k * n + j]
                jac[w + k * n + j] = jac[w + best * n + j]
                jac[w + best * n + j] = swap
        for i in range(k + 1, n):
            factor = jac[w + i * n + k] / jac[w + k * n + k]
            jac[w + i * n + k] = factor
            for j in range(k + 1, n):
                jac[w + i * n + j] -= factor * jac[w + k * n + j]


@njit(cache=True, error_model="numpy", _nrt=False)
def _solve_stage(n, gh, seg, jac, b, row):
    """Solve (I − γh·J)·k = r for the body part's stage vector k = (k_q, k_v), r read from
    and k written to b[row, :2n], J the linearisation [[0, I], [∂q̈/∂q, ∂q̈/∂q̇]] of the
    stiff forces. In the absolute coordinates X = P·q (φ_k = q_k + φ_parent(k) + offset):

        W·(P·k_v) = M·(P·r_v) + γh·S·(P·r_q),    k_q = r_q + γh·k_v

    with W factorised by `_factor_iteration_matrix`."""
    nn = n * n
    nb = n - int(seg[0, SEG_COUNT_COLUMN])
    w = 3 * nn
    pivots = 4 * nn + 2 * n
    rq = pivots + n  # P·r_q, P·r_v, then the right-hand side
    rv = rq + n
    x = rv + n
    for i in range(n):  # P·r (parents come first)
        jac[rq + i] = b[row, i]
        jac[rv + i] = b[row, n + i]
        if i >= nb:
            p = int(seg[i - nb, SEG_PARENT_COLUMN])
            if p >= 0:
                jac[rq + i] += jac[rq + nb + p]
                jac[rv + i] += jac[rv + nb + p]
    for i in range(n):
        v = 0.0
        for j in range(n):
            v += jac[i * n + j] * jac[rv + j] + gh * jac[nn + i * n + j] * jac[rq + j]
        jac[x + i] = v
    for k in range(n):  # the row swaps, then L·z = rhs and U·(P·k_v) = z
        p = int(jac[pivots + k])
        if p != k:
            swap = jac[x + k]
            jac[x + k] = jac[x + p]
            jac[x + p] = swap
    for i in range(n):
        v = jac[x + i]
        for j in range(i):
            v -= jac[w + i * n + j] * jac[x + j]
        jac[x + i] = v
    for i in range(n - 1, -1, -1):
        v = jac[x + i]
        for j in range(i + 1, n):
            v -= jac[w + i * n + j] * jac[x + j]
        jac[x + i] = v / jac[w + i * n + i]
    for i in range(n - 1, -1, -1):  # k_v = P⁻¹·(P·k_v), children first
        v = jac[x + i]
        if i >= nb:
            p = int(seg[i - nb, SEG_PARENT_COLUMN])
            if p >= 0:
                v -= jac[x + nb + p]
        b[row, n + i] = v
        b[row, i] += gh * v


@njit(cache=True, error_model="numpy", _nrt=False)
def _body_ros2(body_arrays, t, y, h, b, y_new, stats, body):
    """One step of the implicit body part: the two-stage Rosenbrock W-method ROS2 of Verwer,
    Spee, Blom and Hundsdorfer (1999, SIAM J Sci Comput 20:1456) on (q, q̇) = y[:2n], with the
    joint torques τ(s) = τ0 + slope·s/h as in `_body_rk4` and J the linearisation of the
    stiff forces (the end stops and the ground contacts, `force_jacobians`) at the step start:

        (I − γhJ)·k1 = f(t, y),   (I − γhJ)·k2 = f(t + h, y + h·k1) − 2·k1,
        y_new = y + h·(3/2·k1 + 1/2·k2),    γ = 1 + 1/√2

    Order 2 whatever J is (a W-method: the rest of the body's forces stay explicit), and
    L-stable on the modes J holds, so the contacts and end stops set no step-size limit. Two
    evaluations of the body's rates and one factorisation of the iteration matrix per step.
    ``body_arrays`` = (n, segments, flat joints, work array, Jacobian scratch of
    `body_jacobian_size`); the rest as for `_body_rk4`."""
    n = body_arrays[0]
    jac = body_arrays[4]
    m = unit_states_start(n)
    gh = ROS2_GAMMA * h
    for s in range(2):  # (one call of the inlined rates: each call site compiles a copy)
        for i in range(m):
            b[_STAGE, i] = y[i] + h * b[_K1, i] if s == 1 else y[i]
        for j in range(n):
            b[_TORQUE, j] = b[_TORQUE0, j] + b[_TORQUE_SLOPE, j] if s == 1 else b[_TORQUE0, j]
        if body is None:
            _pivot_stage_rates(body_arrays, b, _K1 + s)
        else:
            _body_stage_rates(body_arrays, t, h, b, _K1 + s, stats, body, s == 0)
        if s == 0:
            _linearise_body(body_arrays, b, body)
            _factor_iteration_matrix(n, gh, jac)
        else:
            for i in range(m):
                b[_K2, i] -= 2.0 * b[_K1, i]
        _solve_stage(n, gh, body_arrays[1], jac, b, _K1 + s)
    for i in range(m):
        y_new[i] = y[i] + h * (1.5 * b[_K1, i] + 0.5 * b[_K2, i])
    stats[BODY_JACOBIANS] += 1


@njit(cache=True, error_model="numpy", _nrt=False)
def _muscle_part(muscles, t, y, h, substeps, b, y_new, dynamics, explicit, implicit):
    """``substeps`` steps of the muscle part (the units' states y[2n:]) over [t, t + h] by a
    diagonally implicit Runge-Kutta method, its tableau (A, b, c) as data (`tableaus`): the
    explicit classical RK4 (``implicit`` None) or the L-stable SDIRK2 of the IMEX technique
    (``explicit`` None), the module's constant arrays (arguments would be reference-counted
    at every call). ``explicit`` and ``implicit`` (True or None) say whether the tableau has
    explicit and implicit stages: the code of a kind of stage it has not is not compiled (a
    cold IMEX run compiled 1.3 s more with the explicit stage's root finder in it). The joint
    angles are q(s) = q_n + slope·s/h (slope = b[_Q_SLOPE]), the activation profiles are
    evaluated at every stage time. Result into y_new[2n:]. ``muscles`` = (n, number of units,
    profile row width, flat units, flat profiles, the implicit stages' Newton tolerance on a
    unit's state in rad: `unit_implicit_stage`'s ``state_tolerance``, 0 in the fixed-step
    loops).

    A stage with a_ss = 0 evaluates the units' rates (`unit_rates`); one with a_ss > 0 solves
    each unit's implicit stage (`unit_implicit_stage`), which leaves the muscle part no
    step-size stability limit. Either term writes all of a unit's stage rates, whatever its
    kind: the loop knows no unit's states. The units are independent given q(s). Each
    stage's CE velocity of a unit (b[_W]) seeds its next stage's root finder; the first is
    b[_OMEGA], the CE velocities at the step start. A first stage that is explicit at the step
    start takes the rates the caller evaluated there (b[_RATE]). Stage rates go into the rows
    b[_K1…] and stage states into b[_MUSCLE_STAGE] (indexed as y).

    Returns the work: explicit stage evaluations of the muscle part (RK4: 4·substeps − 1),
    implicit stage equations solved and their residual evaluations (`NFEV_MUSCLE`,
    `IMPLICIT_SOLVES`, `NEWTON_ITERATIONS`).
    """
    n, nu, width, units, profiles, newton_tolerance = muscles
    if implicit is None:
        a, weights, c = _RK4_A, _RK4_B, _RK4_C
    else:
        a, weights, c = _SDIRK2_A, _SDIRK2_B, _SDIRK2_C
    stages = weights.shape[0]
    hs = h / substeps
    first = unit_states_start(n)
    size = y.shape[0]
    stage = b[_MUSCLE_STAGE]
    given = a[0, 0] == 0.0  # the first stage is the caller's rates at the step start
    solves = 0
    explicit_stages = 0
    for i in range(first, size):
        y_new[i] = y[i]
    for u in range(nu):
        b[_W, u] = b[_OMEGA, u]
    for sub in range(substeps):
        for s in range(stages):
            if s == 0 and sub == 0 and given:
                for i in range(first, size):
                    b[_K1, i] = b[_RATE, i]
                continue
            at = sub * hs + c[s] * hs  # the stage time after t
            for i in range(first, size):  # y + h·Σ_{r<s} a_sr·k_r
                stage[i] = y_new[i]
            for r in range(s):
                coefficient = a[s, r] * hs
                if coefficient != 0.0:
                    for i in range(first, size):
                        stage[i] += coefficient * b[_K1 + r, i]
            gh = a[s, s] * hs
            if gh == 0.0:
                explicit_stages += 1
            for u in range(nu):
                j, j2 = unit_joints(units, u)
                i = unit_state(n, units, u)
                psi = unit_angle(y[j] + b[_Q_SLOPE, j] / h * at,
                                 y[j2] + b[_Q_SLOPE, j2] / h * at, units, u)
                level = unit_excitation(t + at, profiles, width, u)
                if explicit is not None:
                    if gh == 0.0:
                        b[_W, u], _ = unit_rates(psi, stage, i, level, b[_W, u], units, u,
                                                 dynamics, b[_K1 + s])
                        continue
                if implicit is not None:  # (the tableau is SDIRK2's: every stage implicit)
                    b[_W, u], count = unit_implicit_stage(psi, stage, i, level, gh, b[_W, u],
                                                          units, u, dynamics, newton_tolerance,
                                                          b[_K1 + s])
                    solves += count
        for i in range(first, size):
            increment = 0.0
            for s in range(stages):
                increment += weights[s] * b[_K1 + s, i]
            y_new[i] += hs * increment
    return (explicit_stages, (stages * substeps - explicit_stages - (1 if given else 0)) * nu,
            solves)


@njit(cache=True, error_model="numpy", _nrt=False)
def _muscles_at_step_start(muscles, t, y, hm, b, stats, dynamics):
    """The units at the step start (time t, state y): their joint torques into b[_TORQUE0],
    their rates into b[_RATE] and CE velocities into b[_OMEGA] (the muscle part's first
    explicit stage and the seeds of its root finders), their step/τ into the guard. A
    function of its own, called once a step: it is compiled once for each ``dynamics``
    (`unit_rates`) and shared by every partitioned technique and body, where inlined in
    `rk4_partitioned` each of the loop's kinds compiled the units' rates again."""
    n, nu, width, units, profiles, _ = muscles
    for j in range(n):
        b[_TORQUE0, j] = 0.0
    for u in range(nu):
        i = unit_state(n, units, u)
        psi = unit_angle_at(y, units, u)
        add_unit_torque(b[_TORQUE0], psi, y[i], units, u)
        b[_OMEGA, u], tau = unit_rates(psi, y, i, unit_excitation(t, profiles, width, u),
                                       b[_OMEGA, u], units, u, dynamics, b[_RATE])
        _record_stiffness(stats, t, hm / tau, u)
    stats[NFEV_MUSCLE] += 1


@njit(cache=True, error_model="numpy")
def rk4_partitioned(system, h, n_steps, coupling, out, stats, body, dynamics, implicit_muscles,
                    implicit_body):
    """Body and muscle parts each advanced by their own integrator, exchanging at step
    boundaries (technique 1), under the coupling scheme ``coupling`` (see ``Coupling``).

    Default scheme (Jacobi, hold, 1 sub-step, 1 sweep): the body integrates with the joint
    torques held at τ(y_n) and the muscles with the joint angles held at q_n (zero-order hold).
    Within a step each exchanged signal is affine in time: its step-start value plus a slope
    that is zero (hold), the previous step's change (linear extrapolation) or, once the other
    part has been advanced in this step, the change it produced (Gauss-Seidel / iteration).
    ``body`` and ``dynamics``: as for `rk4_monolithic`. The muscle part is advanced by its
    solver's tableau (`_muscle_part`): SDIRK2 (``implicit_muscles`` True) or RK4 (None); the
    body part by RK4 (``implicit_body`` None, `_body_rk4`) or by ROS2, linearly implicit in
    its stiff forces (True, `_body_ros2`); both must be the packed ``coupling``'s. The
    initial state is out[0]. (The every-stage exchange is monolithic RK4: `run_step_loop`
    runs it in `rk4_monolithic`.) The four switches are arguments of their own, not the
    loop's `StepKinds`: Numba drops a branch on an argument's None before it types the
    function, and given the kinds as one value it typed and compiled both solvers of each
    part (measured: a cold first monolithic and partitioned run 9.0 s → 10.5 s).
    """
    seg = system[0]
    check_body(system[1], seg, body)
    if (int(coupling[MUSCLE_SOLVER]) == SDIRK2) != (implicit_muscles is not None) or \
            (int(coupling[BODY_SOLVER]) == ROS2) != (implicit_body is not None) or \
            int(coupling[ORDER]) == EVERY_STAGE:
        raise ValueError("the coupling array and the step loop's kinds disagree")
    explicit_muscles = _other_switch(implicit_muscles)
    order = int(coupling[ORDER])
    predictor = int(coupling[PREDICTOR])
    substeps = int(coupling[MUSCLE_SUBSTEPS])
    sweeps = int(coupling[ITERATIONS])
    tol = coupling[TOLERANCE]
    n, nu, width, units, joints, profiles = flat_arrays(system)
    check_unit_kinds(units, nu, dynamics)
    size = out.shape[1]
    c = unit_states_start(n)
    y = out[0].copy()
    y1 = out[0].copy()
    b = np.empty((_SCRATCH_ROWS, size))
    work = np.empty(body_work_size(n, seg))
    jacobian = np.empty(0 if implicit_body is None else body_jacobian_size(n))
    body_arrays = (n, seg, joints, work, jacobian)
    muscles = (n, nu, width, units, profiles, 0.0)
    q_prev = out[0, :n].copy()
    torque_prev = np.empty(n)
    for u in range(nu):
        b[_OMEGA, u] = np.nan
    joint_muscle_torques(y, y, units, nu, torque_prev, n)
    hm = h / substeps
    for step in range(n_steps):
        t = step * h
        _muscles_at_step_start(muscles, t, y, hm, b, stats, dynamics)
        for j in range(n):
            if predictor == LINEAR and step > 0:
                b[_Q_SLOPE, j] = y[j] - q_prev[j]
                b[_TORQUE_SLOPE, j] = b[_TORQUE0, j] - torque_prev[j]
            else:
                b[_Q_SLOPE, j] = 0.0
                b[_TORQUE_SLOPE, j] = 0.0
        for i in range(size):
            y1[i] = y[i]
        torque_jump = 0.0
        angle_jump = 0.0
        for sweep in range(sweeps):
            for i in range(size):
                b[_OLD, i] = y1[i]
            if order == MUSCLES_FIRST:
                _count_muscle_work(stats, _muscle_part(muscles, t, y, h, substeps, b, y1, dynamics,
                                                     explicit_muscles, implicit_muscles))
                for j in range(n):
                    b[_Q, j] = y[j] + b[_Q_SLOPE, j]
                joint_muscle_torques(b[_Q], y1, units, nu, b[_TORQUE], n)
                for j in range(n):
                    b[_TORQUE_SLOPE, j] = b[_TORQUE, j] - b[_TORQUE0, j]
                if implicit_body is None:
                    _body_rk4(body_arrays, t, y, h, b, y1, stats, body)
                else:
                    _body_ros2(body_arrays, t, y, h, b, y1, stats, body)
            else:
                if implicit_body is None:  # (an argument: the other solver is not compiled)
                    _body_rk4(body_arrays, t, y, h, b, y1, stats, body)
                else:
                    _body_ros2(body_arrays, t, y, h, b, y1, stats, body)
                if order == BODY_FIRST:
                    for j in range(n):
                        b[_Q_SLOPE, j] = y1[j] - y[j]
                _count_muscle_work(stats, _muscle_part(muscles, t, y, h, substeps, b, y1, dynamics,
                                                     explicit_muscles, implicit_muscles))
            stats[NFEV_BODY] += 4 if implicit_body is None else 2
            stats[SWEEPS] += 1
            # Later sweeps see the other part's end-of-step values (waveform relaxation).
            joint_muscle_torques(y1, y1, units, nu, b[_TORQUE], n)
            # Coupling-error indicator (no extra evaluation): the jump between the joint
            # torque the body integrated with at the step end and the torque the muscles
            # give there, and between the angle the muscles integrated with and the body's.
            torque_jump = 0.0
            angle_jump = 0.0
            for j in range(n):
                torque_jump = max(torque_jump, abs(b[_TORQUE0, j] + b[_TORQUE_SLOPE, j]
                                                   - b[_TORQUE, j]))
                angle_jump = max(angle_jump, abs(y[j] + b[_Q_SLOPE, j] - y1[j]))
            for j in range(n):
                b[_Q_SLOPE, j] = y1[j] - y[j]
                b[_TORQUE_SLOPE, j] = b[_TORQUE, j] - b[_TORQUE0, j]
            if sweep > 0 and tol > 0.0:
                change = 0.0
                for i in range(size):
                    scale = h if n <= i < c else 1.0
                    change = max(change, abs(y1[i] - b[_OLD, i]) * scale)
                if change <= tol:
                    break
        stats[COUPLING_TORQUE] += torque_jump * h
        stats[COUPLING_ANGLE] += angle_jump
        if torque_jump > stats[COUPLING_TORQUE_MAX]:
            stats[COUPLING_TORQUE_MAX] = torque_jump
            stats[COUPLING_TIME] = t + h
        for j in range(n):
            q_prev[j] = y[j]
            torque_prev[j] = b[_TORQUE0, j]
        for i in range(size):
            y[i] = y1[i]
            out[step + 1, i] = y[i]
        stats[STEPS] = step + 1
        status = _check_state(y, n, joints)
        if status != OK:
            stats[STATUS] = status
            return


@njit(cache=True, error_model="numpy", inline="always")
def _count_muscle_work(stats, work):
    """Add `_muscle_part`'s work (explicit evaluations, implicit solves, Newton iterations)
    to ``stats``."""
    stats[NFEV_MUSCLE] += work[0]
    stats[IMPLICIT_SOLVES] += work[1]
    stats[NEWTON_ITERATIONS] += work[2]


def _other_switch(switch):
    """True for a None switch, None for a True one (`_other_switch_of`)."""
    return True if switch is None else None


@overload(_other_switch, jit_options={"error_model": "numpy"})
def _other_switch_of(switch):
    """`_other_switch` decided by the switch's Numba type while compiling, so that the result
    is a switch that prunes (typed None or bool, `check_body`)."""
    if isinstance(switch, types.NoneType):
        return lambda switch: True
    return lambda switch: None
