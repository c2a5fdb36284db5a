"""The error-controlled step loop (``imex-ros2-adaptive``): imex-ros2's step (body on ROS2,
linearly implicit in the end stops and ground contacts; units on SDIRK2; body first, linear
torque predictor), its step size chosen by an error estimate at every step, take-off and
touchdown located as events, and the state written on a fixed output grid by interpolation.

Error estimate (embedded, no extra evaluation): each part's step against a first-order
solution from the same stages,

    body (ROS2, Verwer et al. 1999):  e = h·(k1 + k2)/2          (y + h·k1 is order 1)
    units (SDIRK2, γ = 1 − 1/√2):     e = h·γ·(k2 − k1)          (y + h·k1 is order 1)

both O(h²), the local error of the order-1 solution, which bounds the order-2 step's. The
body's stages are already solved with (I − γhJ), so the estimate of the contacts' and end
stops' stiff modes is damped as the step is. The error norm is the largest of
|e_i|/(atol_i + rtol·|y_i|) over the state, with atol_i the angle tolerance (rad; m for the
base's position) on angles and unit states and `VELOCITY_SCALE` times it on speeds.

Step-size control (Hairer & Wanner II §IV.8; Gustafsson's PI controller, as diffrax's
``PIDController`` with pcoeff 0.4/k, icoeff 0.3/k, k = 2): a step is accepted when the norm
err ≤ 1, and the next step is h·0.9·err^(−0.35)·err_prev^(0.2), within [0.2, 5]·h (no growth
right after a rejection); a rejected step is retried at h·max(0.2, 0.9·err^(−1/2)). The step
never exceeds ``max_step`` (the caller's: a tenth of the shortest activation ramp, so that no
ramp falls between the stage times) nor passes the end.

Events: a contact point's height (`contact_heights`) changing sign within a step. The
step is retried up to the crossing (secant on the heights) until the crossing lies within
`EVENT_TIME_TOLERANCE` of the step's end, and its time is recorded; the step after it starts
at the size proposed before the event.

Output: the rows of ``out`` at k·h_out (k = 0 … n_out) from the accepted step spanning them:
q by cubic Hermite interpolation on (q, q̇) at both ends, q̇ by its derivative, the units'
states by the quadratic through both ends with the step start's rate; local error O(h⁴),
O(h³), O(h³), at least the technique's order.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.body import (
    SEG_COUNT_COLUMN,
    SEG_INERTIA_COLUMN,
    SEG_PARENT_COLUMN,
    body_jacobian_size,
    body_work_size,
    contact_heights,
)
from ..model.jit import njit
from ..model.state import unit_states_start
from . import fixed_step as fs
from . import partitioned as pt
from .coupling_layout import ABSOLUTE_TOLERANCE, MAX_STEP, RELATIVE_TOLERANCE
from .rates import check_unit_kinds, flat_arrays, joint_muscle_torques
from .techniques import VELOCITY_SCALE

#: The units' implicit stages iterate until an update moves a unit's state by at most this
#: fraction of the angle tolerance (`unit_implicit_stage`'s ``state_tolerance``, as
#: CVODE's nonlinear tolerance), and at most by `NEWTON_MAX_STATE_ERROR` rad: at a loose
#: tolerance every step is the largest, and unit states solved to a tenth of it made those
#: runs' errors erratic (the arm raise 0.07° off at atol 1 and 1e-2 rad, 2.5° at 1e-3; its
#: accuracy check at 1 rad 10x off).
NEWTON_FRACTION = 0.1
NEWTON_MAX_STATE_ERROR = 1e-5
#: An event (a contact point's height changing sign) is located within this time, s.
EVENT_TIME_TOLERANCE = 1e-6
#: Below this step the loop stops with `STEP_TOO_SMALL`, s.
MIN_STEP = 1e-9
#: Attempted steps after which the loop stops with `STEP_TOO_SMALL` (a run that would take
#: days).
MAX_ATTEMPTS = 20_000_000
#: The first step tried, s (at most the largest step): the controller grows it 5x per step.
FIRST_STEP = 1e-4
_SAFETY, _SHRINK_MIN, _GROW_MAX = 0.9, 0.2, 5.0
#: PI exponents for an error estimate of local order k = 2 (Gustafsson: 0.7/k and 0.4/k).
_ALPHA, _BETA = 0.35, 0.2
_GAMMA = pt._SDIRK2_A[0, 0]


@njit(cache=True, error_model="numpy")
def error_controlled_partitioned(system, h_out, n_out, control, out, stats, body, dynamics):
    """Run the error-controlled imex-ros2 from out[0] to n_out·h_out s (module docstring),
    writing the state at every k·h_out into out[k]; ``control`` is the packed imex-ros2
    coupling with the tolerances and the largest step (`coupling_layout`), ``stats`` as the
    fixed-step loops' (`fixed_step.new_stats`) with the accepted steps in STEPS, the rejected
    ones in REJECTED_STEPS, the output rows written in ROWS and the events' times."""
    seg = system[0]
    fs.check_body(system[1], seg, body)
    atol = control[ABSOLUTE_TOLERANCE]
    rtol = control[RELATIVE_TOLERANCE]
    h_max = control[MAX_STEP]
    n, nu, width, units, joints, profiles = flat_arrays(system)
    check_unit_kinds(units, nu, dynamics)
    size = out.shape[1]
    first = unit_states_start(n)
    t_end = n_out * h_out
    y = out[0].copy()
    y1 = out[0].copy()
    b = np.empty((pt._SCRATCH_ROWS, size))
    work = np.empty(body_work_size(n, seg))
    jacobian = np.empty(body_jacobian_size(n))
    body_arrays = (n, seg, joints, work, jacobian)
    muscles = (n, nu, width, units, profiles,
               min(NEWTON_FRACTION * atol, NEWTON_MAX_STATE_ERROR))
    n_contacts = seg.shape[0] - int(seg[0, SEG_COUNT_COLUMN])
    heights = np.empty(n_contacts)
    heights_end = np.empty(n_contacts)
    angles = np.empty(int(seg[0, SEG_COUNT_COLUMN]))  # scratch of `contact_heights`
    if n_contacts > 0:
        contact_heights(y, n, seg, joints, heights, angles)
    torque_prev = np.empty(n)
    omega_start = np.empty(nu)  # the units' CE velocities at this step's start and the last's
    omega_prev = np.empty(nu)
    for u in range(nu):
        b[pt._OMEGA, u] = np.nan
    joint_muscle_torques(y, y, units, nu, torque_prev, n)
    stats[fs.ROWS] = 1
    stats[fs.SMALLEST_STEP] = math.inf
    t = 0.0
    h = min(FIRST_STEP, h_max)
    h_prev = 0.0
    err_prev = 1.0
    rejected = False
    resume = 0.0  # the step proposed before an event cut one short
    row = 1
    attempts = 0
    while row <= n_out:
        attempts += 1
        if h < MIN_STEP or attempts > MAX_ATTEMPTS:
            stats[fs.STATUS] = fs.STEP_TOO_SMALL
            stats[fs.WORST_TIME] = t
            return
        h = min(h, h_max)
        if t + h * 1.01 >= t_end:
            h = t_end - t
        pt._muscles_at_step_start(muscles, t, y, h, b, stats, dynamics)
        for u in range(nu):  # the first stage's seed: ω extrapolated to t + γh
            omega_start[u] = b[pt._OMEGA, u]
            if h_prev > 0.0:
                b[pt._OMEGA, u] += (omega_start[u] - omega_prev[u]) * _GAMMA * h / h_prev
        for j in range(n):
            b[pt._TORQUE_SLOPE, j] = (b[pt._TORQUE0, j] - torque_prev[j]) * h / h_prev \
                if h_prev > 0.0 else 0.0
            b[pt._Q_SLOPE, j] = 0.0
        for i in range(size):
            y1[i] = y[i]
        pt._body_ros2(body_arrays, t, y, h, b, y1, stats, body)
        for j in range(n):
            b[pt._Q_SLOPE, j] = y1[j] - y[j]
        pt._count_muscle_work(stats, pt._muscle_part(muscles, t, y, h, 1, b, y1, dynamics,
                                                     None, True))
        stats[fs.NFEV_BODY] += 2
        stats[fs.SWEEPS] += 1
        joint_muscle_torques(y1, y1, units, nu, b[pt._TORQUE], n)
        _coupling_acceleration(n, seg, work, b, body)
        err = 0.0
        for i in range(size):
            scale = atol + rtol * abs(y1[i])
            if i < n:
                e = abs(0.5 * h * (b[pt._K1, i] + b[pt._K2, i])) \
                    + h * h / 6.0 * abs(b[pt._Q, i])
            elif i < first:
                e = abs(0.5 * h * (b[pt._K1, i] + b[pt._K2, i])) \
                    + 0.5 * h * abs(b[pt._Q, i - n])
                scale *= VELOCITY_SCALE
            else:
                e = abs(_GAMMA * h * (b[pt._K2, i] - b[pt._K1, i]))
            err = max(err, e / scale)
        if not err <= 1.0:  # (NaN too)
            shrink = _SAFETY * err ** -0.5 if math.isfinite(err) else _SHRINK_MIN
            h *= max(_SHRINK_MIN, shrink)
            rejected = True
            stats[fs.REJECTED_STEPS] += 1
            continue
        crossing = 2.0
        if n_contacts > 0:
            contact_heights(y1, n, seg, joints, heights_end, angles)
            for c in range(n_contacts):
                if (heights[c] > 0.0) != (heights_end[c] > 0.0):
                    crossing = min(crossing, heights[c] / (heights[c] - heights_end[c]))
            if crossing <= 1.0 and (1.0 - crossing) * h > EVENT_TIME_TOLERANCE:
                if resume == 0.0:
                    resume = h
                h = crossing * h + 0.5 * EVENT_TIME_TOLERANCE
                stats[fs.REJECTED_STEPS] += 1
                continue
        # accepted: the output rows within the step, then the step's end becomes its start
        t_new = t + h if t + h < t_end else t_end
        while row <= n_out and row * h_out <= t_new + 1e-12:
            _interpolate(y, y1, b, (row * h_out - t) / h, h, n, first, size, out[row])
            row += 1
        stats[fs.ROWS] = row
        if crossing <= 1.0:
            k = int(stats[fs.EVENTS])
            if k < fs.EVENT_SLOTS:
                stats[fs.EVENT_TIMES + k] = t + crossing * h
            stats[fs.EVENTS] = k + 1
        for j in range(n):
            torque_prev[j] = b[pt._TORQUE0, j]
        for u in range(nu):
            omega_prev[u] = omega_start[u]
        for i in range(size):
            y[i] = y1[i]
        for c in range(n_contacts):
            heights[c] = heights_end[c]
        stats[fs.STEPS] += 1
        stats[fs.SMALLEST_STEP] = min(stats[fs.SMALLEST_STEP], h)
        stats[fs.LARGEST_STEP] = max(stats[fs.LARGEST_STEP], h)
        t = t_new
        h_prev = h
        status = fs._check_state(y, n, joints)
        if status != fs.OK:
            stats[fs.STATUS] = status
            stats[fs.WORST_TIME] = t
            return
        factor = _SAFETY * max(err, 1e-10) ** -_ALPHA * err_prev ** _BETA
        factor = min(_GROW_MAX, max(_SHRINK_MIN, factor))
        if rejected:
            factor = min(factor, 1.0)
        err_prev = max(err, 1e-4)
        rejected = False
        h *= factor
        if crossing <= 1.0:  # an event ended the step: on at the size proposed before it
            if resume > 0.0:
                h = resume
            resume = 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def _coupling_acceleration(n, seg, work, b, body):
    """The error of the body's accelerations at the step end from the torque predictor,
    rad/s², into b[_Q]: M⁻¹·δτ for the torque error δτ = τ0 + slope − τ(y_new) (the torque
    the body integrated with at the step end, b[_TORQUE0] + b[_TORQUE_SLOPE], against the
    units' there, b[_TORQUE]); linear over the step, it moves q̇ by h/2 and q by h²/6 times
    this. M is the one factorised (LDLᵀ) by the body's last evaluation (in ``work``), in the
    absolute angles φ: the joint torques enter as Q_k = τ_k − Σ_children τ_c, and
    q̈_k = φ̈_k − φ̈_parent. One segment on a pivot: δτ/I."""
    for j in range(n):
        b[pt._Q, j] = b[pt._TORQUE0, j] + b[pt._TORQUE_SLOPE, j] - b[pt._TORQUE, j]
    if body is None:
        b[pt._Q, 0] /= seg[0, SEG_INERTIA_COLUMN]
        return
    nb = n - int(seg[0, SEG_COUNT_COLUMN])
    for k in range(n - nb):  # Q_parent −= τ_k (parents come first)
        p = int(seg[k, SEG_PARENT_COLUMN])
        if p >= 0:
            b[pt._Q, nb + p] -= b[pt._TORQUE0, nb + k] + b[pt._TORQUE_SLOPE, nb + k] \
                - b[pt._TORQUE, nb + k]
    for i in range(n):  # L·z = Q, then D·Lᵀ·x = z
        v = b[pt._Q, i]
        for k in range(i):
            v -= work[i * n + k] * b[pt._Q, k]
        b[pt._Q, i] = v
    for i in range(n - 1, -1, -1):
        v = b[pt._Q, i] / work[i * n + i]
        for k in range(i + 1, n):
            v -= work[k * n + i] * b[pt._Q, k]
        b[pt._Q, i] = v
    for k in range(n - nb - 1, 0, -1):  # q̈_k = φ̈_k − φ̈_parent (children first)
        p = int(seg[k, SEG_PARENT_COLUMN])
        if p >= 0:
            b[pt._Q, nb + k] -= b[pt._Q, nb + p]


@njit(cache=True, error_model="numpy", inline="always")
def _interpolate(y, y1, b, s, h, n, first, size, row):
    """The state at the fraction s of the step from y to y1 (module docstring) into ``row``:
    q cubic Hermite on (q, q̇) at both ends, q̇ its derivative, the units' states the
    quadratic through both ends with the rate b[_RATE] at the start."""
    s2 = s * s
    s3 = s2 * s
    for j in range(n):
        q0, q1, v0, v1 = y[j], y1[j], y[n + j], y1[n + j]
        row[j] = (2.0 * s3 - 3.0 * s2 + 1.0) * q0 + (s3 - 2.0 * s2 + s) * h * v0 \
            + (3.0 * s2 - 2.0 * s3) * q1 + (s3 - s2) * h * v1
        row[n + j] = (6.0 * s2 - 6.0 * s) * (q0 - q1) / h + (3.0 * s2 - 4.0 * s + 1.0) * v0 \
            + (3.0 * s2 - 2.0 * s) * v1
    for i in range(first, size):
        slope = h * b[pt._RATE, i]
        row[i] = y[i] + s * slope + s2 * (y1[i] - y[i] - slope)
