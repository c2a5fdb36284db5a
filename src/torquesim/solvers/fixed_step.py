"""What the compiled step loops share: the ``stats`` array they fill (indices below) and its
status codes, the check of the state after every step, the stability guards of the units and
the ground contacts, classical RK4's stage offsets and increment (written once, for the
monolithic loop and the partitioned body part) and the check of a packed body against its
kinds.

The loops are one module a technique: `monolithic` (technique 2: classical RK4 on the whole
state), `partitioned` (technique 1: the body and muscle parts each by its own solver under a
coupling scheme, the IMEX techniques among them) and `error_control` (``imex-ros2-adaptive``);
`step_loop.run_step_loop` runs the one a run's kinds choose. They take the packed chain arrays
(`PackedChain`) as one tuple, the body's kinds (`BodyKinds`, None for one segment) and the
units' switches (`step_loop.StepKinds`), write the state y = (q, q̇, the units' states) at
every step into ``out`` and fill ``stats``. Scratch arrays are allocated once per run and the
parameter arrays are read flat with row offsets. A compiled function holding loops over array
arguments costs Numba atomic reference counting at every call, measured to cost more than the
model itself; so the monolithic loop, the right-hand side and the parts' functions the
partitioned loops call at every step are compiled without it (``_nrt=False``: they allocate
nothing and return no array; tests/test_compiled_code.py checks that runs leave no array
behind). Measured against the same code with counting, min of 3 runs in alternating
processes: the squat jump's IMEX step 0.85x, the 6-segment chain's 0.86x, the elbow's at 1 ms
0.88x, the jump's error-controlled run 0.83x; trajectories bit-identical.

Stability guard: at the start of every step each unit's time constant τ = a·T_θ·|h'(ω_cc)|/k
is evaluated (from the slope the CE root finder ends with, so at no extra cost) and the
largest step/τ is recorded with its time and unit index; explicit RK4 is stable for
step/τ ≤ `RK4_STABILITY_LIMIT`.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.body import (
    ENDSTOP_HIGH,
    ENDSTOP_LOW,
    JOINT_ROW_SIZE,
    SEG_COUNT_COLUMN,
    SEG_SERIAL_COLUMN,
    SPEED_LIMIT,
    contact_time_constant,
)
from ..model.jit import njit
from . import tableaus  # the module: coupling_layout's SDIRK2 is the muscle solver's code
from .coupling_layout import (  # noqa: F401  (the layout, read here as fs.NAME)
    ABSOLUTE_TOLERANCE,
    BODY_FIRST,
    BODY_SOLVER,
    COUPLING_SIZE,
    EVERY_STAGE,
    EXPLICIT_RK4,
    HOLD,
    ITERATIONS,
    JACOBI,
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

# Indices of the stats array returned by the loops.
# NEWTON_ITERATIONS: residual evaluations of the implicit unit equations (each one a Newton
# iteration with its scalar linear solve, or the eccentric clamp's check where the iteration
# needs it); IMPLICIT_SOLVES: implicit stage equations solved. COUPLING_*: the coupling-error
# indicator of the partitioned loop (see `partitioned.rk4_partitioned`): Σ over steps of
# max_j |δτ_j|·h (N·m·s), its largest term's |δτ| (N·m) and time (s), and Σ over steps of
# max_j |δq_j| (rad).
# CONTACT_*: the stability guard of the ground contacts (explicit in the body part's RK4):
# the largest step/τ of a contact (`contact_time_constant`), its time and contact index.
# BODY_JACOBIANS: linearisations of the body's stiff forces, each with the factorisation of
# its iteration matrix (the implicit body part, `partitioned._body_ros2`).
STATUS, STEPS, NFEV_BODY, NFEV_MUSCLE, WORST_RATIO, WORST_TIME, WORST_UNIT, SWEEPS, \
    NEWTON_ITERATIONS, IMPLICIT_SOLVES, COUPLING_TORQUE, COUPLING_TORQUE_MAX, COUPLING_TIME, \
    COUPLING_ANGLE, CONTACT_RATIO, CONTACT_TIME, CONTACT_INDEX, BODY_JACOBIANS = range(18)
# The error-controlled loop's (`error_control`): steps rejected (by the error test or to
# locate an event), output rows written, the smallest and largest accepted step (s), the
# events located and the times of the first EVENT_SLOTS of them (s). (It leaves the time it
# stopped at in WORST_TIME when it fails: it has no stability guard of its own.)
REJECTED_STEPS, ROWS, SMALLEST_STEP, LARGEST_STEP, EVENTS = range(18, 23)
EVENT_TIMES = 23
EVENT_SLOTS = 16
STATS_SIZE = EVENT_TIMES + EVENT_SLOTS
# Status codes. DIVERGED: the state left the physically possible range (a joint more than a
# full turn beyond its end stops, or faster than its speed limit, ChainModel.speed_limits).
# STEP_TOO_SMALL: the error-controlled loop's step fell below its smallest.
OK, NON_FINITE, DIVERGED, STEP_TOO_SMALL = 0, 1, 2, 3
#: Real-axis stability limit of classical RK4: |λ|·h ≤ 2.785 (where |R(−x)| of its tableau
#: reaches 1, `tableaus.RK4.real_stability_limit`; tests/test_tableaus.py checks the two).
RK4_STABILITY_LIMIT = 2.785293563405282

#: Stage times of classical RK4 as fractions of the step (`tableaus.RK4`; a_{s,s−1} = c_s,
#: every other entry of A zero): an array, which Numba freezes into the compiled loops as a
#: constant (a tuple indexed by the stage made the partitioned elbow step 3–4 % slower,
#: min of 8 interleaved rounds).
_RK4_C = np.array(tableaus.RK4.c)


# Classical RK4 (`tableaus.RK4`) on the whole state and on the body part, written once: every
# stage starts from y plus c_s·h times the previous stage's derivative, and the step adds
# h·Σ b_s·k_s. The monolithic loop and the body part take their stage offsets and their
# combination from these two inlined functions over scalars (measured: no slower than the
# loops written out); the muscle part runs its solver's tableau (`partitioned._muscle_part`).
@njit(cache=True, error_model="numpy", inline="always")
def rk4_stage_offset(s, h):
    """c_s·h: stage ``s``'s time after the step start, and the multiple of the previous
    stage's derivative added to y to form it (0, h/2, h/2, h)."""
    return _RK4_C[s] * h


@njit(cache=True, error_model="numpy", inline="always")
def rk4_increment(k1, k2, k3, k4, h):
    """h·Σ b_s·k_s of one component with RK4's b = (1/6, 1/3, 1/3, 1/6), factored as
    h/6·(k1 + 2·(k2 + k3) + k4) (tests/test_tableaus.py holds it to the tableau's b)."""
    return h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)


@njit(cache=True, error_model="numpy", inline="always")
def _check_state(y, n, joints):
    """OK, NON_FINITE or DIVERGED: some joint more than a full turn beyond its end stops, or
    faster than its speed limit (the physically possible range)."""
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return NON_FINITE
    for k in range(n):
        o = k * JOINT_ROW_SIZE
        if (y[k] < joints[o + ENDSTOP_LOW] - 2.0 * math.pi
                or y[k] > joints[o + ENDSTOP_HIGH] + 2.0 * math.pi
                or abs(y[n + k]) > joints[o + SPEED_LIMIT]):
            return DIVERGED
    return OK


@njit(cache=True, error_model="numpy", inline="always")
def _record_stiffness(stats, t, ratio, u):
    """Update the largest step/τ seen (the stability guard) with unit u's ratio at time t."""
    if ratio > stats[WORST_RATIO]:
        stats[WORST_RATIO] = ratio
        stats[WORST_TIME] = t
        stats[WORST_UNIT] = u


@njit(cache=True, error_model="numpy", _nrt=False)
def _record_contacts(stats, t, h, y, n, seg, work, free_base):
    """Update the contacts' stability guard at state ``y`` (time t, step h), right after
    `joint_accelerations` there (see `contact_time_constant`). Contacts exist only on a free
    base: with ``free_base`` None nothing is compiled."""
    if free_base is not None:
        tau, c = contact_time_constant(y, n, seg, work)
        ratio = h / tau
        if ratio > stats[CONTACT_RATIO]:
            stats[CONTACT_RATIO] = ratio
            stats[CONTACT_TIME] = t
            stats[CONTACT_INDEX] = c


@njit(cache=True, error_model="numpy")
def check_body(joints, seg, body):
    """Check that the packed body matches ``body``, its `BodyKinds` or None.

    The loops take None for one segment on a fixed base, where the acceleration is one
    division, and a `BodyKinds` for bodies of two or more coordinates (the general
    mass-matrix solve: chains, trees, a free base). None is a type of its own to Numba, so
    the general branch (``if body is not None``) is removed from that compilation: the
    elbow's loop neither compiles the general solve (a bool False is a run-time branch, and
    was compiled: the elbow's monolithic loop took 9.6 s to compile with it, 4.6 s without)
    nor pays its array reference counting where it is not taken (14 % of the elbow's run).
    """
    n = joints.shape[0]
    if body is None:
        if n > 1:
            raise ValueError("a body of two or more coordinates needs its BodyKinds")
    else:
        if (n != int(seg[0, SEG_COUNT_COLUMN])) != (body.free_base is not None):
            raise ValueError("free_base must be True exactly for a body on a free base")
        if (seg[0, SEG_SERIAL_COLUMN] == 0.0) != (body.tree is not None):
            raise ValueError("tree must be True exactly for a body that is not a serial chain")


def new_stats() -> np.ndarray:
    """A zeroed stats array for the loops."""
    return np.zeros(STATS_SIZE)

