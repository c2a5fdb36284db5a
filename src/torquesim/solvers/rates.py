"""Right-hand sides of the two parts of a chain model, compiled (docs/model.md §1–§2).

State y = (q, q̇, every unit's own states; `torquesim.model.state`). Body part: (q, q̇) with
input the joint muscle torques; muscle part: the units' states (θ_cc, and a with activation
dynamics) with input the joint angles q. Unit u acts on joint j with direction d
(+1 flexor, −1 extensor) and, a two-joint unit, on the adjacent joint j2 with the signed
moment arm r (its row of the moment-arm matrix: d at j, r at j2; `model.unit_row`):

    unit angle ψ_u = q_j + d·r·q_j2,      SE stretch s_u = d·(θ_cc,u − ψ_u),
    unit torque T_u = k·max(s_u, 0),       joint torques τ_j += d·T_u, τ_j2 += r·T_u,
    dθ_cc,u/dt = d·ω_cc,u

(r = 0 for a one-joint unit: ψ = q_j and nothing is added at a second joint, so its
arithmetic is the one-joint formulation's, bit for bit).

with ω_cc,u the CE velocity solving the CE equation (positive = concentric). ``guess`` (rad/s)
is a solver's prediction of a CE velocity: it only seeds the root finder (NaN: no guess).

The whole right-hand side dy/dt is assembled in one place, `state_rates`: the monolithic
loop's stages and SciPy's solvers (`compiled_derivative`) call it. The per-unit functions are
loop-free and inlined into it and into the partitioned loops, which loop over units and joints
themselves: Numba counts the references of the arrays a compiled function holding loops
reads, at every call, and cannot prune that counting, which cost more than the whole model
when the loops sat in helpers (measured: 2.6x slower elbow steps). `state_rates` holds loops
and escapes this by being compiled without reference counting (see there). The arrays are
flat, as the solvers pass them: ``units`` holds the units' rows of `UNIT_ROW_SIZE` one after
another, ``profiles`` the activation rows of ``width``.
"""

from __future__ import annotations

import numpy as np

from ..model.activation import activation, activation_rate, activation_time_constant
from ..model.body import (
    body_kinds,
    body_work_size,
    single_segment_acceleration,
    tree_accelerations,
)
from ..model.jit import njit
from ..model.state import has_activation_state, unit_state
from ..model.torque_generator import (
    ce_equation,
    ce_time_constant,
    ce_velocity_and_slope,
    unit_torque,
)
from ..model.unit_row import (
    UNIT_ACTIVATION_TIME,
    UNIT_DEACTIVATION_TIME,
    UNIT_DIRECTION,
    UNIT_JOINT,
    UNIT_ROW_SIZE,
    UNIT_SECOND_ARM,
    UNIT_SECOND_JOINT,
)


@njit(cache=True, error_model="numpy", inline="always")
def unit_joints(units, u):
    """(j, j2): the indices of the coordinates unit u acts on (j2 = j: one joint)."""
    o = u * UNIT_ROW_SIZE
    return int(units[o + UNIT_JOINT]), int(units[o + UNIT_SECOND_JOINT])


@njit(cache=True, error_model="numpy", inline="always")
def unit_angle(q_joint, q_second, units, u):
    """Unit u's angle ψ = q_j + d·r·q_j2, rad, from the angles of its joint and of its second
    joint (the first again for a one-joint unit: r = 0, ψ = q_j). The branch on r = 0 keeps
    one-joint units on their former arithmetic (measured: the elbow's step 1.01× with it,
    1.06× computing d·r·q_j2 = 0 always)."""
    o = u * UNIT_ROW_SIZE
    r = units[o + UNIT_SECOND_ARM]
    if r == 0.0:
        return q_joint
    return q_joint + units[o + UNIT_DIRECTION] * r * q_second


@njit(cache=True, error_model="numpy", inline="always")
def unit_angle_at(q, units, u):
    """`unit_angle` read from the coordinates ``q`` (a state or any array indexed as y)."""
    j, j2 = unit_joints(units, u)
    return unit_angle(q[j], q[j2], units, u)


@njit(cache=True, error_model="numpy", inline="always")
def unit_stretch(psi, theta_cc, units, u):
    """SE stretch of unit u at CE angle ``theta_cc`` and unit angle ``psi`` (`unit_angle`; the
    joint angle for a one-joint unit): d·(θ_cc − ψ), rad."""
    return units[u * UNIT_ROW_SIZE + UNIT_DIRECTION] * (theta_cc - psi)


@njit(cache=True, error_model="numpy", inline="always")
def add_unit_torque(torque, psi, theta_cc, units, u):
    """Add unit u's torque T = k·max(s, 0) to the joint torques (N·m, flexion positive) by its
    row of the moment-arm matrix: d·T at its joint, r·T at its second joint (none for a
    one-joint unit, r = 0)."""
    o = u * UNIT_ROW_SIZE
    j, j2 = unit_joints(units, u)
    tension = unit_torque(unit_stretch(psi, theta_cc, units, u), units, o)
    torque[j] += units[o + UNIT_DIRECTION] * tension
    r = units[o + UNIT_SECOND_ARM]
    if r != 0.0:
        torque[j2] += r * tension


@njit(cache=True, error_model="numpy", inline="always")
def unit_excitation(t, profiles, width, u):
    """e_u(t), the value of unit u's packed profile row at time t (s): its activation when it
    has no activation dynamics, its excitation (the input of its dynamics) when it has."""
    return activation(t, profiles, u * width)


@njit(cache=True, error_model="numpy", inline="always")
def unit_rates(psi, y, i, excitation, guess, units, u, dynamics, rates):
    """The rates of unit u's own states, which start at y[i] (θ_cc; then a, with activation
    dynamics), into rates[i:] (dθ_cc/dt in rad/s; da/dt in 1/s), at unit angle ``psi``
    (`unit_angle`) and profile value ``excitation``. Returns (ω_cc, τ) in rad/s and s.

    This is the one place a unit's activation is read: its profile value e(t) without
    activation dynamics, its state y[i + 1] with (da/dt is then `activation_rate`). The
    loops call it for any unit and know neither its kind nor how many states it has.
    ``dynamics``: True when some unit of the model has activation dynamics, None when none
    has (a compile-time constant: the activation-state code is then not compiled,
    `check_unit_kinds`). τ is the unit's shortest time constant (the stability guard's
    input): its CE's, from the root finder's last slope, or with dynamics
    `activation_time_constant` if that is shorter."""
    o = u * UNIT_ROW_SIZE
    theta_cc = y[i]
    level = excitation if dynamics is None else unit_level(excitation, y, i, units, u)
    # The model's three pieces called here, not through one inlined wrapper: each level of
    # inlining copies the root finder's code again while compiling (every step loop).
    capacity, target, damping = ce_equation(unit_stretch(psi, theta_cc, units, u), theta_cc,
                                            level, units, o)
    w, slope = ce_velocity_and_slope(target, units, guess, damping, o)
    tau = ce_time_constant(capacity, slope, units, o)
    rates[i] = units[o + UNIT_DIRECTION] * w
    if dynamics is not None:
        if has_activation_state(units, u):
            t_act, t_deact = units[o + UNIT_ACTIVATION_TIME], units[o + UNIT_DEACTIVATION_TIME]
            rates[i + 1] = activation_rate(excitation, level, t_act, t_deact)
            tau = min(tau, activation_time_constant(excitation, level, t_act, t_deact))
    return w, tau


@njit(cache=True, error_model="numpy")
def check_unit_kinds(units, n_units, dynamics):
    """Raise unless ``dynamics`` (True or None, see `unit_rates`) matches the flat packed
    ``units``: None with a unit that has activation dynamics would ignore its state."""
    if dynamics is None:
        for u in range(n_units):
            if has_activation_state(units, u):
                raise ValueError("a unit has activation dynamics: the loop needs dynamics=True")


@njit(cache=True, error_model="numpy", inline="always")
def unit_level(excitation, y, i, units, u):
    """The activation unit u's CE sees: its state y[i + 1] with activation dynamics, else
    its profile value (`unit_rates` and the outputs read it here)."""
    return y[i + 1] if has_activation_state(units, u) else excitation


@njit(cache=True, error_model="numpy", inline="always")
def flat_arrays(system):
    """(n coordinates, n units, profile row width, flat units, flat joints, flat profiles) of
    ``system`` = the 2-D packed arrays (segments, joints, units, profiles) of `PackedChain`,
    as the loops read them (the joint array has a row per coordinate): views, by reshape
    (ravel returns its array from a compiled function, which code compiled without
    reference counting cannot call)."""
    joints, units, profiles = system[1], system[2], system[3]
    return (joints.shape[0], units.shape[0], profiles.shape[1], units.reshape(units.size),
            joints.reshape(joints.size), profiles.reshape(profiles.size))


@njit(cache=True, error_model="numpy", _nrt=False)
def joint_muscle_torques(q, x, units, n_units, out, n_joints):
    """τ = Σ_u (row u of the moment-arm matrix)·T_u, N·m, into out[:n_joints], at joint angles
    q and unit states from the state vector x (θ_cc,u = x[unit_state(n, units, u)]).
    (Outside the step loops; the loops add `add_unit_torque` themselves.)"""
    for j in range(n_joints):
        out[j] = 0.0
    for u in range(n_units):
        add_unit_torque(out, unit_angle_at(q, units, u), x[unit_state(n_joints, units, u)],
                        units, u)


def chain_derivative(t, y, seg, joints, units, profiles):
    """dy/dt at time t (s) as a new array, for SciPy's solvers; takes the 2-D packed arrays of
    `PackedChain` (`compiled_derivative` with the body's kinds)."""
    return compiled_derivative(t, y, (seg, joints, units, profiles),
                               body_kinds(seg, joints.shape[0]))


@njit(cache=True, error_model="numpy")
def compiled_derivative(t, y, system, body):
    """`chain_derivative` of the packed ``system`` (`PackedChain`) whose body is of the
    kinds ``body`` (`body_kinds`: None for one segment on a fixed pivot), so that only that
    body's solve is compiled."""
    n, nu, width, units, joints, profiles = flat_arrays(system)
    seg = system[0]
    unit_io = np.empty((UNIT_IO_ROWS, nu))
    for u in range(nu):
        unit_io[EXCITATION, u] = unit_excitation(t, profiles, width, u)
        unit_io[GUESS, u] = np.nan
    dy = np.empty(y.shape[0])
    state_rates(y, dy, unit_io, (n, nu, units, joints, seg, np.empty(n),
                                 np.empty(body_work_size(n, seg))), body, True)
    return dy


#: Rows of `state_rates`' unit array: each unit's profile value e(t) at the stage's time and
#: the CE root finder's seed (rad/s, NaN: none) in; its CE velocity ω_cc (rad/s) and its
#: shortest time constant τ (s, `unit_rates`) out.
EXCITATION, GUESS, CE_VELOCITY, TIME_CONSTANT = range(4)
UNIT_IO_ROWS = 4


@njit(cache=True, error_model="numpy", _nrt=False, forceinline=True)
def state_rates(y, rates, unit_io, model, body, dynamics):
    """dy/dt of the whole state ``y`` into ``rates``: the right-hand side, written once for
    the monolithic loop's stages (`monolithic.rk4_monolithic`) and SciPy's solvers
    (`compiled_derivative`): the joint torques of the units' SE torques, each unit's rates
    (`unit_rates`), the body's accelerations.

    ``unit_io``: the units' inputs and outputs, a row each (`EXCITATION`, `GUESS`,
    `CE_VELOCITY`, `TIME_CONSTANT`). ``model`` = (n coordinates, n units, flat units, flat
    joints, segments, joint-torque scratch of n, the body's work array of `body_work_size`,
    which it leaves as `joint_accelerations` does); ``body`` and ``dynamics`` as for
    `rk4_monolithic`.

    Compiled without Numba's reference counting (``_nrt=False``: it allocates nothing and
    returns no array), so that the loops in it cost no counting, and marked for LLVM to
    inline it at every call (``forceinline``): the loop runs it with no call at all
    (measured against the stage written out in the loop, min of 5 runs in alternating
    processes, several rounds: elbow 0.86-0.94x, squat jump 0.94-0.95x, 6-segment chain
    0.99-1.01x per step). Numba's own inlining (``inline="always"``) ran as fast but copies
    the function's IR once per block while compiling: the cold first ``simulate`` took 1.5 s
    longer."""
    n, nu, units, joints, seg, torque, work = model
    for j in range(n):
        torque[j] = 0.0
        rates[j] = y[n + j]
    for u in range(nu):
        i = unit_state(n, units, u)
        psi = unit_angle_at(y, units, u)
        add_unit_torque(torque, psi, y[i], units, u)
        unit_io[CE_VELOCITY, u], unit_io[TIME_CONSTANT, u] = unit_rates(
            psi, y, i, unit_io[EXCITATION, u], unit_io[GUESS, u], units, u, dynamics, rates)
    if body is None:
        rates[1] = single_segment_acceleration(y[0], torque[0], seg, joints)
    else:
        tree_accelerations(y, n, body, torque, seg, joints, work)
        for k in range(n):
            rates[n + k] = work[n * n + k]
