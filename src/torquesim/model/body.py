"""The body: rigid segments in a planar tree, on a fixed pivot or free against the ground
(docs/model.md §1, §7 and §9): the elbow's parameters (`BodyParameters`), the joints' end
stops, and the equations of motion M(q)·q̈ = τ + T_p(q) + Jᵀ·F − h(q, q̇) written once for
both bases (`joint_accelerations`), with the one-segment fixed case as a division
(`single_segment_acceleration`), the abstract's Eq. 1

    I_E · dω/dt = T_net + T_p(θ) − (m_t·g·l1 + m_db·g·l2)·sin θ.

Angles are joint flexion in rad (0 = the segment hanging straight on, at the elbow full
extension).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import NamedTuple

import numpy as np

from ..errors import ModelError, check_range
from .contact import (
    CONTACT_DISTANCE,
    CONTACT_OFFSET,
    CONTACT_SEGMENT,
    contact_force,
    contact_stiffness,
    friction_damping,
)
from .jit import njit

# Layout of a packed end-stop array: the first columns of a chain joint's row
# (torquesim.model.chain).
ENDSTOP_TORQUE, ENDSTOP_SCALE, ENDSTOP_LOW, ENDSTOP_HIGH = range(4)


@dataclass(frozen=True)
class BodyParameters:
    """Anthropometry of the moving segment and the dumbbell, and the passive end stops.

    Defaults are docs/model.md §1 (de Leva 1996, reference male 73 kg; 5 kg dumbbell).

    Attributes
    ----------
    gravity : float
        g, m/s². Default 9.81. Bounds [0, inf).
    segment_mass : float
        m_t, forearm + hand mass, kg. Default 1.628. Bounds (0, inf).
    segment_com_distance : float
        l1, elbow → forearm+hand centre of mass, m. Default 0.1815. Bounds (0, inf).
    segment_inertia : float
        I_limb,E, forearm + hand moment of inertia about the elbow, kg·m². Default 0.0763.
        Bounds (0, inf).
    dumbbell_mass : float
        m_db, kg. Default 5.0. Bounds [0, inf).
    dumbbell_distance : float
        l2, elbow → dumbbell centre, m. Default 0.337. Bounds (0, inf).
    dumbbell_inertia : float
        I_db,own, dumbbell's own inertia about its handle axis, kg·m². Default 0.009.
        Bounds [0, inf).
    endstop_torque : float
        k_p, end-stop torque scale, N·m. Default 1.0. Bounds [0, inf); 0 gives the abstract's
        Eq. 1 exactly.
    endstop_angle_scale : float
        s_p, end-stop angular scale, rad. Default 0.05. Bounds (0, inf).
    endstop_lower_angle, endstop_upper_angle : float
        θ_lo, θ_hi, end-stop angles, rad. Defaults 0 and 2.618 (150°). Bounds [-π, 2π],
        θ_lo < θ_hi.
    """

    gravity: float = 9.81
    segment_mass: float = 1.628
    segment_com_distance: float = 0.1815
    segment_inertia: float = 0.0763
    dumbbell_mass: float = 5.0
    dumbbell_distance: float = 0.337
    dumbbell_inertia: float = 0.009
    endstop_torque: float = 1.0
    endstop_angle_scale: float = 0.05
    endstop_lower_angle: float = 0.0
    endstop_upper_angle: float = 2.618

    def __post_init__(self) -> None:
        pos = dict(low=0.0, low_open=True)
        check_range("gravity", self.gravity, 0.0, 100.0, unit="m/s^2")
        check_range("segment_mass", self.segment_mass, 0.0, 1e3, low_open=True, unit="kg")
        check_range("segment_com_distance", self.segment_com_distance, 0.0, 10.0, low_open=True,
                    unit="m")
        check_range("segment_inertia", self.segment_inertia, 0.0, 1e4, low_open=True,
                    unit="kg·m^2")
        check_range("dumbbell_mass", self.dumbbell_mass, 0.0, 1e3, unit="kg")
        check_range("dumbbell_distance", self.dumbbell_distance, 0.0, 10.0, low_open=True, unit="m")
        check_range("dumbbell_inertia", self.dumbbell_inertia, 0.0, 1e4, unit="kg·m^2")
        check_range("endstop_torque", self.endstop_torque, 0.0, 1e5, unit="N·m")
        check_range("endstop_angle_scale", self.endstop_angle_scale, **pos, unit="rad")
        lo = check_range("endstop_lower_angle", self.endstop_lower_angle, -math.pi, 2 * math.pi,
                         unit="rad")
        hi = check_range("endstop_upper_angle", self.endstop_upper_angle, -math.pi, 2 * math.pi,
                         unit="rad")
        if hi <= lo:
            raise ModelError("endstop_upper_angle",
                             f"{hi!r} must exceed endstop_lower_angle = {lo!r} rad")

    @property
    def elbow_inertia(self) -> float:
        """I_E = I_limb,E + m_db·l2² + I_db,own, kg·m² (parallel-axis theorem)."""
        return self.segment_inertia + self.dumbbell_mass * self.dumbbell_distance**2 \
            + self.dumbbell_inertia

    @property
    def gravity_torque_coefficient(self) -> float:
        """G = m_t·g·l1 + m_db·g·l2, N·m: gravity torque is −G·sin θ."""
        return self.gravity * (self.segment_mass * self.segment_com_distance
                               + self.dumbbell_mass * self.dumbbell_distance)

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


@njit(cache=True, error_model="numpy", inline="always")
def passive_torque(theta, b, o=0):
    """End-stop torque T_p(θ) = k_p·[exp((θ_lo − θ)/s_p) − exp((θ − θ_hi)/s_p)], N·m."""
    s = b[o + ENDSTOP_SCALE]
    return b[o + ENDSTOP_TORQUE] * (math.exp((b[o + ENDSTOP_LOW] - theta) / s)
                                - math.exp((theta - b[o + ENDSTOP_HIGH]) / s))


@njit(cache=True, error_model="numpy")
def passive_energy(theta, b, o=0):
    """Potential V_p(θ) of the end stops, J, with −dV_p/dθ = T_p(θ)."""
    s = b[o + ENDSTOP_SCALE]
    return b[o + ENDSTOP_TORQUE] * s * (math.exp((b[o + ENDSTOP_LOW] - theta) / s)
                                    + math.exp((theta - b[o + ENDSTOP_HIGH]) / s))


@njit(cache=True, error_model="numpy")
def passive_stiffness(theta, b, o=0):
    """dT_p/dθ = −V_p(θ)/s_p², N·m/rad (≤ 0: the end stops push back; `passive_torque`)."""
    s = b[o + ENDSTOP_SCALE]
    return -passive_energy(theta, b, o) / (s * s)


#: Column of a packed joint row holding the angle offset added to q_k in φ_k (the chain's
#: base angle for the first joint, 0 for the others), and the joint row size.
ZERO_OFFSET = ENDSTOP_HIGH + 1
#: Column of a packed joint row holding the largest physically possible joint speed, rad/s.
SPEED_LIMIT = ZERO_OFFSET + 1
JOINT_ROW_SIZE = SPEED_LIMIT + 1
#: Columns of a packed segment row (torquesim.model.chain.ChainModel.segment_array): A_k, B_k,
#: g·B_k, the parent's index (−1: the base); in row 0 only, the number of segments, the total
#: mass, g times it and 1 for a serial chain (each segment's parent the one before it);
#: from SEG_LEVER_COLUMN on, row a holds Λ_ab for every segment b.
(SEG_INERTIA_COLUMN, SEG_MOMENT_COLUMN, SEG_GRAVITY_COLUMN, SEG_PARENT_COLUMN,
 SEG_COUNT_COLUMN, SEG_MASS_COLUMN, SEG_WEIGHT_COLUMN, SEG_SERIAL_COLUMN,
 SEG_LEVER_COLUMN) = range(9)


@njit(cache=True, error_model="numpy", inline="always")
def single_segment_acceleration(q, muscle_torque, seg, joints):
    """q̈ of a one-segment chain on a fixed base, rad/s²: M is the scalar A_1, so
    `joint_accelerations` reduces to one division, docs/model.md's

        I_E·dω/dt = T_net + T_p(θ) − G·sin θ      (abstract Eq. 1 with end stops)

    with the same arithmetic as the general solve (tested). Loop-free, so the solvers inline
    it into their step loops at no cost."""
    return (muscle_torque + passive_torque(q, joints, 0)
            - seg[0, SEG_GRAVITY_COLUMN] * math.sin(joints[ZERO_OFFSET] + q)) \
        / seg[0, SEG_INERTIA_COLUMN]


@njit(cache=True, error_model="numpy")
def body_work_size(n, seg):
    """Length of the scratch array `joint_accelerations` needs for n coordinates and the
    contacts of the packed body ``seg``."""
    return n * n + 4 * n + CONTACT_SLOTS * (seg.shape[0] - int(seg[0, SEG_COUNT_COLUMN]))


#: What `joint_accelerations` leaves per contact in its scratch array: F_x, F_y (N), the
#: point's x, y (m) and vertical speed (m/s).
CONTACT_SLOTS = 5


@njit(cache=True, error_model="numpy")
def contacts_start(n):
    """Where `joint_accelerations` leaves each contact's `CONTACT_SLOTS` values in its
    scratch array, for n coordinates, contact after contact."""
    return n * n + 4 * n


@njit(cache=True, error_model="numpy")
def _free_base_terms(y, n, n_seg, seg, work, free_base):
    """The free base's rows of M and Q (x, y) and the ground contacts' forces in Q, into the
    scratch of `joint_accelerations` (its trigonometry and speeds filled): apart, so that
    the fixed-base solve carries none of this code (``free_base`` None: nothing compiled)."""
    if free_base is None:
        return
    rhs = n * n
    sine = rhs + n
    cosine = sine + n
    speed = cosine + n
    work[0] = seg[0, SEG_MASS_COLUMN]
    work[n] = 0.0
    work[n + 1] = seg[0, SEG_MASS_COLUMN]
    work[rhs] = 0.0
    work[rhs + 1] = -seg[0, SEG_WEIGHT_COLUMN]
    for a in range(n_seg):
        i = 2 + a
        moment = seg[a, SEG_MOMENT_COLUMN]
        work[i * n] = moment * work[cosine + i]
        work[i * n + 1] = moment * work[sine + i]
        squared = work[speed + i] * work[speed + i]
        work[rhs] += moment * squared * work[sine + i]
        work[rhs + 1] -= moment * squared * work[cosine + i]
    for c in range(n_seg, seg.shape[0]):  # ground contacts
        k = int(seg[c, CONTACT_SEGMENT])
        i = 2 + k
        d = seg[c, CONTACT_DISTANCE]
        e = seg[c, CONTACT_OFFSET]
        # the point: base + Σ_ancestors Λ_sk·u(φ_s) + d·u(φ_k) + e·n(φ_k)
        px = y[0] + d * work[sine + i] + e * work[cosine + i]
        py = y[1] - d * work[cosine + i] + e * work[sine + i]
        vx = y[n] + work[speed + i] * (d * work[cosine + i] - e * work[sine + i])
        vy = y[n + 1] + work[speed + i] * (d * work[sine + i] + e * work[cosine + i])
        s = int(seg[k, SEG_PARENT_COLUMN])
        while s >= 0:
            lever = seg[s, SEG_LEVER_COLUMN + k]
            px += lever * work[sine + 2 + s]
            py -= lever * work[cosine + 2 + s]
            vx += lever * work[speed + 2 + s] * work[cosine + 2 + s]
            vy += lever * work[speed + 2 + s] * work[sine + 2 + s]
            s = int(seg[s, SEG_PARENT_COLUMN])
        fx, fy = contact_force(py, vy, vx, seg, c)
        o = speed + n + CONTACT_SLOTS * (c - n_seg)  # `contacts_start`
        work[o], work[o + 1], work[o + 2], work[o + 3], work[o + 4] = fx, fy, px, py, vy
        if fx == 0.0 and fy == 0.0:
            continue
        work[rhs] += fx
        work[rhs + 1] += fy
        work[rhs + i] += (d * work[cosine + i] - e * work[sine + i]) * fx \
            + (d * work[sine + i] + e * work[cosine + i]) * fy
        s = int(seg[k, SEG_PARENT_COLUMN])
        while s >= 0:
            lever = seg[s, SEG_LEVER_COLUMN + k]
            work[rhs + 2 + s] += lever * (work[cosine + 2 + s] * fx
                                          + work[sine + 2 + s] * fy)
            s = int(seg[s, SEG_PARENT_COLUMN])


def joint_accelerations(y, n, muscle_torque, seg, joints, work):
    """Accelerations of the n coordinates of a planar tree of segments (docs/model.md §1, §7,
    §9), into work[n²:n²+n]; coordinates y[:n], their speeds y[n:2n].

    The coordinates are the joint angles q_k (rad), preceded on a free base by the position
    (x, y) of the root segment's proximal point (m); the root's q is then its absolute angle
    and carries no muscle torque. The equations are written once, for both bases, in the
    absolute angles φ_k = φ_parent(k) + offset_k + q_k:

        M·ẍ + c = Q,    X = (x, y, φ_1…φ_n) on a free base, (φ_1…φ_n) on a fixed one

    with, for segments a and b where a is an ancestor of b (Λ_ab: the distance along a from
    its proximal joint to where the branch leading to b is attached; 0 for unrelated
    segments),

        M_aa = A_a,  M_ab = Λ_ab·B_b·cos(φ_a − φ_b),   c_a = Σ_b D_ab·sin(φ_a − φ_b)·φ̇_b²,
        D_ab = D_ba = Λ_ab·B_b,                        gravity Q_a −= g·B_a·sin φ_a,

    and on a free base M_xx = M_yy = m (total mass), M_xa = B_a·cos φ_a, M_ya = B_a·sin φ_a,
    c_x = −Σ B_a·φ̇_a²·sin φ_a, c_y = Σ B_a·φ̇_a²·cos φ_a, Q_y −= m·g (A_a, B_a: inertia and
    first moment about a's proximal joint of a and everything distal to it). Joint torques
    τ_k = muscle_torque_k + T_p(q_k) act between segment k and its parent: Q_k += τ_k,
    Q_parent −= τ_k. A contact force F at a point P of segment k (`contact_force`) adds
    Jᵀ·F: F_x, F_y to Q_x, Q_y, Λ_sk·n(φ_s)·F for every ancestor s and (d·n(φ_k) − e·u(φ_k))·F
    for k itself (u = (sin φ, −cos φ) the segment axis, n = (cos φ, sin φ), d and e the
    point's distance and offset). Solved by an LDLᵀ factorization of M (symmetric positive
    definite); then q̈_k = φ̈_k − φ̈_parent(k).

    ``seg``: the packed segment rows, then the contact rows (`ChainModel.segment_array`);
    ``joints``: the flat joint rows of the n coordinates (end stops, zero offset); ``work``:
    flat scratch of `body_work_size`, which holds the accelerations at the end, and from
    `contacts_start` on each contact's force and point (no output array: the solvers' step
    loops pay for every array argument).

    Called from Python; compiled callers use `body_accelerations` (or the step loops
    `tree_accelerations`), whose `BodyKinds` keep the other bodies' code out of their
    compilation.
    """
    body_accelerations(y, n, muscle_torque, seg, joints, work,
                       body_kinds(seg, n) or BodyKinds(None, None))


class BodyKinds(NamedTuple):
    """What the compiled code of a body of two or more coordinates is made of, each kind True
    or None (`switch`): None is a type of its own to Numba, so code behind
    ``if kinds.free_base is not None`` is typed as a constant branch that LLVM removes, and a
    function given a None kind as an argument drops that code when it compiles. A body of
    one segment on a fixed pivot has no BodyKinds (None: q̈ is one division,
    `single_segment_acceleration`). `body_kinds` makes them."""

    #: The body on a free base (on the ground, with its contacts).
    free_base: bool | None
    #: The body a tree, not a serial chain.
    tree: bool | None


def body_kinds(seg, n) -> BodyKinds | None:
    """The `BodyKinds` of the packed body ``seg`` with n coordinates, None for one segment on
    a fixed pivot."""
    if n == 1:
        return None
    return BodyKinds(switch(int(seg[0, SEG_COUNT_COLUMN]) != n),
                     switch(seg[0, SEG_SERIAL_COLUMN] == 0.0))


def ground_kinds(seg, n) -> BodyKinds | None:
    """The `BodyKinds` of the packed body ``seg`` with n coordinates when it is on the ground
    (a free base), else None: the argument of compiled code that has something to do only on
    the ground (its contacts)."""
    kinds = body_kinds(seg, n)
    return kinds if kinds is not None and kinds.free_base else None


def switch(flag) -> bool | None:
    """A compile-time switch of the compiled code: True when ``flag`` holds, else None."""
    return True if flag else None


@njit(cache=True, error_model="numpy", inline="always")
def tree_accelerations(y, n, kinds, muscle_torque, seg, joints, work):
    """`joint_accelerations` of a body of the `BodyKinds` ``kinds``, inlined into the step
    loops (`body_accelerations` elsewhere). Its base coordinates nb (0: fixed, 2: free) and
    ``serial`` (each segment's parent the one before it) are read off the kinds' types:
    ``x is None`` of a None or bool type compiles to a constant, which LLVM folds, so the
    code runs as fast as with literal constants (measured: a runtime ``nb`` or parent lookups
    in a serial chain made its solve 1.3–1.4x slower) and is typed once. (An inlined
    overload choosing among four solves by the kinds' types ran equally fast, but Numba
    typed its implementation at every pass of type inference, six times: the jump's loops
    compiled 1.4–1.5x slower, measured cold, 3 interleaved rounds.)"""
    nb = 0 if kinds.free_base is None else 2
    serial = kinds.tree is None
    n_seg = n - nb
    rhs = n * n
    sine = rhs + n
    cosine = sine + n
    speed = cosine + n
    for k in range(n_seg):
        i = nb + k
        o = i * JOINT_ROW_SIZE
        p = k - 1 if serial else int(seg[k, SEG_PARENT_COLUMN])
        phi = joints[o + ZERO_OFFSET] + y[i]
        phid = y[n + i]
        if p >= 0:  # parents come first: their φ is in work[nb + p] (M's first row, unused
            phi += work[nb + p]  # until M is filled below)
            phid += work[speed + nb + p]
        work[i] = phi
        work[sine + i] = math.sin(phi)
        work[cosine + i] = math.cos(phi)
        work[speed + i] = phid
        work[rhs + i] = muscle_torque[i] + passive_torque(y[i], joints, o)
    # Each joint torque's reaction on the parent (its children come later). A serial chain
    # (each parent the segment before) indexes without the parent column: the lookups made
    # its solve 1.3x slower.
    if serial:
        for k in range(n_seg - 1):
            work[rhs + nb + k] -= work[rhs + nb + k + 1]
    else:
        for k in range(n_seg):
            p = int(seg[k, SEG_PARENT_COLUMN])
            if p >= 0:
                work[rhs + nb + p] -= work[rhs + nb + k]
    for a in range(n_seg):  # gravity, and the diagonal of M
        i = nb + a
        work[rhs + i] -= seg[a, SEG_GRAVITY_COLUMN] * work[sine + i]
        work[i * n + i] = seg[a, SEG_INERTIA_COLUMN]
    for a in range(n_seg):  # each pair a < b once: M_ba, and c_a, c_b
        i = nb + a
        for b in range(a + 1, n_seg):
            j = nb + b
            # Λ_ab = 0 for unrelated segments (a tree's branches): their terms vanish
            d_ab = seg[a, SEG_LEVER_COLUMN + b] * seg[b, SEG_MOMENT_COLUMN]
            # sin and cos of φ_a − φ_b from those of φ_a and φ_b: 2n trig calls, not n²
            sin_ab = work[sine + i] * work[cosine + j] - work[cosine + i] * work[sine + j]
            work[j * n + i] = d_ab * (work[cosine + i] * work[cosine + j]
                                      + work[sine + i] * work[sine + j])
            work[rhs + i] -= d_ab * sin_ab * work[speed + j] * work[speed + j]
            work[rhs + j] += d_ab * sin_ab * work[speed + i] * work[speed + i]
    if nb == 2:
        _free_base_terms(y, n, n_seg, seg, work, kinds.free_base)
    # LDLᵀ in place: L below the diagonal, D on it.
    for j in range(n):
        d = work[j * n + j]
        for k in range(j):
            d -= work[j * n + k] * work[j * n + k] * work[k * n + k]
        work[j * n + j] = d
        for i in range(j + 1, n):
            v = work[i * n + j]
            for k in range(j):
                v -= work[i * n + k] * work[j * n + k] * work[k * n + k]
            work[i * n + j] = v / d
    for i in range(n):  # L·z = Q − c
        v = work[rhs + i]
        for k in range(i):
            v -= work[i * n + k] * work[rhs + k]
        work[rhs + i] = v
    for i in range(n - 1, -1, -1):  # D·Lᵀ·ẍ = z
        v = work[rhs + i] / work[i * n + i]
        for k in range(i + 1, n):
            v -= work[k * n + i] * work[rhs + k]
        work[rhs + i] = v
    for k in range(n_seg - 1, 0, -1):  # q̈_k = φ̈_k − φ̈_parent (parents come first)
        p = k - 1 if serial else int(seg[k, SEG_PARENT_COLUMN])
        work[rhs + nb + k] -= work[rhs + nb + p]


@njit(cache=True, error_model="numpy")
def body_accelerations(y, n, muscle_torque, seg, joints, work, kinds):
    """`joint_accelerations` for compiled callers outside the step loops, of a body of the
    `BodyKinds` ``kinds``: compiled (and cached) once per kinds, not inlined into each
    caller."""
    tree_accelerations(y, n, kinds, muscle_torque, seg, joints, work)


@njit(cache=True, error_model="numpy", inline="always")
def _inverse_effective_mass(n, work, rhs):
    """w = J·M⁻¹·Jᵀ for the direction J in work[rhs:rhs+n] (overwritten), by the LDLᵀ
    factorization of M left in work[:n²] by `joint_accelerations`."""
    w = 0.0
    for i in range(n):  # L·z = J
        v = work[rhs + i]
        for j in range(i):
            v -= work[i * n + j] * work[rhs + j]
        work[rhs + i] = v
    for i in range(n):  # zᵀ·D⁻¹·z
        w += work[rhs + i] * work[rhs + i] / work[i * n + i]
    return w


@njit(cache=True, error_model="numpy", inline="always")
def _point_direction(n, seg, work, row, k, vertical):
    """The generalized direction J of the vertical (else horizontal) velocity of contact
    ``row``'s point on segment k into work[n²:n²+n] (the trigonometry read from ``work``)."""
    rhs = n * n
    sine = rhs + n
    cosine = sine + n
    for i in range(n):
        work[rhs + i] = 0.0
    d = seg[row, CONTACT_DISTANCE]
    e = seg[row, CONTACT_OFFSET]
    i = 2 + k
    if vertical:
        work[rhs + 1] = 1.0
        work[rhs + i] = d * work[sine + i] + e * work[cosine + i]
    else:
        work[rhs] = 1.0
        work[rhs + i] = d * work[cosine + i] - e * work[sine + i]
    s = int(seg[k, SEG_PARENT_COLUMN])
    while s >= 0:
        lever = seg[s, SEG_LEVER_COLUMN + k]
        work[rhs + 2 + s] = lever * (work[sine + 2 + s] if vertical else work[cosine + 2 + s])
        s = int(seg[s, SEG_PARENT_COLUMN])


@njit(cache=True, error_model="numpy")
def contact_heights(y, n, seg, joints, heights, phi):
    """Height above the ground (m) of every contact point of the free-base body ``seg`` at
    the coordinates y[:n], into heights[c] (contact after contact): the kinematics of
    `_free_base_terms`' points alone (the base's y, then each ancestor's lever and the
    point's distance and offset on its segment), for the error-controlled loop's events
    (take-off and touchdown: a height changing sign). The absolute angles
    φ_k = q_k + offset + φ_parent go into the scratch ``phi`` (one per segment)."""
    n_seg = n - 2
    for k in range(n_seg):
        p = int(seg[k, SEG_PARENT_COLUMN])
        phi[k] = joints[(2 + k) * JOINT_ROW_SIZE + ZERO_OFFSET] + y[2 + k] \
            + (phi[p] if p >= 0 else 0.0)
    for c in range(n_seg, seg.shape[0]):
        k = int(seg[c, CONTACT_SEGMENT])
        height = y[1] - seg[c, CONTACT_DISTANCE] * math.cos(phi[k]) \
            + seg[c, CONTACT_OFFSET] * math.sin(phi[k])
        s = int(seg[k, SEG_PARENT_COLUMN])
        while s >= 0:
            height -= seg[s, SEG_LEVER_COLUMN + k] * math.cos(phi[s])
            s = int(seg[s, SEG_PARENT_COLUMN])
        heights[c - n_seg] = height


@njit(cache=True, error_model="numpy")
def contact_time_constant(y, n, seg, work):
    """Time constant τ = 1/|λ| (s) of the ground contacts together, for the stability guard,
    and the index (among the contacts) of the one that contributes most; (+inf, 0) off the
    ground. τ is the smaller of a normal and a friction time constant.

    Normal: each loaded point's vertical motion as a mass 1/w_c on the contact's spring
    ∂F_y/∂δ and damper ∂F_y/∂δ̇ (`contact_stiffness`), w_c = J_c·M⁻¹·J_cᵀ its inverse
    effective mass (J_c: the generalized direction of its vertical velocity); springs and
    dampers summed over the contacts as w_c·k_c and w_c·d_c (toe and heel on one foot act on
    nearly one motion, so their stiffnesses add), λ the larger root of
    λ² − Σw·d·λ + Σw·k = 0 in magnitude. Friction: the regularised Coulomb force is a damper
    on the point's horizontal velocity, ∂F_x/∂v_x = −μ·F_y·v_s²/(v_x² + v_s²)^{3/2}
    = −μ·F_y·(1 − ρ²)^{3/2}/v_s with ρ = |F_x|/(μ·F_y), so λ = Σ_c w_x,c·μ·F_y,c·(1 − ρ_c²)^{3/2}
    /v_s,c (the trace of W·D, an upper bound of its largest eigenvalue). On the squat jump
    the contacts' smallest τ over the run is 13 µs at v_s = 0.01 m/s, far below the normal
    force's.

    Call it right after `joint_accelerations` at the same state: it reads the factorization of
    M, the trigonometry and the contacts' forces and points left in ``work`` and overwrites
    the accelerations (the caller has copied them)."""
    n_seg = int(seg[0, SEG_COUNT_COLUMN])
    rhs = n * n
    damping = 0.0
    stiffness = 0.0
    friction = 0.0
    largest = 0.0
    index = 0
    for c in range(seg.shape[0] - n_seg):
        o = rhs + 4 * n + CONTACT_SLOTS * c  # `contacts_start`
        row = n_seg + c
        k = int(seg[row, CONTACT_SEGMENT])
        height = work[o + 3]
        if height >= 0.0:
            continue
        tangential, normal = work[o], work[o + 1]
        spring, damper = contact_stiffness(height, work[o + 4], seg, row)
        own = 0.0
        if spring > 0.0 or damper > 0.0:
            _point_direction(n, seg, work, row, k, True)
            w = _inverse_effective_mass(n, work, rhs)
            damping += w * damper
            stiffness += w * spring
            own = max(w * damper, math.sqrt(w * spring))
        slip_damper = friction_damping(tangential, normal, seg, row)
        if slip_damper > 0.0:
            _point_direction(n, seg, work, row, k, False)
            rate = _inverse_effective_mass(n, work, rhs) * slip_damper
            friction += rate
            own = max(own, rate)
        if own > largest:
            largest = own
            index = c
    disc = damping * damping - 4.0 * stiffness
    rate = 0.5 * (damping + math.sqrt(disc)) if disc >= 0.0 else math.sqrt(stiffness)
    rate = max(rate, friction)
    return (1.0 / rate if rate > 0.0 else np.inf), index



@njit(cache=True, error_model="numpy")
def body_jacobian_size(n):
    """Length of the scratch array of `force_jacobians` and the implicit body part for n
    coordinates: four n×n matrices (M, S, G and the iteration matrix), then 8 rows of n."""
    return 4 * n * n + 8 * n


@njit(cache=True, error_model="numpy")
def force_jacobians(y, n, seg, joints, work, jac):
    """The linearisation of the body's stiff forces at state ``y`` (docs/model.md §4, the
    implicit body part): into jac[0:n²] the mass matrix M, rebuilt from the LDLᵀ
    factorisation `joint_accelerations` left in ``work`` (M = L·D·Lᵀ), into jac[n²:2n²]
    S = ∂Q/∂X and into jac[2n²:3n²] G = ∂Q/∂Ẋ: the Jacobians of the generalized forces Q of
    the end stops and the ground contacts with respect to the absolute coordinates X and
    their speeds (row-major; row i: the force on X_i). The rest of Q (gravity, the velocity
    terms, the muscle torques) is left out: only what is stiff is linearised.

        end stop of joint k:  S += T_p'(q_k)·e_k·e_kᵀ   (e_k = ∂q_k/∂X: 1 at k, −1 at its
                                                         parent; `passive_stiffness`)
        contact c:            S += −K_n·(ρ·J_x + J_y)·J_yᵀ
                              G += −D_f·J_x·J_xᵀ − C_n·(ρ·J_x + J_y)·J_yᵀ

    J_x and J_y: the generalized directions of the point's horizontal and vertical velocity
    (`_point_direction`); K_n = ∂F_y/∂δ and C_n = ∂F_y/∂δ̇ (`contact_stiffness`);
    ρ = F_x/F_y (the friction force follows the normal one); D_f = −∂F_x/∂v_x
    (`friction_damping`). Call right after `joint_accelerations` at ``y``: this overwrites
    the accelerations in ``work`` (the caller has copied them)."""
    n_seg = int(seg[0, SEG_COUNT_COLUMN])
    nb = n - n_seg
    nn = n * n
    rhs = nn
    for i in range(n):
        for j in range(n):
            m = 0.0
            for k in range(min(i, j) + 1):
                left = 1.0 if k == i else work[i * n + k]
                right = 1.0 if k == j else work[j * n + k]
                m += left * work[k * n + k] * right
            jac[i * n + j] = m
            jac[nn + i * n + j] = 0.0
            jac[2 * nn + i * n + j] = 0.0
    for k in range(n_seg):
        i = nb + k
        stiffness = passive_stiffness(y[i], joints, i * JOINT_ROW_SIZE)
        p = int(seg[k, SEG_PARENT_COLUMN])
        jac[nn + i * n + i] += stiffness
        if p >= 0:
            a = nb + p
            jac[nn + a * n + a] += stiffness
            jac[nn + i * n + a] -= stiffness
            jac[nn + a * n + i] -= stiffness
    jx = 4 * nn  # the point's directions, J_x then J_y
    jy = jx + n
    for c in range(seg.shape[0] - n_seg):
        o = rhs + 4 * n + CONTACT_SLOTS * c  # `contacts_start`
        row = n_seg + c
        tangential, normal, height = work[o], work[o + 1], work[o + 3]
        if height >= 0.0 or normal <= 0.0:
            continue
        spring, damper = contact_stiffness(height, work[o + 4], seg, row)
        slip_damper = friction_damping(tangential, normal, seg, row)
        ratio = tangential / normal
        k = int(seg[row, CONTACT_SEGMENT])
        _point_direction(n, seg, work, row, k, False)
        for i in range(n):
            jac[jx + i] = work[rhs + i]
        _point_direction(n, seg, work, row, k, True)
        for i in range(n):
            jac[jy + i] = work[rhs + i]
        for i in range(n):
            lever = ratio * jac[jx + i] + jac[jy + i]
            for j in range(n):
                jac[nn + i * n + j] -= spring * lever * jac[jy + j]
                jac[2 * nn + i * n + j] -= slip_damper * jac[jx + i] * jac[jx + j] \
                    + damper * lever * jac[jy + j]

#: What `ground_outputs` returns per state: total ground reaction force F_x, F_y (N) and
#: the centre of mass x, y (m).
GROUND_OUTPUTS = ("grf_x", "grf_y", "com_x", "com_y")


@njit(cache=True, error_model="numpy")
def ground_outputs(y, n, seg, joints, muscle_torque, work, out, kinds):
    """The total ground reaction force and the centre of mass of a body on a free base at
    state ``y`` into out[0:4] (`GROUND_OUTPUTS`), for the fit's compiled residual:

        F = Σ_contacts F_c,    x_CoM = x_base + Σ_a B_a·u(φ_a) / m,   u(φ) = (sin φ, −cos φ)

    (B_a: first moment of segment a and everything distal to it about a's proximal joint,
    the same as in the free base's rows of M). Runs `body_accelerations` at ``y`` for the
    contact forces and the trigonometry; ``muscle_torque`` (n, zeros) and ``work`` are
    scratch; ``kinds`` its `BodyKinds`."""
    body_accelerations(y, n, muscle_torque, seg, joints, work, kinds)
    n_seg = int(seg[0, SEG_COUNT_COLUMN])
    nb = n - n_seg
    sine = n * n + n
    cosine = sine + n
    o = contacts_start(n)
    fx = 0.0
    fy = 0.0
    for c in range(seg.shape[0] - n_seg):
        fx += work[o + CONTACT_SLOTS * c]
        fy += work[o + CONTACT_SLOTS * c + 1]
    mass = seg[0, SEG_MASS_COLUMN]
    cx = y[0]
    cy = y[1]
    for a in range(n_seg):
        cx += seg[a, SEG_MOMENT_COLUMN] * work[sine + nb + a] / mass
        cy -= seg[a, SEG_MOMENT_COLUMN] * work[cosine + nb + a] / mass
    out[0], out[1], out[2], out[3] = fx, fy, cx, cy
