"""A planar open chain of rigid segments driven by torque generator units (docs/model.md §1).

The chain hangs from a fixed base, proximal to distal. Joint k is the proximal joint of
segment k; its angle q_k is relative (segment k against segment k − 1, or against the base),
0 = straight/hanging in line with the previous segment, positive = flexion. The absolute angle
of segment k from hanging straight down is

    φ_k = base_angle + q_1 + … + q_k

(``base_angle`` = 0: the first segment hangs straight down at q_1 = 0, as the elbow's forearm).

Each torque generator unit acts on one joint with a direction d = +1 (flexor, pulls towards
positive q) or −1 (extensor). The state used everywhere is

    y = (q_1 … q_n, q̇_1 … q̇_n, θ_cc of every unit)

in rad and rad/s; the units are rows of one array, in the order they are listed.
The elbow of docs/model.md is the one-segment chain with one flexor and one extensor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ..errors import ModelError, check_name
from .activation import ActivationDynamics, ActivationProfile
from .body import (
    ENDSTOP_HIGH,
    ENDSTOP_LOW,
    ENDSTOP_SCALE,
    ENDSTOP_TORQUE,
    JOINT_ROW_SIZE,
    SEG_COUNT_COLUMN,
    SEG_GRAVITY_COLUMN,
    SEG_INERTIA_COLUMN,
    SEG_LEVER_COLUMN,
    SEG_MASS_COLUMN,
    SEG_MOMENT_COLUMN,
    SEG_PARENT_COLUMN,
    SEG_SERIAL_COLUMN,
    SEG_WEIGHT_COLUMN,
    SPEED_LIMIT,
    ZERO_OFFSET,
    passive_torque,
)
from .contact import (
    CONTACT_DAMPING,
    CONTACT_DISTANCE,
    CONTACT_EXPONENT,
    CONTACT_FRICTION,
    CONTACT_OFFSET,
    CONTACT_ROW_SIZE,
    CONTACT_SEGMENT,
    CONTACT_SLIP_SPEED,
    CONTACT_STIFFNESS,
    GroundContact,
    Point,
)
from .fields import Allowed, check_fields
from .state import UNIT_STATE_WIDTHS, StateLayout
from .torque_generator import (
    ACTIVATION_FLOOR,
    H_ISOMETRIC,
    K_SE,
    TorqueGeneratorUnit,
    torque_angle,
)
from .unit_row import (  # noqa: F401  (the packed unit row, read here as chain.UNIT_*)
    UNIT_ACTIVATION_TIME,
    UNIT_DEACTIVATION_TIME,
    UNIT_DIRECTION,
    UNIT_JOINT,
    UNIT_ROW_SIZE,
    UNIT_SECOND_ARM,
    UNIT_SECOND_JOINT,
    UNIT_STATE_OFFSET,
)

MAX_SEGMENTS = 16
#: Columns of the packed segment array (see `ChainModel.segment_array`).
SEG_INERTIA, SEG_MOMENT, SEG_GRAVITY = SEG_INERTIA_COLUMN, SEG_MOMENT_COLUMN, SEG_GRAVITY_COLUMN
#: The base kinds: a fixed pivot, or free (x, y of the first segment's proximal point and its
#: absolute angle are coordinates, and the body stands on its ground contacts).
BASES = ("fixed", "free")
#: Coordinates of a free base, m: the first segment's proximal point.
BASE_COORDINATES = ("base_x", "base_y")
#: Output columns the model itself names (the time, the free base, the centre of mass, the total
#: ground force and its centre of pressure): no joint, unit, point or contact may name a column
#: so, whether or not this model has them (`ChainModel.output_columns`).
RESERVED_COLUMNS = ("time", *BASE_COORDINATES, *(f"{c}_speed" for c in BASE_COORDINATES),
                    "com_x", "com_y", "com_speed_x", "com_speed_y", "grf_x", "grf_y", "cop_x")
#: Speed limit of a free base's coordinates, m/s (faster is a numerical failure).
BASE_SPEED_LIMIT = 100.0
JOINT_ARRAY_SIZE = JOINT_ROW_SIZE  # end stops, zero offset, speed limit (model.body)
FLEXOR, EXTENSOR = 1, -1
#: Largest |moment arm ratio| of a two-joint unit at its second joint (`Unit.second_arm`).
MAX_SECOND_ARM = 2.0
#: A joint speed above this many times its fastest unit's ω_max is physically impossible.
SPEED_LIMIT_FACTOR = 10.0


#: Deepest a body may sink into the ground standing on its contacts, m (a soft mat: a few cm);
#: softer contacts than that are not a floor.
MAX_STANDING_SINK = 0.05
#: Upper bounds of body parameters: far beyond any human segment, finite so that no value can
#: overflow the mechanics (kg, m, kg·m²).
MAX_MASS, MAX_LENGTH, MAX_INERTIA = 1000.0, 10.0, 1.0e4

#: The allowed values of a point load's, a segment's and a joint's numbers, of a two-joint
#: unit's arm and of the model's own numbers (`Allowed`).
LOAD_FIELDS = {
    "mass": Allowed("kg", "", 0.0, MAX_MASS),
    "distance": Allowed("m", "from the segment's proximal joint along its axis", 0.0,
                        MAX_LENGTH),
    "inertia": Allowed("kg·m^2", "about its own centre", 0.0, MAX_INERTIA),
}
SEGMENT_FIELDS = {
    "mass": Allowed("kg", "", 0.0, MAX_MASS, low_open=True),
    "com_distance": Allowed("m", "proximal joint to centre of mass", 0.0, MAX_LENGTH),
    "inertia_about_joint": Allowed("kg·m^2", "about the proximal joint, loads excluded", 0.0,
                                   MAX_INERTIA, low_open=True),
    "length": Allowed("m", "proximal joint to the next joint", 0.0, MAX_LENGTH),
    "parent_distance": Allowed("m", "where its joint sits along the parent's axis",
                               -MAX_LENGTH, MAX_LENGTH, optional=True),
}
JOINT_FIELDS = {
    "initial_angle": Allowed("rad", "0 = straight/hanging, positive = the joint's positive "
                             "motion (default flexion)", -math.pi, math.pi),
    "initial_speed": Allowed("rad/s", "joint angular velocity at t = 0 (0 = at rest)", -100.0,
                             100.0),
    "endstop_torque": Allowed("N·m", "passive end-stop scale k_p (0 = none)", 0.0, 1e5),
    "endstop_angle_scale": Allowed("rad", "end-stop angular scale s_p", 0.0, math.inf,
                                   low_open=True, high_open=True),
    "endstop_lower_angle": Allowed("rad", "q_lo", -math.pi, 2 * math.pi),
    "endstop_upper_angle": Allowed("rad", "q_hi", (1.0, "endstop_lower_angle"), 2 * math.pi,
                                   low_open=True),
}
UNIT_GEOMETRY_FIELDS = {
    "second_arm": Allowed("", "its moment arm there relative to the one at joint, signed (+: "
                          "towards that joint's positive way)", -MAX_SECOND_ARM,
                          MAX_SECOND_ARM),
}
CHAIN_FIELDS = {
    "gravity": Allowed("m/s^2", "", 0.0, 100.0),
    "base_angle": Allowed("rad", "first joint's zero direction from hanging down", -math.pi,
                          math.pi),
    "duration": Allowed("s", "simulated time", 0.0, 600.0, low_open=True),
    "landing_speed": Allowed("m/s", "a landing: starts at touchdown, moving down at this speed "
                             "(free base; 0 = standing)", 0.0, 10.0),
}


@dataclass(frozen=True)
class PointLoad:
    """A mass carried rigidly by a segment on its axis (a dumbbell, an ankle weight).

    Attributes
    ----------
    name : str
    mass : float
        kg. Bounds [0, 1e3].
    distance : float
        From the segment's proximal joint along the segment axis, m. Bounds [0, 10].
    inertia : float
        Its own moment of inertia about its own centre, kg·m². Default 0. Bounds [0, 1e4].
    """

    name: str
    mass: float
    distance: float
    inertia: float = 0.0

    def __post_init__(self) -> None:
        check_name("name", self.name)
        check_fields(self, LOAD_FIELDS)


@dataclass(frozen=True)
class Segment:
    """A rigid segment, with the point loads it carries.

    Attributes
    ----------
    name : str
    mass : float
        kg. Bounds (0, 1e3].
    com_distance : float
        Proximal joint → centre of mass, along the segment axis, m. Bounds [0, 10].
    inertia_about_joint : float
        Moment of inertia about the proximal joint axis (not about the centre of mass), loads
        excluded, kg·m². Bounds (0, 1e4]; at least mass·com_distance² (parallel axes).
    length : float
        Proximal joint → next joint, m (unused for the last segment). Bounds [0, 10].
    loads : tuple of PointLoad
    parent : str
        Name of the segment its proximal joint sits on; "" (default): the segment before it
        in the model's list (the base for the first), which makes a serial chain. Several
        segments may share a parent (a tree: two legs on one pelvis).
    parent_distance : float or None
        Where its proximal joint sits on the parent: distance along the parent's axis from the
        parent's proximal joint, m. None (default): the parent's ``length``. Bounds [-10, 10].
    """

    name: str
    mass: float
    com_distance: float
    inertia_about_joint: float
    length: float = 0.0
    loads: tuple[PointLoad, ...] = ()
    parent: str = ""
    parent_distance: float | None = None

    def __post_init__(self) -> None:
        check_name("name", self.name)
        values = check_fields(self, SEGMENT_FIELDS)
        m, c, inertia = values["mass"], values["com_distance"], values["inertia_about_joint"]
        if not isinstance(self.parent, str):
            raise ModelError("parent", "must be a segment name or \"\"")
        if inertia < m * c * c * (1.0 - 1e-12):
            raise ModelError("inertia_about_joint", f"{inertia!r} is below mass·com_distance² "
                             f"= {m * c * c:.6g}; allowed ≥ that (parallel-axis theorem)")
        object.__setattr__(self, "loads", tuple(self.loads))
        names = set()
        for i, load in enumerate(self.loads):
            if not isinstance(load, PointLoad):
                raise ModelError(f"loads[{i}]", "must be a PointLoad(name, mass, distance, "
                                 "inertia)")
            if load.name in names:
                raise ModelError(f"loads[{i}].name", f"{load.name!r} is used twice; allowed: "
                                 "unique names")
            names.add(load.name)

    @property
    def extent(self) -> float:
        """How far the segment reaches from its proximal joint, m: its length, or for a last
        segment (length 0) twice its centre-of-mass distance or its farthest load."""
        return max([self.length, 2.0 * self.com_distance,
                    *(load.distance for load in self.loads)])

    @property
    def total_mass(self) -> float:
        """Segment and loads, kg."""
        return self.mass + sum(load.mass for load in self.loads)

    @property
    def first_moment(self) -> float:
        """m·c + Σ m_load·d_load about the proximal joint, kg·m."""
        out = self.mass * self.com_distance
        for load in self.loads:
            out += load.mass * load.distance
        return out

    @property
    def inertia_with_loads(self) -> float:
        """Moment of inertia about the proximal joint, loads included, kg·m²."""
        out = self.inertia_about_joint
        for load in self.loads:
            out = out + load.mass * load.distance**2 + load.inertia
        return out


#: What a joint's growing angle can be, as a biomechanist names it (`Joint.positive`).
POSITIVE_MOTIONS = ("flexion", "extension", "dorsiflexion", "plantarflexion", "abduction",
                    "adduction", "counterclockwise")
#: The motion opposite each one (a shrinking angle).
OPPOSITE_MOTIONS = {"flexion": "extension", "extension": "flexion",
                    "dorsiflexion": "plantarflexion", "plantarflexion": "dorsiflexion",
                    "abduction": "adduction", "adduction": "abduction",
                    "counterclockwise": "clockwise"}


@dataclass(frozen=True)
class Joint:
    """A hinge joint and its passive end stops (docs/model.md §1 form).

        T_p(q) = k_p·[exp((q_lo − q)/s_p) − exp((q − q_hi)/s_p)]

    Attributes
    ----------
    name : str
    initial_angle : float
        q at t = 0, rad (0 = straight in line with the previous segment; positive: see
        ``positive``). Bounds [−π, π].
    endstop_torque : float
        k_p, N·m. Default 1.0. Bounds [0, 1e5]; 0 = no end stops.
    endstop_angle_scale : float
        s_p, rad. Default 0.05. Bounds (0, inf).
    endstop_lower_angle : float
        q_lo, rad. Default 0. Bounds [−π, 2π].
    endstop_upper_angle : float
        q_hi, rad. Default 2.618 (150°). Bounds (endstop_lower_angle, 2π].
    coordinate : str
        Name of the angle's output column, as an OpenSim coordinate. Default
        ``<name>_flexion``.
    initial_speed : float
        q̇ at t = 0, rad/s (a start in motion, e.g. a recording that begins mid-movement).
        Default 0 (at rest). Bounds [-100, 100].
    positive : str
        The anatomical motion a growing angle is, one of `POSITIVE_MOTIONS`: the joint's
        positive way for its angle, speed and net and passive torques, and the way a unit
        with direction +1 pulls. Default ``"flexion"``; the jump's hip ``"extension"``
        (relative angles of a planar chain all turn counterclockwise, so hip flexion and
        knee flexion cannot both be positive), its ankle ``"plantarflexion"``, the free
        root's absolute angle ``"counterclockwise"``.
    """

    name: str
    initial_angle: float = 0.0
    endstop_torque: float = 1.0
    endstop_angle_scale: float = 0.05
    endstop_lower_angle: float = 0.0
    endstop_upper_angle: float = 2.618
    coordinate: str = ""
    initial_speed: float = 0.0
    positive: str = "flexion"

    def __post_init__(self) -> None:
        check_name("name", self.name)
        if self.positive not in POSITIVE_MOTIONS:
            raise ModelError("positive", f"{self.positive!r}; allowed: "
                             + ", ".join(POSITIVE_MOTIONS))
        check_fields(self, JOINT_FIELDS)
        if not self.coordinate:
            object.__setattr__(self, "coordinate", f"{self.name}_flexion")
        check_name("coordinate", self.coordinate)
        if self.coordinate == "time" or self.coordinate.startswith(
                ("torque_", "activation_", "excitation_", "omega_cc_", "theta_cc_")):
            raise ModelError("coordinate", f"{self.coordinate!r} would clash with another "
                             "output column; allowed: a name other than time and not starting "
                             "with torque_, activation_, excitation_, omega_cc_ or theta_cc_")

    @property
    def negative(self) -> str:
        """The motion a shrinking angle is (the opposite of ``positive``)."""
        return OPPOSITE_MOTIONS[self.positive]

    def endstop_array(self) -> np.ndarray:
        """[k_p, s_p, q_lo, q_hi] in the layout of `torquesim.model.body.passive_torque`."""
        p = np.zeros(ZERO_OFFSET)
        p[ENDSTOP_TORQUE] = self.endstop_torque
        p[ENDSTOP_SCALE] = self.endstop_angle_scale
        p[ENDSTOP_LOW] = self.endstop_lower_angle
        p[ENDSTOP_HIGH] = self.endstop_upper_angle
        return p


@dataclass(frozen=True)
class Unit:
    """One torque generator unit placed on a joint.

    Attributes
    ----------
    name : str
        Unique in the model (names output columns, e.g. ``torque_<name>``).
    joint : str
        Name of the joint it acts on.
    direction : int
        +1 flexor (its SE stretch is θ_cc − q, it pulls towards flexion), −1 extensor
        (stretch q − θ_cc).
    parameters : TorqueGeneratorUnit
    activation : ActivationProfile
        ``initial_level=None`` ("equilibrium"): the level is solved so the chain starts at
        rest (see `ChainModel.initial_state`). With ``activation_dynamics`` it is the unit's
        excitation e(t).
    activation_dynamics : ActivationDynamics or None
        None (default, the abstract's model): the activation is the profile, a = e(t). Else
        a follows e(t) with first-order dynamics and is a state of the unit, starting at the
        profile's initial level (at rest, a = e).
    second_joint : str or None
        A two-joint unit (a gastrocnemius, hamstrings, rectus femoris): the adjacent joint it
        also spans. None (default): it spans ``joint`` only.
    second_arm : float
        Its moment arm r at ``second_joint`` relative to the one at ``joint`` (signed: +
        pulls towards the second joint's positive way), dimensionless. Bounds [-2, 2]. Its
        torque T acts as δ·T at ``joint`` and r·T at ``second_joint``, and its SE stretch is
        s = δ·(θ_cc − ψ) with ψ = q_joint + δ·r·q_second the unit's angle (docs/model.md
        §7, two-joint units). 0 with no second joint.
    """

    name: str
    joint: str
    direction: int
    parameters: TorqueGeneratorUnit
    activation: ActivationProfile
    activation_dynamics: ActivationDynamics | None = None
    second_joint: str | None = None
    second_arm: float = 0.0

    def __post_init__(self) -> None:
        check_name("name", self.name)
        check_name("joint", self.joint)
        if isinstance(self.direction, bool) or self.direction not in (FLEXOR, EXTENSOR):
            raise ModelError("direction", f"{self.direction!r}; allowed +1 (flexor) or -1 "
                             "(extensor)")
        object.__setattr__(self, "direction", int(self.direction))
        if not isinstance(self.parameters, TorqueGeneratorUnit):
            raise ModelError("parameters", "must be a TorqueGeneratorUnit")
        if not isinstance(self.activation, ActivationProfile):
            raise ModelError("activation", "must be an ActivationProfile")
        if self.activation_dynamics is not None and \
                not isinstance(self.activation_dynamics, ActivationDynamics):
            raise ModelError("activation_dynamics", "must be an ActivationDynamics or None")
        if self.second_joint is None:
            if self.second_arm != 0.0:
                raise ModelError("second_arm", f"{self.second_arm!r} without a second_joint; "
                                 "allowed: 0, or name the second_joint")
        else:
            check_name("second_joint", self.second_joint)
            if self.second_joint == self.joint:
                raise ModelError("second_joint", f"{self.second_joint!r} is the unit's joint; "
                                 "allowed: another, adjacent joint")
            check_fields(self, UNIT_GEOMETRY_FIELDS)
            object.__setattr__(self, "second_arm", float(self.second_arm))

    @property
    def kind(self) -> str:
        """The unit kind, which fixes its states (`UNIT_STATE_WIDTHS`)."""
        return "hill" if self.activation_dynamics is None else "hill_with_activation_dynamics"


class PackedChain(NamedTuple):
    """Plain float arrays handed to the compiled solvers.

    segments : (n, 4)  A_k, B_k, L_k, g·B_k (see `ChainModel.pack`)
    joints : (n, 6)    end stops, zero offset and speed limit
    units : (U, 25)    TorqueGeneratorUnit array, then joint index, direction, state offset,
                       activation time constants, second joint and its arm (`model.unit_row`)
    activations : (U, P)  packed activation profiles [a_0, n, (t_on, r, level) × n]
    """

    segments: np.ndarray
    joints: np.ndarray
    units: np.ndarray
    activations: np.ndarray


class ChainStart(NamedTuple):
    """Static equilibrium at rest (docs/model.md §7, "Static-equilibrium start")."""

    state: np.ndarray  #: y(0), rad and rad/s
    levels: np.ndarray  #: initial activation of every unit used in the run
    torques: np.ndarray  #: unit torques at t = 0, N·m


#: The first segment's angles (rad, from the given one) from which `ChainModel._stand`
#: seeks a standing equilibrium, in turn: the given angle first.
STAND_TURNS = (0.0, *(sign * 0.05 * k for k in range(1, 11) for sign in (1, -1)))


@dataclass(frozen=True)
class ChainModel:
    """A complete simulation model: a planar chain, its units, and the duration.

    Attributes
    ----------
    name : str
    segments : tuple of Segment
        1 to 16, each after its parent (`Segment.parent`).
    joints : tuple of Joint
        One per segment: joint k is the proximal joint of segment k. On a free base the first
        joint's angle is the first segment's absolute angle (from hanging down, plus
        ``base_angle``) and it carries no units.
    units : tuple of Unit
        At least one per joint (but a free base's).
    gravity : float
        g, m/s², acting in the plane towards "hanging". Default 9.81. Bounds [0, 100]; not 0
        with ground contacts.
    base_angle : float
        Absolute angle of the first joint's zero direction from hanging straight down, rad,
        positive in its flexion direction. Default 0 (the elbow: forearm hanging at q = 0).
        −π/2 for a seated knee (thigh horizontal, straight knee = shank horizontal).
        Bounds [−π, π].
    duration : float
        Simulated time, s. Default 3.0. Bounds (0, 600].
    notes : tuple of str
        Free text kept with the model (the presets cite their sources here).
    base : str
        "fixed" (default): the first joint is a pivot fixed at the origin. "free": the first
        segment's proximal point (x, y) and its absolute angle are coordinates, the body
        stands on its ground contacts and starts in static equilibrium on them.
    points : tuple of Point
        Named points on segments, reported in the results (toe, heel, hip…).
    contacts : tuple of GroundContact
        Ground contacts at points, against the line y = 0 (free base only).
    landing_speed : float
        A landing: the body starts at touchdown, moving straight down at this speed, m/s
        (free base with contacts only). It is in its standing posture with the units as
        standing (levels and SE stretches of the static equilibrium), lifted so that its
        lowest contact point just touches the ground. A drop from height h lands at √(2gh):
        2.43 m/s from 0.3 m. Default 0 (standing). Bounds [0, 10].
    """

    name: str
    segments: tuple[Segment, ...]
    joints: tuple[Joint, ...]
    units: tuple[Unit, ...]
    gravity: float = 9.81
    base_angle: float = 0.0
    duration: float = 3.0
    notes: tuple[str, ...] = ()
    base: str = "fixed"
    points: tuple[Point, ...] = ()
    contacts: tuple[GroundContact, ...] = ()
    landing_speed: float = 0.0

    def __post_init__(self) -> None:
        check_name("name", self.name.replace("-", "_") if isinstance(self.name, str)
                    else self.name)
        for key in ("segments", "joints", "units", "notes", "points", "contacts"):
            object.__setattr__(self, key, tuple(getattr(self, key)))
        if self.base not in BASES:
            raise ModelError("base", f"{self.base!r}; allowed: {', '.join(BASES)}")
        check_fields(self, CHAIN_FIELDS)
        if self.contacts and self.gravity == 0.0:
            raise ModelError("gravity", "0 with ground contacts: no weight holds the body on "
                             "the ground (and the ground forces are read per body weight); "
                             "allowed (0, 100] m/s^2 for a model with [[contacts]]")
        if self.landing_speed and not self.contacts:
            raise ModelError("landing_speed", f"{self.landing_speed:g} m/s on a model without "
                             "ground contacts; allowed: 0, or a free base with [[contacts]]")
        n = len(self.segments)
        if not 1 <= n <= MAX_SEGMENTS:
            raise ModelError("segments", f"{n} segments; allowed 1 to {MAX_SEGMENTS}")
        if len(self.joints) != n:
            raise ModelError("joints", f"{len(self.joints)} joints for {n} segments; allowed: "
                             "one joint per segment (joint k moves segment k)")
        for key, kind in (("segments", Segment), ("joints", Joint), ("units", Unit),
                          ("points", Point), ("contacts", GroundContact)):
            seen = set()
            for i, item in enumerate(getattr(self, key)):
                if not isinstance(item, kind):
                    raise ModelError(f"{key}[{i}]", f"must be a {kind.__name__}")
                name = item.point if key == "contacts" else item.name
                if name in seen:
                    field = "point" if key == "contacts" else "name"
                    raise ModelError(f"{key}[{i}].{field}", f"{name!r} is used twice; "
                                     "allowed: unique names")
                seen.add(name)
        self._check_tree()
        self._check_points()
        coordinates = [j.coordinate for j in self.joints]
        if len(set(coordinates)) != n:
            raise ModelError("joints.coordinate", "two joints share a coordinate name; "
                             "allowed: unique names")
        joint_names = [j.name for j in self.joints]
        free_joint = self.joints[0].name if self.base == "free" else None
        for i, unit in enumerate(self.units):
            if unit.joint not in joint_names:
                raise ModelError(f"units[{i}].joint", f"{unit.joint!r} is not a joint; "
                                 f"allowed: {', '.join(joint_names)}")
            if unit.joint == free_joint:
                raise ModelError(f"units[{i}].joint", f"{unit.joint!r} is the free base's "
                                 "joint, which carries no units; allowed: "
                                 f"{', '.join(joint_names[1:])}")
            if unit.second_joint is not None:
                self._check_second_joint(i, unit, joint_names, free_joint)
                if unit.activation.initial_level is None:
                    raise ModelError(f"units[{i}].activation.initial_level", "\"equilibrium\" "
                                     "for a two-joint unit; allowed: a level in [0, 1] (the "
                                     "one-joint units at its joints hold the rest)")
        for joint in self.joints:
            if joint.name != free_joint and not any(u.joint == joint.name for u in self.units):
                raise ModelError(f"joints.{joint.name}", "has no torque generator unit; "
                                 "allowed: at least one unit per joint")
        self._check_output_names()
        self.initial_state()  # raises if the start cannot be held

    def _check_second_joint(self, i: int, unit: Unit, joint_names: list[str],
                            free_joint: str | None) -> None:
        """A two-joint unit spans two adjacent joints (one moves the segment the other's
        segment hangs from), neither the free base's."""
        key = f"units[{i}].second_joint"
        parents = self.parents
        k = joint_names.index(unit.joint)
        neighbours = [j for j in range(len(joint_names))
                      if (parents[j] == k or parents[k] == j) and joint_names[j] != free_joint]
        allowed = ", ".join(joint_names[j] for j in neighbours) or "none: no adjacent joint"
        if unit.second_joint not in joint_names or \
                joint_names.index(unit.second_joint) not in neighbours:
            raise ModelError(key, f"{unit.second_joint!r} is not a joint adjacent to "
                             f"{unit.joint!r} (sharing a segment with it); allowed: {allowed}")

    def _check_tree(self) -> None:
        names = [seg.name for seg in self.segments]
        for k, seg in enumerate(self.segments):
            if seg.parent and seg.parent not in names[:k]:
                raise ModelError(f"segments[{k}].parent", f"{seg.parent!r} is not a segment "
                                 "listed before it; allowed: "
                                 f"{', '.join(names[:k]) or 'none (the first segment)'}")

    def _check_points(self) -> None:
        segments = {seg.name: seg for seg in self.segments}
        for i, point in enumerate(self.points):
            if point.segment not in segments:
                raise ModelError(f"points[{i}].segment", f"{point.segment!r} is not a "
                                 f"segment; allowed: {', '.join(segments)}")
            reach = segments[point.segment].extent
            for field in ("distance", "offset"):
                value = getattr(point, field)
                if not -reach <= value <= reach:
                    raise ModelError(f"points[{i}].{field}", f"{value!r} m is off segment "
                                     f"{point.segment}; allowed [{-reach:g}, {reach:g}] m "
                                     "(its extent)")
        points = [p.name for p in self.points]
        for i, contact in enumerate(self.contacts):
            if contact.point not in points:
                raise ModelError(f"contacts[{i}].point", f"{contact.point!r} is not a point; "
                                 f"allowed: {', '.join(points) or 'none (define points)'}")
        if self.contacts and self.base != "free":
            raise ModelError("contacts", "need base = \"free\" (a body on a fixed pivot "
                             "cannot stand on the ground)")
        if self.base == "free" and not self.contacts:
            raise ModelError("contacts", "a free base needs at least one ground contact to "
                             "start standing on")

    # -- structure ----------------------------------------------------------------------
    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def n_units(self) -> int:
        return len(self.units)

    @property
    def has_activation_dynamics(self) -> bool:
        """Whether some unit has activation dynamics (a state of its activation)."""
        return any(u.activation_dynamics is not None for u in self.units)

    @property
    def weight(self) -> float:
        """m·g, N: the whole body's weight (segments and their loads)."""
        return self.gravity * sum(seg.total_mass for seg in self.segments)

    @property
    def n_base(self) -> int:
        """Coordinates of the base before the joint angles: 2 (x, y) on a free base, else 0."""
        return len(BASE_COORDINATES) if self.base == "free" else 0

    @property
    def n_coordinates(self) -> int:
        """Generalized coordinates: the base's (free base) and the joint angles."""
        return self.n_base + self.n_joints

    @property
    def parents(self) -> tuple[int, ...]:
        """Index of each segment's parent segment, −1 for the first (on the base)."""
        names = [seg.name for seg in self.segments]
        return tuple(-1 if k == 0 else names.index(seg.parent) if seg.parent else k - 1
                     for k, seg in enumerate(self.segments))

    @property
    def is_serial(self) -> bool:
        """Whether each segment hangs from the one before it (a chain, not a tree)."""
        return all(p == k - 1 for k, p in enumerate(self.parents))

    def parent_distances(self) -> np.ndarray:
        """Where each segment's proximal joint sits along its parent's axis, m (0 for the
        first)."""
        out = np.zeros(self.n_joints)
        for k, p in enumerate(self.parents):
            if p >= 0:
                seg = self.segments[k]
                out[k] = self.segments[p].length if seg.parent_distance is None \
                    else seg.parent_distance
        return out

    @property
    def state_size(self) -> int:
        return self.layout.size

    @property
    def layout(self) -> StateLayout:
        """Where the coordinates, their speeds and each unit's states sit in y."""
        return StateLayout(self.n_joints, tuple(UNIT_STATE_WIDTHS[u.kind] for u in self.units),
                           self.n_base)

    def joint_index(self, name: str) -> int:
        """Index of the joint named ``name`` (or with that coordinate name)."""
        names = [j.name for j in self.joints]
        if name in names:
            return names.index(name)
        coordinates = [j.coordinate for j in self.joints]
        if name in coordinates:
            return coordinates.index(name)
        raise ModelError("joint", f"{name!r} is not a joint of {self.name}; allowed: "
                         f"{', '.join(names)}")

    def unit_index(self, name: str) -> int:
        """Index of the unit named ``name``."""
        names = [u.name for u in self.units]
        if name not in names:
            raise ModelError("unit", f"{name!r} is not a unit of {self.name}; allowed: "
                             f"{', '.join(names)}")
        return names.index(name)

    def unit_aliases(self) -> dict[str, str]:
        """Other names of each unit: ``JOINT.flexor``/``JOINT.extensor`` for the joint's only
        unit of that direction, and on a one-joint model ``flexor``/``extensor``."""
        aliases = {}
        for joint in self.joints:
            for direction, role in ((1, "flexor"), (-1, "extensor")):
                units = [u.name for u in self.units if u.joint == joint.name
                         and u.direction == direction]
                if len(units) == 1:
                    aliases[f"{joint.name}.{role}"] = units[0]
                    if self.n_joints == 1:
                        aliases[role] = units[0]
        return aliases

    def state_names(self) -> tuple[str, ...]:
        """Names of the entries of y: coordinates, their speeds, each unit's CE angle (and
        activation, for a unit with activation dynamics): the output table's columns after
        its time (`output_columns`)."""
        return tuple(c for c, _ in self._output_column_pairs()[1:1 + self.state_size])

    def output_columns(self) -> dict[str, str]:
        """Every column of the output table (`SimulationResult.columns`) in table order, each
        with the model field that names it (``""`` for the model's own columns,
        `RESERVED_COLUMNS`)."""
        return dict(self._output_column_pairs())

    def _output_column_pairs(self) -> list[tuple[str, str]]:
        units = [(f"units[{i}].name", u.name) for i, u in enumerate(self.units)]
        dynamic = [pair for pair, u in zip(units, self.units, strict=True)
                   if u.activation_dynamics is not None]
        coordinates = [("", c) for c in BASE_COORDINATES[:self.n_base]] + [
            (f"joints[{j}].coordinate", joint.coordinate) for j, joint in enumerate(self.joints)]
        out = [("time", "")]
        out += [(c, field) for field, c in coordinates]
        out += [(f"{c}_speed", field) for field, c in coordinates]
        for field, name in units:
            out.append((f"theta_cc_{name}", field))
            if (field, name) in dynamic:
                out.append((f"activation_state_{name}", field))
        out += [(f"torque_{name}", field) for field, name in units]
        for j, joint in enumerate(self.joints):
            out += [(f"torque_{kind}_{joint.name}", f"joints[{j}].name")
                    for kind in ("net", "passive")]
        out += [(f"activation_{name}", field) for field, name in units]
        out += [(f"omega_cc_{name}", field) for field, name in units]
        out += [(f"excitation_{name}", field) for field, name in dynamic]
        if self.points or self.base == "free":
            for i, point in enumerate(self.points):
                out += [(f"{point.name}_{axis}", f"points[{i}].name") for axis in "xy"]
            out += [(name, "") for name in ("com_x", "com_y", "com_speed_x", "com_speed_y")]
        if self.contacts:
            for i, contact in enumerate(self.contacts):
                out += [(f"grf_{axis}_{contact.point}", f"contacts[{i}].point")
                        for axis in "xy"]
            out += [(name, "") for name in ("grf_x", "grf_y", "cop_x")]
        return out

    def _check_output_names(self) -> None:
        """Refuse a name whose output column is reserved (`RESERVED_COLUMNS`) or another
        field's: the table would silently overwrite one with the other."""
        owner = dict.fromkeys(RESERVED_COLUMNS, "")
        for column, field in self._output_column_pairs():
            if not field:
                continue
            if column in owner:
                other = owner[column]
                clash = (f"the model's own (reserved: {', '.join(RESERVED_COLUMNS)})"
                         if not other else f"also named by {other}")
                raise ModelError(field, f"gives the output column {column!r}, {clash}; "
                                 "allowed: a name whose output columns are its own")
            owner[column] = field

    def replace(self, **changes) -> ChainModel:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    def replace_unit(self, name: str, **changes) -> ChainModel:
        """A copy with unit ``name``'s fields (``parameters``, ``activation``, …) changed."""
        i = self.unit_index(name)
        units = list(self.units)
        units[i] = replace(units[i], **changes)
        return self.replace(units=tuple(units))

    def replace_joint(self, name: str, **changes) -> ChainModel:
        i = self.joint_index(name)
        joints = list(self.joints)
        joints[i] = replace(joints[i], **changes)
        return self.replace(joints=tuple(joints))

    def replace_segment(self, name: str, **changes) -> ChainModel:
        i = [s.name for s in self.segments].index(name)
        segments = list(self.segments)
        segments[i] = replace(segments[i], **changes)
        return self.replace(segments=tuple(segments))

    # -- packing ------------------------------------------------------------------------
    def segment_array(self) -> np.ndarray:
        """The packed body: one row per segment k, then one row per ground contact.

        Segment rows, with M_c the mass of segment c and everything distal to it and d_c the
        distance along its parent where c is attached (`parent_distances`):

        A_k = J_k + Σ_children d_c²·M_c    inertia about joint k of segment k and all it
                                           carries, kg·m²
        B_k = S_k + Σ_children d_c·M_c     first moment about joint k of the same, kg·m
        g·B_k                              gravity moment coefficient, N·m
        parent                             index of the parent segment, −1: the base
        Λ_kb (columns SEG_LEVER + b)       for every segment b distal to k, the distance
                                           along k to where the branch leading to b is
                                           attached, m (0 for the others)

        (J_k, S_k: the segment's own inertia about its joint and first moment, loads
        included.) Row 0 also holds the number of segments, the total mass (kg) and the
        weight (N). For a serial chain Λ_kb = L_k (b > k), so the mass matrix in absolute
        angles is M_kk = A_k and M_jk = L_j·B_k·cos(φ_j − φ_k) for j < k (docs/model.md §1).
        Contact rows: segment index, the point's distance and offset, and the contact's
        parameters (`torquesim.model.contact`).
        """
        n = self.n_joints
        parents = self.parents
        attach = self.parent_distances()
        out = np.zeros((n + len(self.contacts), max(SEG_LEVER_COLUMN + n, CONTACT_ROW_SIZE)))
        distal = np.array([seg.total_mass for seg in self.segments])  # M_k, summed below
        for k in range(n - 1, -1, -1):  # children come after their parents
            seg = self.segments[k]
            out[k, SEG_INERTIA] += seg.inertia_with_loads
            out[k, SEG_MOMENT] += seg.first_moment
            out[k, SEG_GRAVITY] = self.gravity * out[k, SEG_MOMENT]
            out[k, SEG_PARENT_COLUMN] = parents[k]
            p = parents[k]
            if p >= 0:
                out[p, SEG_INERTIA] += attach[k] ** 2 * distal[k]
                out[p, SEG_MOMENT] += attach[k] * distal[k]
                distal[p] += distal[k]
        for b in range(n):  # Λ_sb: walk from b up to the base
            child, s = b, parents[b]
            while s >= 0:
                out[s, SEG_LEVER_COLUMN + b] = attach[child]
                child, s = s, parents[s]
        out[0, SEG_COUNT_COLUMN] = n
        out[0, SEG_SERIAL_COLUMN] = float(self.is_serial)
        out[0, SEG_MASS_COLUMN] = distal[0]
        out[0, SEG_WEIGHT_COLUMN] = self.gravity * distal[0]
        points = {p.name: p for p in self.points}
        segments = [seg.name for seg in self.segments]
        for c, contact in enumerate(self.contacts):
            point = points[contact.point]
            row = out[n + c]
            row[CONTACT_SEGMENT] = segments.index(point.segment)
            row[CONTACT_DISTANCE] = point.distance
            row[CONTACT_OFFSET] = point.offset
            row[CONTACT_STIFFNESS] = contact.stiffness
            row[CONTACT_EXPONENT] = contact.exponent
            row[CONTACT_DAMPING] = contact.damping
            row[CONTACT_FRICTION] = contact.friction
            row[CONTACT_SLIP_SPEED] = contact.slip_speed
        return out

    def joint_array(self) -> np.ndarray:
        """One row per coordinate (`n_coordinates`): the base's x and y on a free base (no
        end stops), then each joint's end stops, the offset added to q_k in φ_k (the base
        angle for the first joint, 0 for the others) and its speed limit (`speed_limits`). A
        free base's joint has no end stops."""
        nb = self.n_base
        out = np.zeros((self.n_coordinates, JOINT_ARRAY_SIZE))
        for i in range(nb):  # no stops within ±1 km: only a divergence reaches them
            out[i, ENDSTOP_SCALE] = 1.0
            out[i, ENDSTOP_LOW], out[i, ENDSTOP_HIGH] = -1e3, 1e3
        for k, joint in enumerate(self.joints):
            out[nb + k, :ZERO_OFFSET] = joint.endstop_array()
        if nb:
            out[nb, ENDSTOP_TORQUE] = 0.0
        out[nb, ZERO_OFFSET] = self.base_angle
        out[:, SPEED_LIMIT] = self.speed_limits()
        return out

    def speed_limits(self) -> np.ndarray:
        """The largest physically possible speed of each coordinate, rad/s (m/s for a free
        base's x, y): `SPEED_LIMIT_FACTOR` × the fastest ω_max of the joint's units (of all
        units for a free base's angle; 10 rad/s for a body without units);
        `BASE_SPEED_LIMIT` for x and y. A joint turning
        faster than any of its units can shorten, ten times over, is a numerical failure, not
        a motion; the solvers stop there (and at an angle more than a full turn beyond the
        end stops)."""
        overall = max((u.parameters.max_velocity for u in self.units), default=10.0)
        fastest = [max((u.parameters.max_velocity for u in self.units
                        if j.name in (u.joint, u.second_joint)), default=overall)
                   for j in self.joints]
        return np.array([BASE_SPEED_LIMIT] * self.n_base
                        + [SPEED_LIMIT_FACTOR * w for w in fastest])

    def unit_angles(self, q) -> np.ndarray:
        """Each unit's angle ψ_u = q_joint + δ·r·q_second, rad (its joint's angle for a
        one-joint unit; `Unit.second_arm`), at joint angles ``q`` (rad; the last axis the
        joints, any leading axes kept)."""
        q = np.asarray(q, dtype=float)
        out = np.empty(q.shape[:-1] + (self.n_units,))
        for i, unit in enumerate(self.units):
            out[..., i] = q[..., self.joint_index(unit.joint)]
            if unit.second_joint is not None:
                out[..., i] += unit.direction * unit.second_arm \
                    * q[..., self.joint_index(unit.second_joint)]
        return out

    def unit_array(self) -> np.ndarray:
        out = np.zeros((self.n_units, UNIT_ROW_SIZE))
        for i, unit in enumerate(self.units):
            out[i, :UNIT_JOINT] = unit.parameters.to_array()
            out[i, UNIT_JOINT] = self.n_base + self.joint_index(unit.joint)  # its coordinate
            out[i, UNIT_DIRECTION] = unit.direction
            out[i, UNIT_SECOND_JOINT] = out[i, UNIT_JOINT] if unit.second_joint is None \
                else self.n_base + self.joint_index(unit.second_joint)
            out[i, UNIT_SECOND_ARM] = unit.second_arm
            out[i, UNIT_STATE_OFFSET] = self.layout.unit_offset(i)
            if unit.activation_dynamics is not None:
                out[i, UNIT_ACTIVATION_TIME] = unit.activation_dynamics.activation_time
                out[i, UNIT_DEACTIVATION_TIME] = unit.activation_dynamics.deactivation_time
        return out

    def pack(self, levels=None) -> PackedChain:
        """The arrays the compiled solvers read; ``levels`` (default: from the static
        equilibrium) resolve the "equilibrium" initial activation levels."""
        levels = self.initial_state().levels if levels is None else levels
        return PackedChain(self.segment_array(), self.joint_array(), self.unit_array(),
                           pack_activations([u.activation for u in self.units], levels))

    # -- the start ------------------------------------------------------------------------
    def absolute_angles(self, q) -> np.ndarray:
        """φ_k = φ_parent + q_k, φ_1 = base_angle + q_1, rad (a serial chain:
        base_angle + q_1 + … + q_k)."""
        q = np.asarray(q, dtype=float)
        phi = np.empty(self.n_joints)
        for k, p in enumerate(self.parents):
            phi[k] = (self.base_angle if p < 0 else phi[p]) + q[k]
        return phi

    def gravity_joint_torques(self, q) -> np.ndarray:
        """Torque gravity exerts at each joint, N·m (flexion positive):
        −Σ_{k distal to j, and j} g·B_k·sin φ_k."""
        phi = self.absolute_angles(q)
        acc = self.segment_array()[:self.n_joints, SEG_GRAVITY] * np.sin(phi)
        for k in range(self.n_joints - 1, 0, -1):
            acc[self.parents[k]] += acc[k]
        return -acc

    def initial_state(self) -> ChainStart:
        """Static equilibrium at rest at the joints' initial angles (docs/model.md §7).
        Solved once per (immutable) model; each call returns fresh copies of the arrays.
        Joints with an ``initial_speed`` start moving at it from that state (the units as at
        rest there: their SE holds the static torques); a free base then moves so that its
        loaded contact points start still (least squares over them). A model with a
        ``landing_speed`` starts at touchdown: that standing state lifted until its lowest
        contact point is at the ground, moving down at that speed.

        At joint j the units must cancel the load τ_load = Σ_{k≥j} g·B_k·sin φ_k − T_p(q_j)
        (gravity and end stops; flexion positive).

        - A unit with a given initial level a (an antagonist) is isometric at its rest SE
          stretch: k·s = max(a, 0.01)·T_θ(q + d·s)·h(0).
        - The torque still needed, τ = τ_load − Σ d·T (given-level units), is carried by the
          units with ``initial_level = "equilibrium"`` whose direction is sign(τ) (the
          agonists), at one common level; "equilibrium" units of the other direction rest at
          activation 0. With one agonist the level is closed-form: s = |τ|/k,
          a = |τ|/(h(0)·T_θ(q + d·s)) (docs/model.md §3).
        - A joint with no "equilibrium" unit: the one unit of direction sign(τ_load) carries
          τ (its stretch solved as above) at its own given level, so its CE starts away from
          isometric (docs/model.md's elbow with a given flexor level); with several such units
          each is isometric at its own level and the joint need not start at rest.

        Raises `ModelError` naming the joint when no level in [0, 1] holds it.
        """
        start = self.__dict__.get("_start")
        if start is None:
            start = self._solve_initial_state()
            self.__dict__["_start"] = start  # frozen: cache outside the fields
        return ChainStart(start.state.copy(), start.levels.copy(), start.torques.copy())

    def kinematics(self, coordinates, speeds=None) -> dict[str, np.ndarray]:
        """Where the body is, and how fast it moves, at coordinates (x, y on a free base, then
        q; shape (N,) or (T, N)) and their speeds, m and m/s:

        ``joints``, ``centres`` (…, n, 2): each segment's proximal joint and centre of mass
        (with its loads); ``points`` (…, points, 2); ``com`` (…, 2): the whole body's centre
        of mass; ``angles`` (…, n): the absolute angles φ_k (rad); with ``speeds`` also
        ``centre_velocities``, ``point_velocities`` and ``com_velocity``. The base (fixed, at
        the origin) or (x, y) (free) is the first joint; a segment's axis points along
        u(φ) = (sin φ, −cos φ), its perpendicular n(φ) = (cos φ, sin φ), and a point at
        distance d and offset e on segment k is at P_k + d·u(φ_k) + e·n(φ_k)."""
        coords = np.atleast_2d(np.asarray(coordinates, dtype=float))
        rates = None if speeds is None else np.atleast_2d(np.asarray(speeds, dtype=float))
        nb, n = self.n_base, self.n_joints
        steps = coords.shape[0]
        phi = np.empty((steps, n))
        phid = np.zeros((steps, n))
        for k, p in enumerate(self.parents):
            phi[:, k] = (self.base_angle if p < 0 else phi[:, p]) + coords[:, nb + k]
            if rates is not None:
                phid[:, k] = (0.0 if p < 0 else phid[:, p]) + rates[:, nb + k]
        axis = np.stack([np.sin(phi), -np.cos(phi)], axis=-1)
        normal = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
        swing = phid[..., None] * normal  # d(u)/dt per unit length
        attach = self.parent_distances()
        joints = np.zeros((steps, n, 2))
        joint_v = np.zeros((steps, n, 2))
        for k, p in enumerate(self.parents):
            if p < 0:
                if nb:
                    joints[:, k] = coords[:, :2]
                    if rates is not None:
                        joint_v[:, k] = rates[:, :2]
            else:
                joints[:, k] = joints[:, p] + attach[k] * axis[:, p]
                joint_v[:, k] = joint_v[:, p] + attach[k] * swing[:, p]
        lever = np.array([seg.first_moment / seg.total_mass for seg in self.segments])
        masses = np.array([seg.total_mass for seg in self.segments])
        centres = joints + lever[None, :, None] * axis
        centre_v = joint_v + lever[None, :, None] * swing
        index = {seg.name: k for k, seg in enumerate(self.segments)}
        on = np.array([index[pt.segment] for pt in self.points], dtype=int)
        d = np.array([pt.distance for pt in self.points])[None, :, None]
        e = np.array([pt.offset for pt in self.points])[None, :, None]
        points = joints[:, on] + d * axis[:, on] + e * normal[:, on]
        out = {"joints": joints, "centres": centres, "points": points, "angles": phi,
               "com": np.einsum("k,tkc->tc", masses, centres) / masses.sum()}
        if rates is not None:
            out["centre_velocities"] = centre_v
            out["point_velocities"] = joint_v[:, on] + d * swing[:, on] \
                + e * (-phid[:, on, None] * axis[:, on])
            out["com_velocity"] = np.einsum("k,tkc->tc", masses, centre_v) / masses.sum()
        if np.ndim(coordinates) == 1:
            out = {key: value[0] for key, value in out.items()}
        return out

    def _contact_points(self) -> list[int]:
        """Index in `points` of each contact's point."""
        names = [p.name for p in self.points]
        return [names.index(c.point) for c in self.contacts]

    def _stand(self, q0: np.ndarray):
        """Static equilibrium of a free body on its contacts at the joint angles ``q0``:
        the base height y and the first segment's angle q_1 at which the contacts' normal
        forces k·δⁿ carry the weight with no net moment (x = 0, at rest, so no friction).
        Returns (base (x, y), q_1, the torque every joint must supply against gravity and
        the contacts, N·m). A `ModelError` when the centre of mass is not over the contacts."""
        from scipy.optimize import fsolve

        weight = self.weight
        masses = np.array([seg.total_mass for seg in self.segments])
        which = self._contact_points()

        def forces(height_and_angle):
            coords = np.concatenate([[0.0, height_and_angle[0], height_and_angle[1]], q0[1:]])
            where = self.kinematics(coords)
            depth = np.maximum(-where["points"][which, 1], 0.0)
            k = np.array([c.stiffness for c in self.contacts])
            power = np.array([c.exponent for c in self.contacts])
            return where, k * depth**power

        def residual(height_and_angle):
            where, normal = forces(height_and_angle)
            arms = where["points"][which, 0] - where["com"][0]
            return [(normal.sum() - weight) / weight, normal @ arms / weight]

        where = self.kinematics(np.concatenate([[0.0, 0.0], q0]))
        com = where["com"]
        xs = where["points"][which, 0]
        if self.gravity > 0 and not xs.min() <= com[0] <= xs.max():
            raise ModelError("joints.initial_angle", f"the centre of mass (x = {com[0]:.3f} "
                             f"m) is not over the contacts (x from {xs.min():.3f} to "
                             f"{xs.max():.3f} m): the posture cannot stand; allowed: a "
                             "posture whose centre of mass lies over its contact points")
        for c, contact in enumerate(self.contacts):  # the body's weight shared alike
            share = weight / len(which)
            sink = (share / contact.stiffness) ** (1 / contact.exponent)
            if sink > MAX_STANDING_SINK:
                least = share / MAX_STANDING_SINK ** contact.exponent
                raise ModelError(f"contacts[{c}].stiffness", f"{contact.stiffness:.4g} "
                                 f"N/m^{contact.exponent:g} lets the body sink {sink:.3g} m into "
                                 f"the ground standing; allowed ≥ {least:.3g} N/m^"
                                 f"{contact.exponent:g} for this body (a standing sink of at "
                                 f"most {MAX_STANDING_SINK * 100:g} cm)")
        sink = max((weight / len(which) / c.stiffness) ** (1 / c.exponent)
                   for c in self.contacts)
        # From the given first angle; where that fails (the foot tilted so that one contact
        # carries nothing, where the residual is flat), from first angles ever farther from it.
        for turn in STAND_TURNS:
            angle = q0[0] + turn
            low = self.kinematics(np.concatenate([[0.0, 0.0, angle], q0[1:]]))["points"]
            guess = [-low[which, 1].min() - sink, angle]
            with np.errstate(all="ignore"):  # a posture that cannot stand fails below
                solution, info, ok, _ = fsolve(residual, guess, full_output=True, xtol=1e-13)
                unbalanced = max(abs(v) for v in residual(solution))
            if ok == 1 and unbalanced <= 1e-9:
                break
        else:
            raise ModelError("joints.initial_angle", "no static equilibrium on the ground "
                             "found near this posture; allowed: a posture that can stand")
        where, normal = forces(solution)
        external = np.zeros(self.n_joints)  # torque of gravity and contacts about joint j
        subtree = self._subtrees()
        segment_of = [next(k for k, s in enumerate(self.segments)
                           if s.name == self.points[i].segment) for i in which]
        for j in range(self.n_joints):
            pivot = where["joints"][j]
            for k in subtree[j]:
                external[j] -= self.gravity * masses[k] * (where["centres"][k, 0] - pivot[0])
            for c, i in enumerate(which):
                if segment_of[c] in subtree[j]:
                    external[j] += normal[c] * (where["points"][i, 0] - pivot[0])
        return np.array([0.0, solution[0]]), solution[1], external

    def _subtrees(self) -> list[set[int]]:
        """Each segment with everything distal to it."""
        out = [{k} for k in range(self.n_joints)]
        for k in range(self.n_joints - 1, 0, -1):
            out[self.parents[k]] |= out[k]
        return out

    def _solve_initial_state(self) -> ChainStart:
        """`initial_state`, solved."""
        n, nu = self.n_joints, self.n_units
        q0 = np.array([float(j.initial_angle) for j in self.joints])
        segments = self.segment_array()
        base = np.zeros(self.n_base)
        if self.base == "free":  # standing: the ground holds the body, the joints hold it
            base, q0[0], gravity = self._stand(q0)
        else:
            gravity = self.gravity_joint_torques(q0) if n > 1 else None
        theta_cc = np.zeros(nu)
        levels = np.zeros(nu)
        torques = np.zeros(nu)
        # two-joint units have given levels: isometric at their rest stretch, at both joints
        spanning = [i for i, u in enumerate(self.units) if u.second_joint is not None]
        psi = self.unit_angles(q0)
        for i in spanning:
            unit = self.units[i]
            levels[i] = float(unit.activation.initial_level)
            s = _rest_stretch(unit, psi[i], levels[i])
            torques[i] = unit.parameters.se_stiffness * s
            theta_cc[i] = psi[i] + unit.direction * s
        for j, joint in enumerate(self.joints):
            if self.base == "free" and j == 0:
                continue  # the free base's joint: no units, nothing to hold
            q = q0[j]
            passive = passive_torque(q, joint.endstop_array(), 0)
            if gravity is None:  # one segment: the elbow's own arithmetic (docs/model.md §3)
                needed = segments[0, SEG_GRAVITY] * math.sin(self.base_angle + q) - passive
            else:
                needed = -gravity[j] - passive
            for i in spanning:  # what the two-joint units hold here
                unit = self.units[i]
                if unit.joint == joint.name:
                    needed -= unit.direction * torques[i]
                elif unit.second_joint == joint.name:
                    needed -= unit.second_arm * torques[i]
            mine = [i for i, u in enumerate(self.units)
                    if u.joint == joint.name and u.second_joint is None]
            pending = [i for i in mine if self.units[i].activation.initial_level is None]
            carrier = None
            if not pending:
                side = FLEXOR if needed > 0.0 else EXTENSOR
                same = [i for i in mine if self.units[i].direction == side]
                carrier = same[0] if len(same) == 1 and needed != 0.0 else None
            for i in mine:
                unit = self.units[i]
                theta_cc[i] = q
                if i in pending or i == carrier:
                    continue
                levels[i] = float(unit.activation.initial_level)
                s = _rest_stretch(unit, q, levels[i])
                torques[i] = unit.parameters.se_stiffness * s
                theta_cc[i] = q + unit.direction * s
                needed -= unit.direction * torques[i]
            # `needed`: what the agonists must add at rest (flexion positive).
            if needed == 0.0 or (not pending and carrier is None):
                continue
            direction = FLEXOR if needed > 0.0 else EXTENSOR
            side = "flexor" if direction == FLEXOR else "extensor"
            if carrier is not None:
                agonists = [carrier] if self.units[carrier].direction == direction else []
            else:
                agonists = [i for i in pending if self.units[i].direction == direction]
            if not agonists:
                raise ModelError(
                    f"joints.{joint.name}.initial_angle",
                    f"{joint.name} cannot rest at {math.degrees(q):.2f}°: it needs "
                    f"{abs(needed):.3g} N·m of {side} torque (the "
                    f"{'extensor' if side == 'flexor' else 'flexor'} would have to push) and no "
                    f"{side} unit there can supply it at initial_level = \"equilibrium\"; "
                    "allowed: a start the units can hold (change the angle or the given levels)")
            level = _agonist_level(self.units, agonists, q, abs(needed))
            if carrier is None and level > 1.0:
                raise ModelError(
                    f"joints.{joint.name}.initial_angle",
                    f"holding {joint.name} at {math.degrees(q):.2f}° needs activation "
                    f"{level:.3f} > 1 of {', '.join(self.units[i].name for i in agonists)}; "
                    "allowed: a start the units can hold (activation ≤ 1)")
            for i in agonists:
                unit = self.units[i]
                if len(agonists) == 1:
                    s = abs(needed) / unit.parameters.se_stiffness
                else:
                    s = _rest_stretch(unit, q, level)
                levels[i] = level if carrier is None else float(unit.activation.initial_level)
                torques[i] = unit.parameters.se_stiffness * s
                theta_cc[i] = q + unit.direction * s
        state = np.zeros(self.state_size)
        state[:self.n_base] = base
        state[self.layout.angles] = q0
        layout = self.layout
        for i in range(nu):
            state[layout.unit_state(i)] = theta_cc[i]
            if self.units[i].activation_dynamics is not None:
                state[layout.activation_state(i)] = levels[i]  # at rest a = e
        speeds = np.array([float(j.initial_speed) for j in self.joints])
        if np.any(speeds):
            state[layout.speeds] = speeds
            if self.base == "free" and self.contacts:
                state[layout.coordinate_speeds][:2] = self._contact_still(state)
        if self.landing_speed:  # at touchdown: lifted out of the standing sink, moving down
            lowest = self.kinematics(state[:self.n_base + n])["points"][self._contact_points(), 1]
            state[1] -= lowest.min()
            state[layout.coordinate_speeds][1] -= self.landing_speed
        return ChainStart(state, levels, torques)

    def _contact_still(self, state: np.ndarray) -> np.ndarray:
        """The base velocity (m/s) at which the loaded contact points of ``state`` (its joint
        speeds given) move least: minus the mean of their velocities with the base still."""
        layout = self.layout
        coords = state[layout.coordinates]
        rates = state[layout.coordinate_speeds].copy()
        rates[:2] = 0.0
        where = self.kinematics(coords, rates)
        which = self._contact_points()
        loaded = where["points"][which, 1] < 0.0
        if not loaded.any():
            return np.zeros(2)
        return -where["point_velocities"][which][loaded].mean(axis=0)


def _rest_stretch(unit: Unit, q: float, level: float) -> float:
    """SE stretch s ≥ 0 of an isometric unit at activation ``level``:
    k·s = max(a, 0.01)·T_θ(q + d·s)·h(0)."""
    p = unit.parameters.to_array()
    a = max(level, ACTIVATION_FLOOR)
    k, d = p[K_SE], unit.direction

    def balance(s: float) -> float:
        return k * s - a * torque_angle(q + d * s, p, 0) * p[H_ISOMETRIC]

    s_max = a * p[H_ISOMETRIC] / k  # T_θ ≤ 1 bounds the stretch
    from scipy.optimize import brentq

    return brentq(balance, 0.0, s_max * (1 + 1e-12) + 1e-300, xtol=1e-16, rtol=1e-15)


def agonist_level(torques, needed: float) -> float:
    """The one activation a shared by a joint's agonists (the units of the needed direction)
    at which their torques add up to ``needed`` (N·m, > 0): Σ_u torque_u(a) = needed, with
    ``torques`` one function a → N·m per agonist (non-decreasing in a). A level below the
    activation floor is the floor; a need above what a = 1 gives returns 1 + the missing
    fraction (> 1: the joint cannot be held). Used by the static-equilibrium start and by the
    fit's quasi-static initial guess, the one place a joint's torque is split between units."""
    def surplus(a: float) -> float:
        return sum(torque(a) for torque in torques) - needed

    if surplus(1.0) < 0.0:
        return 1.0 + (-surplus(1.0)) / needed
    if surplus(ACTIVATION_FLOOR) >= 0.0:
        return ACTIVATION_FLOOR
    from scipy.optimize import brentq

    return brentq(surplus, ACTIVATION_FLOOR, 1.0, xtol=1e-15, rtol=1e-15)


def _agonist_level(units, agonists, q: float, needed: float) -> float:
    """Common activation of the ``agonists`` (unit indices) holding joint angle ``q`` at rest
    with their summed SE torque ``needed`` (N·m, > 0). One agonist: closed form (its stretch
    is needed/k, so a = needed/(h(0)·T_θ(q + d·s))); several: `agonist_level`."""
    if len(agonists) == 1:
        unit = units[agonists[0]]
        p = unit.parameters.to_array()
        s = needed / unit.parameters.se_stiffness
        return needed / (p[H_ISOMETRIC] * torque_angle(q + unit.direction * s, p, 0))
    return agonist_level([lambda a, u=units[i]: u.parameters.se_stiffness
                          * _rest_stretch(u, q, a) for i in agonists], needed)


def pack_activations(profiles, levels) -> np.ndarray:
    """(U, P) array: row u is profile u packed as [a_0, n, (t_on, r, level) × n], its
    "equilibrium" initial level taken from ``levels[u]``; shorter rows are zero-padded."""
    rows = [p.to_array(float(level)) for p, level in zip(profiles, levels, strict=True)]
    width = max((r.size for r in rows), default=2)
    out = np.zeros((len(rows), width))
    for i, r in enumerate(rows):
        out[i, : r.size] = r
    return out


def as_chain(model) -> ChainModel:
    """A `ChainModel` from a chain or an `ElbowModel`;
    anything else is a TypeError naming the argument."""
    if isinstance(model, ChainModel):
        return model
    to_chain = getattr(model, "to_chain", None)
    if to_chain is None:
        raise TypeError(f"model: expected a ChainModel or ElbowModel, got "
                        f"{type(model).__name__} (load a file with torquesim.load_model)")
    return to_chain()
