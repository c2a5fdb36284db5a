"""The body: forearm + hand + dumbbell turning about a fixed elbow (MODEL.md §1).

    I_E · dω/dt = T_net + T_p(θ) − (m_t·g·l1 + m_db·g·l2)·sin θ          (abstract Eq. 1)

θ is elbow flexion (0 = full extension, forearm hanging down), in rad.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np
from numba import njit

from ..errors import ModelError, check_range

# Layout of a packed end-stop array (a chain joint's row, torquesim.model.chain), and of the
# elbow's packed body array, which adds the inertia and gravity coefficient.
ENDSTOP_TORQUE, ENDSTOP_SCALE, ENDSTOP_LOW, ENDSTOP_HIGH, INERTIA, GRAVITY_TORQUE = range(6)
BODY_ARRAY_SIZE = 6


@dataclass(frozen=True)
class BodyParameters:
    """Anthropometry of the moving segment and the dumbbell, and the passive end stops.

    Defaults are MODEL.md §1 (de Leva 1996, reference male 73 kg; 5 kg dumbbell).

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
        check_range("gravity", self.gravity, 0.0, unit="m/s^2")
        check_range("segment_mass", self.segment_mass, **pos, unit="kg")
        check_range("segment_com_distance", self.segment_com_distance, **pos, unit="m")
        check_range("segment_inertia", self.segment_inertia, **pos, unit="kg·m^2")
        check_range("dumbbell_mass", self.dumbbell_mass, 0.0, unit="kg")
        check_range("dumbbell_distance", self.dumbbell_distance, **pos, unit="m")
        check_range("dumbbell_inertia", self.dumbbell_inertia, 0.0, unit="kg·m^2")
        check_range("endstop_torque", self.endstop_torque, 0.0, unit="N·m")
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

    def to_array(self) -> np.ndarray:
        """Pack into the float array read by the compiled functions."""
        p = np.zeros(BODY_ARRAY_SIZE)
        p[INERTIA] = self.elbow_inertia
        p[GRAVITY_TORQUE] = self.gravity_torque_coefficient
        p[ENDSTOP_TORQUE] = self.endstop_torque
        p[ENDSTOP_SCALE] = self.endstop_angle_scale
        p[ENDSTOP_LOW] = self.endstop_lower_angle
        p[ENDSTOP_HIGH] = self.endstop_upper_angle
        return p


@njit(cache=True, error_model="numpy")
def passive_torque(theta, b):
    """End-stop torque T_p(θ) = k_p·[exp((θ_lo − θ)/s_p) − exp((θ − θ_hi)/s_p)], N·m."""
    s = b[ENDSTOP_SCALE]
    return b[ENDSTOP_TORQUE] * (math.exp((b[ENDSTOP_LOW] - theta) / s)
                                - math.exp((theta - b[ENDSTOP_HIGH]) / s))


@njit(cache=True, error_model="numpy")
def passive_energy(theta, b):
    """Potential V_p(θ) of the end stops, J, with −dV_p/dθ = T_p(θ)."""
    s = b[ENDSTOP_SCALE]
    return b[ENDSTOP_TORQUE] * s * (math.exp((b[ENDSTOP_LOW] - theta) / s)
                                    + math.exp((theta - b[ENDSTOP_HIGH]) / s))


#: Column of the packed joint array holding the angle offset added to q_k in φ_k (the chain's
#: base angle for the first joint, 0 for the others).
ZERO_OFFSET = 4


@njit(cache=True, error_model="numpy", inline="always")
def joint_accelerations(q, qd, muscle_torque, seg, jnt, work, qdd):
    """q̈ (rad/s², into ``qdd``) of a planar open chain (docs/model.md §1):

        M(φ)·φ̈ + c(φ, φ̇) + g(φ) = Q,    φ_k = Σ_{i≤k}(offset_i + q_i)

    in absolute angles φ, with M_kk = A_k, M_jk = L_j·B_k·cos(φ_j − φ_k) (j < k),
    c_j = Σ_{k≠j} D_jk·sin(φ_j − φ_k)·φ̇_k² (D_jk = L_min(j,k)·B_max(j,k)),
    g_j = g·B_j·sin φ_j, and the generalized forces Q_j = τ_j − τ_{j+1} of the joint torques
    τ_j = muscle_torque_j + T_p(q_j) (end stops); then q̈_k = φ̈_k − φ̈_{k−1}. Solved by an
    LDLᵀ factorization of M (symmetric positive definite). For one segment this is
    MODEL.md's I_E·dω/dt = T_net + T_p(θ) − G·sin θ, with the same arithmetic.

    ``seg``: (n, 4) segment array of :meth:`ChainModel.segment_array`; ``jnt``: (n, 5)
    end stops and zero offset; ``work``: (n, n + 4) scratch.
    """
    n = q.shape[0]
    phi = 0.0
    phid = 0.0
    rhs = n
    angle = n + 1
    speed = n + 2
    passive = n + 3
    for k in range(n):
        phi += jnt[k, ZERO_OFFSET] + q[k]
        phid += qd[k]
        work[k, angle] = phi
        work[k, speed] = phid
        work[k, passive] = muscle_torque[k] + passive_torque(q[k], jnt[k])
    for j in range(n):
        force = work[j, passive]
        if j + 1 < n:
            force -= work[j + 1, passive]
        coriolis = 0.0
        for k in range(n):
            if k != j:
                lo, hi = (j, k) if j < k else (k, j)
                d_jk = seg[lo, 2] * seg[hi, 1]
                diff = work[j, angle] - work[k, angle]
                coriolis += d_jk * math.sin(diff) * work[k, speed] * work[k, speed]
                if k > j:
                    work[k, j] = d_jk * math.cos(diff)  # M_kj, lower triangle
        work[j, rhs] = force - coriolis - seg[j, 3] * math.sin(work[j, angle])
        work[j, j] = seg[j, 0]
    # LDLᵀ in place: L below the diagonal, D on it.
    for j in range(n):
        d = work[j, j]
        for k in range(j):
            d -= work[j, k] * work[j, k] * work[k, k]
        work[j, j] = d
        for i in range(j + 1, n):
            v = work[i, j]
            for k in range(j):
                v -= work[i, k] * work[j, k] * work[k, k]
            work[i, j] = v / d
    for i in range(n):  # L·z = rhs
        v = work[i, rhs]
        for k in range(i):
            v -= work[i, k] * work[k, rhs]
        work[i, rhs] = v
    for i in range(n - 1, -1, -1):  # D·Lᵀ·x = z
        v = work[i, rhs] / work[i, i]
        for k in range(i + 1, n):
            v -= work[k, i] * work[k, rhs]
        work[i, rhs] = v
    previous = 0.0
    for k in range(n):
        qdd[k] = work[k, rhs] - previous
        previous = work[k, rhs]
