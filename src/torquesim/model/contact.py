"""Named points on segments and their contact with the ground line y = 0 (docs/model.md §9).

A point sits on a segment at ``distance`` along its axis from its proximal joint and
``offset`` perpendicular to it (positive on the side the segment's angle turns towards, i.e.
forwards, +x, when the segment hangs straight down). A ground contact at a point pushes when
the point is below the ground, with penetration δ = −y ≥ 0 and its rate δ̇ = −ẏ:

    normal      F_y = max(0, k·δⁿ·(1 + c·δ̇))                     (Hunt & Crossley 1975)
    tangential  F_x = −μ·F_y·v_x / √(v_x² + v_s²)                   (regularised Coulomb)

with v_x the point's horizontal velocity. F_y never pulls (the max), and F_x never exceeds
μ·F_y; both vanish as soon as the point leaves the ground.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import check_name
from .fields import Allowed, check_fields
from .jit import njit

#: Columns of a packed contact row (`ChainModel.segment_array`, after the segment rows).
(CONTACT_SEGMENT, CONTACT_DISTANCE, CONTACT_OFFSET, CONTACT_STIFFNESS, CONTACT_EXPONENT,
 CONTACT_DAMPING, CONTACT_FRICTION, CONTACT_SLIP_SPEED) = range(8)
CONTACT_ROW_SIZE = 8

#: The allowed values of a point's numbers and of a ground contact's (`Allowed`).
POINT_FIELDS = {
    "distance": Allowed("m", "along the segment axis from its proximal joint", -10.0, 10.0),
    "offset": Allowed("m", "perpendicular to the axis (+: forwards when hanging)", -10.0, 10.0),
}
CONTACT_FIELDS = {
    "stiffness": Allowed("N/m^n", "k of k*depth^n*(1 + c*depth_rate)", 0.0, 1e9,
                         low_open=True),
    "exponent": Allowed("", "n (1.5: Hertz)", 1.0, 3.0),
    "damping": Allowed("s/m", "c (Hunt-Crossley)", 0.0, 100.0),
    "friction": Allowed("", "mu of the regularised Coulomb friction", 0.0, 5.0),
    "slip_speed": Allowed("m/s", "v_s of the friction regularisation", 1e-3, 1.0),
}


@dataclass(frozen=True)
class Point:
    """A named point fixed on a segment (toe, heel, hip…), reported in the results.

    Attributes
    ----------
    name : str
    segment : str
        Name of the segment it is fixed on.
    distance : float
        Along the segment axis from its proximal joint, m. Bounds [-10, 10].
    offset : float
        Perpendicular to the axis, m, positive forwards (+x) when the segment hangs straight
        down. Default 0. Bounds [-10, 10].
    """

    name: str
    segment: str
    distance: float
    offset: float = 0.0

    def __post_init__(self) -> None:
        check_name("name", self.name)
        check_name("segment", self.segment)
        check_fields(self, POINT_FIELDS)


@dataclass(frozen=True)
class GroundContact:
    """A compliant contact of a point with the ground line y = 0 (module docstring).

    Attributes
    ----------
    point : str
        Name of the point in contact.
    stiffness : float
        k, N/mⁿ. Bounds (0, 1e9]. Default 5e6: with n = 1.5 a 70 kg body standing on two
        such points sinks 1.7 mm. A model refuses contacts so soft that its body, the weight
        shared alike, would sink more than `chain.MAX_STANDING_SINK` (5 cm) standing.
    exponent : float
        n. Default 1.5 (Hertzian contact). Bounds [1, 3].
    damping : float
        c, s/m (Hunt & Crossley 1975, J Appl Mech 42:440). Default 1.0: a landing at 1 m/s
        doubles the spring force. Bounds [0, 100].
    friction : float
        μ. Default 0.8 (a shoe sole on a floor). Bounds [0, 5].
    slip_speed : float
        v_s, m/s: the slip speed under which friction is regularised. Default 0.1: smaller
        is closer to Coulomb's stick but stiffer, the friction's time constant being about
        m_eff·v_s/(μ·F_y) (m_eff: the point's effective mass horizontally). Measured on the
        squat jump (docs/model.md §9): the toe creeps 3.9 mm during the push-off at 0.1 m/s
        (0.25 mm at 0.01), and the contacts' smallest time constant over it is 0.13 ms (13 µs at
        0.01). Bounds [0.001, 1]: at a slower slip speed the friction's time constant on a
        body of human size falls below about 1 µs, and with it the step of every technique
        (the contacts are explicit in each).
    """

    point: str
    stiffness: float = 5.0e6
    exponent: float = 1.5
    damping: float = 1.0
    friction: float = 0.8
    slip_speed: float = 0.1

    def __post_init__(self) -> None:
        check_fields(self, CONTACT_FIELDS)
        check_name("point", self.point)


@njit(cache=True, error_model="numpy", inline="always")
def contact_force(height, vertical_speed, horizontal_speed, rows, c):
    """(F_x, F_y), N, of the contact in packed row ``rows[c]`` at a point at ``height`` (m)
    moving at (``horizontal_speed``, ``vertical_speed``) m/s (module docstring)."""
    depth = -height
    if depth <= 0.0:
        return 0.0, 0.0
    normal = rows[c, CONTACT_STIFFNESS] * depth ** rows[c, CONTACT_EXPONENT] \
        * (1.0 - rows[c, CONTACT_DAMPING] * vertical_speed)
    if normal <= 0.0:
        return 0.0, 0.0
    slip = rows[c, CONTACT_SLIP_SPEED]
    tangential = -rows[c, CONTACT_FRICTION] * normal * horizontal_speed \
        / math.sqrt(horizontal_speed * horizontal_speed + slip * slip)
    return tangential, normal


@njit(cache=True, error_model="numpy", inline="always")
def contact_stiffness(height, vertical_speed, rows, c):
    """(∂F_y/∂δ in N/m, ∂F_y/∂δ̇ in N·s/m) of the contact's normal force at ``height``: the
    spring and damper the stability guard sees (0, 0 off the ground)."""
    depth = -height
    if depth <= 0.0:
        return 0.0, 0.0
    n = rows[c, CONTACT_EXPONENT]
    spring = rows[c, CONTACT_STIFFNESS] * depth ** n
    damping = rows[c, CONTACT_DAMPING]
    if spring * (1.0 - damping * vertical_speed) <= 0.0:
        return 0.0, 0.0
    return n * spring / depth * (1.0 - damping * vertical_speed), spring * damping


@njit(cache=True, error_model="numpy", inline="always")
def friction_damping(tangential, normal, rows, c):
    """−∂F_x/∂v_x (N·s/m, ≥ 0) of the regularised Coulomb friction of the contact in row
    ``rows[c]`` carrying the forces (``tangential``, ``normal``) N: with ρ = |F_x|/(μ·F_y),
    μ·F_y·v_s²/(v_x² + v_s²)^{3/2} = μ·F_y·(1 − ρ²)^{3/2}/v_s (0 off the ground or with
    μ = 0). The damper the stability guard and the implicit body part see."""
    mu = rows[c, CONTACT_FRICTION]
    if normal <= 0.0 or mu <= 0.0:
        return 0.0
    ratio = min(abs(tangential) / (mu * normal), 1.0)
    return mu * normal * (1.0 - ratio * ratio) ** 1.5 / rows[c, CONTACT_SLIP_SPEED]


def take_off_index(grf_y: np.ndarray, threshold: float = 0.0) -> int | None:
    """The first sample whose vertical ground reaction force (N) is at or below ``threshold``
    after one above it (None: the body never leaves the ground). A simulation's force is 0 in
    flight (threshold 0); a measured one is noisy (a threshold such as 1 % of body weight)."""
    loaded = grf_y > threshold
    off = np.flatnonzero(~loaded & np.maximum.accumulate(loaded))
    return int(off[0]) if off.size else None
