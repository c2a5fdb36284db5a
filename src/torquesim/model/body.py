"""The body: rigid segments in a planar open chain hanging from a fixed pivot (docs/model.md
§1 and §7): the elbow's parameters (`BodyParameters`), the joints' end stops, and the chain's
equations of motion M(q)·q̈ = τ + T_p(q) − h(q, q̇) written once (`joint_accelerations`), with
the one-segment case as a division (`single_segment_acceleration`), the abstract's Eq. 1

    I_E · dω/dt = T_net + T_p(θ) − (m_t·g·l1 + m_db·g·l2)·sin θ.

Angles are joint flexion in rad (0 = the segment hanging straight on, at the elbow full
extension).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from numba import njit

from ..errors import ModelError, check_range

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


#: Column of a packed joint row holding the angle offset added to q_k in φ_k (the chain's
#: base angle for the first joint, 0 for the others), and the joint row size.
ZERO_OFFSET = ENDSTOP_HIGH + 1
#: Column of a packed joint row holding the largest physically possible joint speed, rad/s.
SPEED_LIMIT = ZERO_OFFSET + 1
JOINT_ROW_SIZE = SPEED_LIMIT + 1
#: Columns of the packed segment array (torquesim.model.chain.ChainModel.segment_array).
SEG_INERTIA_COLUMN, SEG_MOMENT_COLUMN, SEG_LENGTH_COLUMN, SEG_GRAVITY_COLUMN = range(4)


@njit(cache=True, error_model="numpy", inline="always")
def single_segment_acceleration(q, muscle_torque, seg, joints):
    """q̈ of a one-segment chain, rad/s²: M is the scalar A_1, so `joint_accelerations`
    reduces to one division, docs/model.md's

        I_E·dω/dt = T_net + T_p(θ) − G·sin θ      (abstract Eq. 1 with end stops)

    with the same arithmetic as the general solve (tested). Loop-free, so the solvers inline
    it into their step loops at no cost."""
    return (muscle_torque + passive_torque(q, joints, 0)
            - seg[0, SEG_GRAVITY_COLUMN] * math.sin(joints[ZERO_OFFSET] + q)) \
        / seg[0, SEG_INERTIA_COLUMN]


@njit(cache=True, error_model="numpy")
def body_work_size(n):
    """Length of the scratch array `joint_accelerations` needs for n segments."""
    return n * n + 4 * n


@njit(cache=True, error_model="numpy", inline="always")
def joint_accelerations(y, n, muscle_torque, seg, joints, work):
    """q̈ of a planar open chain (docs/model.md §1), rad/s², into work[n²:n²+n]; q = y[:n],
    q̇ = y[n:2n]:

        M(φ)·φ̈ + c(φ, φ̇) + g(φ) = Q,    φ_k = Σ_{i≤k}(offset_i + q_i)

    in absolute angles φ, with M_kk = A_k, M_jk = L_j·B_k·cos(φ_j − φ_k) (j < k),
    c_j = Σ_{k≠j} D_jk·sin(φ_j − φ_k)·φ̇_k² (D_jk = L_min(j,k)·B_max(j,k)),
    g_j = g·B_j·sin φ_j, and the generalized forces Q_j = τ_j − τ_{j+1} of the joint torques
    τ_j = muscle_torque_j + T_p(q_j) (end stops); then q̈_k = φ̈_k − φ̈_{k−1}. Solved by an
    LDLᵀ factorization of M (symmetric positive definite).

    ``seg``: (n, 4) segment array of `ChainModel.segment_array`; ``joints``: the flat
    joint rows (end stops, zero offset); ``work``: flat scratch of n² + 4n, which holds q̈ at
    the end (no output array: the solvers' step loops pay for every array argument).
    """
    rhs = n * n
    sine = rhs + n
    cosine = sine + n
    speed = cosine + n
    phi = 0.0
    phid = 0.0
    for k in range(n):
        o = k * JOINT_ROW_SIZE
        phi += joints[o + ZERO_OFFSET] + y[k]
        phid += y[n + k]
        work[sine + k] = math.sin(phi)
        work[cosine + k] = math.cos(phi)
        work[speed + k] = phid
        work[rhs + k] = muscle_torque[k] + passive_torque(y[k], joints, o)
    for j in range(n - 1):  # Q_j = τ_j − τ_{j+1}
        work[rhs + j] -= work[rhs + j + 1]
    for j in range(n):  # gravity, and the diagonal of M
        work[rhs + j] -= seg[j, SEG_GRAVITY_COLUMN] * work[sine + j]
        work[j * n + j] = seg[j, SEG_INERTIA_COLUMN]
    for j in range(n):  # each pair j < k once: M_kj, and c_j, c_k (sin is antisymmetric)
        for k in range(j + 1, n):
            d_jk = seg[j, SEG_LENGTH_COLUMN] * seg[k, SEG_MOMENT_COLUMN]
            # sin and cos of φ_j − φ_k from those of φ_j and φ_k: 2n trig calls, not n²
            sin_jk = work[sine + j] * work[cosine + k] - work[cosine + j] * work[sine + k]
            work[k * n + j] = d_jk * (work[cosine + j] * work[cosine + k]
                                      + work[sine + j] * work[sine + k])
            work[rhs + j] -= d_jk * sin_jk * work[speed + k] * work[speed + k]
            work[rhs + k] += d_jk * sin_jk * work[speed + j] * work[speed + j]
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
    for i in range(n):  # L·z = Q − c − g
        v = work[rhs + i]
        for k in range(i):
            v -= work[i * n + k] * work[rhs + k]
        work[rhs + i] = v
    for i in range(n - 1, -1, -1):  # D·Lᵀ·φ̈ = z
        v = work[rhs + i] / work[i * n + i]
        for k in range(i + 1, n):
            v -= work[k * n + i] * work[rhs + k]
        work[rhs + i] = v
    for k in range(n - 1, 0, -1):
        work[rhs + k] -= work[rhs + k - 1]
