"""Built-in models (``builtin:NAME``): the elbow curl of docs/model.md and two chains.

Anthropometry: de Leva (1996), J Biomech 29:1223, reference male of 73 kg (segment mass
fractions, lengths, centre-of-mass positions and sagittal radii of gyration); inertias about
the proximal joint by the parallel-axis theorem. Torque generator curves: the form of Yeadon,
King & Wilson (2006), J Biomech 39:476, with the elbow values of docs/model.md §2.4. Values marked
*est.* are reasoned estimates (docs/presets.md gives the reasoning for each).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

from ..errors import ModelError
from .activation import ActivationProfile, Ramp
from .chain import ChainModel, Joint, PointLoad, Segment, Unit
from .contact import GroundContact, Point
from .elbow import ElbowModel
from .preset_names import PREFIX, PRESET_NAMES
from .torque_generator import TorqueGeneratorUnit

BODY_MASS = 73.0  # kg, de Leva's reference male


def _de_leva(mass_fraction: float, length: float, com_fraction: float,
             gyration_fraction: float) -> tuple[float, float, float]:
    """(mass kg, centre-of-mass distance m, inertia about the proximal joint kg·m²) of a
    de Leva (1996) segment of the 73 kg reference male."""
    mass = mass_fraction * BODY_MASS
    com = com_fraction * length
    inertia = mass * (gyration_fraction * length) ** 2 + mass * com**2
    return mass, com, inertia


def _unit(t0: float, eccentric_ratio: float, optimal_angle: float, curvature: float,
          stiffness: float) -> TorqueGeneratorUnit:
    """A unit with the elbow's T_ω/d shape (docs/model.md §2.4: ω_max 18, ω_c 5.5 rad/s, a_min 0.9,
    ω_r 0.5 rad/s) scaled to T0, and its own angle curve and SE stiffness."""
    return TorqueGeneratorUnit(
        isometric_torque=t0, eccentric_torque_max=eccentric_ratio * t0, max_velocity=18.0,
        velocity_constant=5.5, min_differential_activation=0.90,
        differential_activation_rate=0.5, differential_activation_midpoint=0.0,
        optimal_angle=optimal_angle, angle_curvature=curvature, se_stiffness=stiffness)


def elbow_curl() -> ChainModel:
    """docs/model.md's default: a 5 kg dumbbell curl, 10° → ≈139° → ≈12° in 3 s."""
    chain = ElbowModel().to_chain()
    return chain.replace(name="elbow-curl", notes=(
        "The default elbow curl of torquesim's docs/model.md: forearm+hand of de Leva (1996) "
        "73 kg male, 5 kg dumbbell, elbow flexor/extensor of docs/model.md 2.4 (Yeadon et al. "
        "2006 form, Kentel et al. 2011 curves, Lategan & Kruger 2003 torques).",
        "Activation profiles fitted to the min-jerk curl of docs/model.md 6 (about 2 deg RMS).",))


def knee_extension() -> ChainModel:
    """Seated knee extension with a 5 kg ankle weight: thigh fixed horizontal, the shank and
    foot swing up from hanging (90° knee flexion) to ≈15° and back in 3 s."""
    shank_mass, shank_com, shank_inertia = _de_leva(0.0433, 0.4340, 0.4459, 0.255)
    foot_mass = 0.0137 * BODY_MASS
    foot_gyration = 0.245 * 0.2581
    segment = Segment("shank_foot", shank_mass, shank_com, shank_inertia, 0.4340, (
        PointLoad("foot", foot_mass, 0.4340 + 0.04, foot_mass * foot_gyration**2),
        PointLoad("ankle_weight", 5.0, 0.40, 0.0),
    ))
    knee = Joint("knee", initial_angle=math.radians(90.0), endstop_torque=1.0,
                 endstop_angle_scale=0.05, endstop_lower_angle=0.0,
                 endstop_upper_angle=math.radians(140.0), coordinate="knee_angle")
    extensor = Unit("knee_extensor", "knee", -1, _unit(200.0, 1.35, 1.13, 0.30, 1600.0),
                    ActivationProfile(None, (Ramp(0.0, 0.709, 0.165), Ramp(0.0, 0.194, 0.202),
                                             Ramp(0.989, 0.8, 0.114))))
    flexor = Unit("knee_flexor", "knee", 1, _unit(110.0, 1.35, 0.60, 0.30, 600.0),
                  ActivationProfile(0.05, (Ramp(0.489, 0.307, 0.027), Ramp(0.328, 0.243, 0.01),
                                           Ramp(0.254, 0.529, 0.246))))
    return ChainModel(
        "knee-extension", (segment,), (knee,), (extensor, flexor), base_angle=-math.pi / 2,
        duration=3.0, notes=(
            "Shank 4.33 %, foot 1.37 % of 73 kg; shank 0.434 m, CoM 44.59 %, radius of "
            "gyration 25.5 %; foot radius of gyration 24.5 % of 0.258 m (de Leva 1996).",
            "Foot as a point load 4 cm beyond the ankle on the shank axis, ankle weight 5 kg at "
            "0.40 m (est.). Thigh horizontal: base_angle = -90 deg.",
            "Knee extensor T0 200 N m, flexor 110 N m (est., typical adult male isometric "
            "peaks); optimal knee angles 65 and 35 deg (est.); SE 1600 and 600 N m/rad "
            "(est., k/T0 as the elbow units); T_omega and d(omega) shape of docs/model.md 2.4.",
            "Extensor and flexor activation ramps fitted (least squares, IMEX 5 ms) to a "
            "min-jerk lift 90 -> 15 deg in 0.1-1.3 s, hold, lowering 1.7-2.9 s (0.4 deg RMS).",))


def arm_raise() -> ChainModel:
    """A front raise with a curl holding 2 kg: shoulder and elbow flex together in the
    sagittal plane to ≈70°, hold, and lower again in 3 s."""
    arm_mass, arm_com, arm_inertia = _de_leva(0.0271, 0.2817, 0.5772, 0.285)
    elbow = ElbowModel()
    b = elbow.body
    upper_arm = Segment("upper_arm", arm_mass, arm_com, arm_inertia, 0.2817)
    forearm = Segment("forearm_hand", b.segment_mass, b.segment_com_distance, b.segment_inertia,
                      0.2689 + 0.0862, (PointLoad("dumbbell", 2.0, b.dumbbell_distance,
                                                  b.dumbbell_inertia),))
    shoulder = Joint("shoulder", initial_angle=math.radians(5.0), endstop_torque=1.0,
                     endstop_angle_scale=0.05, endstop_lower_angle=math.radians(-50.0),
                     endstop_upper_angle=math.radians(175.0))
    elbow_joint = Joint("elbow", initial_angle=math.radians(10.0))
    units = (
        Unit("shoulder_flexor", "shoulder", 1, _unit(60.0, 1.35, 1.0, 0.20, 480.0),
             ActivationProfile(None, (Ramp(0.087, 0.375, 0.529), Ramp(0.276, 0.402, 0.324),
                                      Ramp(0.695, 0.784, 0.258)))),
        Unit("shoulder_extensor", "shoulder", -1, _unit(70.0, 1.30, 0.8, 0.15, 350.0),
             ActivationProfile(0.05, (Ramp(0.298, 0.31, 0.074), Ramp(0.33, 0.309, 0.025),
                                      Ramp(0.263, 0.269, 0.092)))),
        Unit("elbow_flexor", "elbow", 1, elbow.flexor,
             ActivationProfile(None, (Ramp(0.028, 0.355, 0.374), Ramp(0.347, 0.419, 0.144),
                                      Ramp(0.15, 0.243, 0.146)))),
        Unit("elbow_extensor", "elbow", -1, elbow.extensor,
             ActivationProfile(0.1, (Ramp(0.41, 0.358, 0.104), Ramp(0.368, 0.372, 0.095),
                                     Ramp(0.454, 0.429, 0.025)))),
    )
    return ChainModel(
        "arm-raise", (upper_arm, forearm), (shoulder, elbow_joint), units, duration=3.0,
        notes=(
            "Upper arm 2.71 % of 73 kg, 0.2817 m, CoM 57.72 %, radius of gyration 28.5 %; "
            "forearm+hand and elbow units as docs/model.md (de Leva 1996).",
            "Dumbbell 2 kg in the hand. Shoulder flexor T0 60 N m, extensor 70 N m (est., adult "
            "male isometric shoulder torques); optimal angles 57 and 46 deg (est.); SE 480 and "
            "350 N m/rad (est.).",
            "Activation ramps of all four units fitted (least squares, IMEX 2 ms) to min-jerk "
            "raises (shoulder 5 -> 70 deg, elbow 10 -> 70 deg in 0.1-1.3 s), hold, lowering "
            "1.7-2.9 s (2.9 deg RMS).",))


def _leg_unit(t0: float, optimal_angle: float, stiffness: float) -> TorqueGeneratorUnit:
    """A lower-limb unit (both legs together): the elbow's T_ω/d shape with ω_max 25 rad/s
    and ω_c 7.5 rad/s (est.: knee and hip extension reach 15–20 rad/s in jumps), eccentric
    plateau 1.4·T0, angle curvature 0.3 rad⁻²."""
    return TorqueGeneratorUnit(
        isometric_torque=t0, eccentric_torque_max=1.4 * t0, max_velocity=25.0,
        velocity_constant=7.5, min_differential_activation=0.90,
        differential_activation_rate=0.5, differential_activation_midpoint=0.0,
        optimal_angle=optimal_angle, angle_curvature=0.3, se_stiffness=stiffness)


def squat_jump() -> ChainModel:
    """A squat jump from a static squat: foot, shank, thigh and head-arms-trunk (both legs
    together) on a free base, standing on toe and heel contacts; the extensors of ankle, knee
    and hip switch on from the static squat, hip first, and the body leaves the ground at
    ≈0.26 s nearly vertically (take-off 2.30 m/s up, −0.05 m/s back; flight 0.27 m)."""
    foot_mass = 2 * 0.0137 * BODY_MASS
    foot = Segment("foot", foot_mass, 0.06, foot_mass * (0.06**2 + (0.245 * 0.2581) ** 2), 0.17)
    shank_mass, shank_com, shank_inertia = _de_leva(2 * 0.0433, 0.4340, 1 - 0.4459, 0.255)
    shank = Segment("shank", shank_mass, shank_com, shank_inertia, 0.4340, parent_distance=0.0)
    thigh_mass, thigh_com, thigh_inertia = _de_leva(2 * 0.1416, 0.4222, 1 - 0.4095, 0.329)
    thigh = Segment("thigh", thigh_mass, thigh_com, thigh_inertia, 0.4222)
    hat_mass = BODY_MASS - foot_mass - shank_mass - thigh_mass
    hat = Segment("head_arms_trunk", hat_mass, 0.33, hat_mass * (0.33**2 + 0.25**2), 0.60)
    # Absolute angles of the static squat (from hanging down, counterclockwise, facing +x):
    # foot axis ankle -> toe 62 deg, shank 151 deg (28.6 deg forwards of upright), thigh 249
    # deg, trunk 146 deg (34 deg forwards).
    phi = (1.08, math.pi - 0.5, math.pi + 1.2, math.pi - 0.6)
    stops = dict(endstop_torque=20.0, endstop_angle_scale=0.05)
    joints = (
        Joint("foot_ground", initial_angle=phi[0], endstop_torque=0.0,
              endstop_lower_angle=-math.pi, endstop_upper_angle=2 * math.pi,
              coordinate="foot_angle", positive="counterclockwise"),
        Joint("ankle", initial_angle=phi[1] - phi[0], endstop_lower_angle=0.5,
              endstop_upper_angle=3.0, coordinate="ankle_angle", positive="plantarflexion",
              **stops),
        Joint("knee", initial_angle=phi[2] - phi[1], endstop_lower_angle=0.0,
              endstop_upper_angle=2.6, coordinate="knee_angle", **stops),
        Joint("hip", initial_angle=phi[3] - phi[2], endstop_lower_angle=-2.6,
              endstop_upper_angle=0.3, coordinate="hip_angle", positive="extension",
              **stops),
    )

    def push(delay: float, hold: float) -> ActivationProfile:
        """Extensor: from its standing level to full in 50 ms after ``delay``, held ``hold``
        s, off (0.05) in 50 ms."""
        return ActivationProfile(None, (Ramp(delay, 0.05, 1.0), Ramp(hold, 0.05, 0.05)))

    def brace(start: float, level: float, hold: float | None) -> ActivationProfile:
        """Antagonist: 0.1 in the squat, on to ``level`` in 50 ms at ``start`` (just before
        take-off), back to 0.1 after ``hold`` s (None: stays on)."""
        ramps = (Ramp(start, 0.05, level),)
        if hold is not None:
            ramps += (Ramp(hold, 0.05, 0.1),)
        return ActivationProfile(0.1, ramps)

    units = (
        Unit("plantarflexors", "ankle", 1, _leg_unit(350.0, 2.0, 4000.0), push(0.125, 0.06)),
        Unit("dorsiflexors", "ankle", -1, _leg_unit(100.0, 1.6, 1500.0),
             brace(0.235, 0.32, None)),
        Unit("knee_extensors", "knee", -1, _leg_unit(550.0, 1.2, 5000.0), push(0.045, 0.13)),
        Unit("knee_flexors", "knee", 1, _leg_unit(200.0, 0.8, 2500.0), brace(0.23, 0.44, 0.085)),
        Unit("hip_extensors", "hip", 1, _leg_unit(650.0, -1.4, 6000.0), push(0.03, 0.15)),
        Unit("hip_flexors", "hip", -1, _leg_unit(250.0, -1.0, 3000.0), brace(0.235, 0.31, 0.11)),
    )
    points = (Point("toe", "foot", 0.17), Point("heel", "foot", -0.0064, -0.094),
              Point("hip_joint", "thigh", 0.4222))
    contacts = (GroundContact("toe", slip_speed=0.15), GroundContact("heel", slip_speed=0.15))
    return ChainModel(
        "squat-jump", (foot, shank, thigh, hat), joints, units, duration=0.55, base="free",
        points=points, contacts=contacts, notes=(
            "Both legs together. Foot 1.37 %, shank 4.33 %, thigh 14.16 % of 73 kg (x2); shank "
            "0.434 m, CoM 44.59 % from the knee, radius of gyration 25.5 %; thigh 0.4222 m, "
            "CoM 40.95 % from the hip, 32.9 %; foot radius of gyration 24.5 % of 0.258 m (de "
            "Leva 1996). Head-arms-trunk: the remaining 44 kg, CoM 0.33 m above the hip, "
            "radius of gyration 0.25 m about it (est.).",
            "Foot: its axis runs from the ankle to the toe (0.17 m, the root of the free base); "
            "the heel 9.4 cm below that axis; the ankle 8 cm above the ground (est.).",
            "Joint torques for both legs (est., about twice single-leg isometric peaks of "
            "trained adult men: 175, 275 and 325 N m): plantarflexors 350, knee extensors 550, "
            "hip extensors 650 N m; antagonists 100-250 N m. SE stiffness 4000, 5000 and 6000 "
            "N m/rad for the extensors, 9-11 T0 per rad (est.).",
            "Ground contacts at toe and heel: Hunt-Crossley k = 5e6 N/m^1.5, n = 1.5, c = 1 s/m, "
            "regularised Coulomb friction mu = 0.8, slip speed 0.15 m/s "
            "(est.; at 0.1 m/s the friction's time constant during the push would hold every "
            "fixed step below 0.25 ms).",
            "Extensors on from the static squat, proximal to distal (hip at 30 ms, knee at 45 "
            "ms, ankle at 125 ms; 50 ms ramps to 1), held at full level for 150, 130 and 60 ms, "
            "then off (0.05) in 50 ms. Antagonists at 0.1 in the squat, braced for the flight "
            "from 230-235 ms (50 ms ramps: knee flexors to 0.44 for 85 ms, hip flexors to 0.31 "
            "for 110 ms, then back to 0.1; dorsiflexors to 0.32). Timings chosen by CMA-ES "
            "(scripts/tune_squat_jump.py, 15 timings and levels) for a flight near 0.28 m, "
            "|v_x| < 0.1 m/s at take-off and no end stop above 5 % of its joint's peak torque; "
            "recorded squat jumps of active adults fly 0.25-0.35 m.",))


def countermovement_jump() -> ChainModel:
    """A countermovement jump from quiet standing: the squat jump's body, units and contacts,
    standing still (knee 5°, hip 8° flexed) until 53 ms, lowering itself with its extensors
    (the centre of mass 0.27 m down) and pushing off proximal to distal while still
    descending; it leaves the ground at ≈0.80 s (flight ≈0.19 m)."""
    jump = squat_jump()
    standing = {"foot_ground": 62.28, "ankle": 114.28, "knee": 4.98, "hip": -8.19}  # deg
    joints = tuple(replace(j, initial_angle=math.radians(standing[j.name])) for j in jump.joints)

    def ramps(*rows: tuple[float, float, float]) -> tuple[Ramp, ...]:
        return tuple(Ramp(*row) for row in rows)

    # (delay after the previous ramp, duration, level): each extensor falls from its standing
    # level, rises to full through the braking and the push, and switches off (to 0.05) for
    # the flight; each antagonist stays at 0.1 until it braces for the flight.
    profiles = {
        "plantarflexors": ActivationProfile(None, ramps(
            (0.577, 0.088, 0.042), (0.0, 0.099, 1.0), (0.048, 0.05, 0.05))),
        "dorsiflexors": ActivationProfile(0.1, ramps((0.751, 0.05, 0.414))),
        "knee_extensors": ActivationProfile(None, ramps(
            (0.175, 0.165, 0.048), (0.172, 0.179, 1.0), (0.063, 0.05, 0.05))),
        "knee_flexors": ActivationProfile(0.1, ramps((0.719, 0.05, 0.461), (0.1, 0.05, 0.1))),
        "hip_extensors": ActivationProfile(None, ramps(
            (0.053, 0.174, 0.019), (0.191, 0.23, 1.0), (0.108, 0.05, 0.05))),
        "hip_flexors": ActivationProfile(0.1, ramps((0.733, 0.05, 0.37), (0.148, 0.05, 0.1))),
    }
    units = tuple(replace(u, activation=profiles[u.name]) for u in jump.units)
    return jump.replace(
        name="countermovement-jump", joints=joints, units=units, duration=1.04, notes=(
            *jump.notes[:4],
            "Quiet standing: ankle 114.28 deg (shank 3.4 deg forwards of upright), knee 4.98 "
            "and hip 8.19 deg flexed, the centre of mass 4 cm ahead of the ankle, the units at "
            "their static levels; the antagonists at 0.1 until they brace for the flight.",
            "Extensors: each falls from its standing level (hip from 53 ms to 0.019, knee from "
            "175 ms to 0.048, ankle from 577 ms to 0.042), rises to full activation through "
            "the braking and the push (hip 418-648 ms, knee 512-691 ms, ankle 665-764 ms), "
            "proximal to distal, and switches off (0.05) in 50 ms 108, 63 and 48 ms later. "
            "Antagonists braced for the flight from 719-751 ms (knee flexors 0.46, hip flexors "
            "0.37, dorsiflexors 0.41). Three ramps a unit, as fit and optimise take them. Made "
            "in steps (scripts/tune_countermovement_jump.py): a descent designed as each "
            "segment's angle by minimum jerk to the squat jump's squat, fitted by torquesim "
            "fit with the antagonists at 0.1; the squat jump's push added and tuned by CMA-ES; "
            "that motion fitted with three ramps a unit; CMA-ES for the highest flight with "
            "|v_x| <= 0.1 m/s at take-off, the centre of mass at least 0.2 m down and no end "
            "stop above 4.5 % of its joint's peak torque.",
            "The flight (about 0.19 m) is below the squat jump's: without activation dynamics "
            "the squat jump's extensors are at full level within 50 ms, so the countermovement "
            "adds no build-up of active state, the main source of the 2-4 cm people gain from "
            "it (Bobbert et al. 1996, Med Sci Sports Exerc 28:1402).",))


def squat_jump_biarticular() -> ChainModel:
    """The squat jump with three two-joint units beside its one-joint ones: gastrocnemius
    (ankle plantarflexor and knee flexor), rectus femoris (knee extensor and hip flexor) and
    hamstrings (hip extensor and knee flexor), each taking part of its one-joint neighbour's
    strength at its own joint and switching on with it (docs/model.md §7, two-joint units).
    It takes off at ≈0.27 s (flight ≈0.25 m, −0.05 m/s back)."""
    jump = squat_jump()
    one_joint = {"plantarflexors": (250.0, 2900.0), "knee_extensors": (430.0, 3900.0),
                 "hip_extensors": (470.0, 4300.0)}  # T0 (N m), SE stiffness (N m/rad)
    units = []
    for unit in jump.units:
        if unit.name in one_joint:
            t0, stiffness = one_joint[unit.name]
            unit = replace(unit, parameters=_leg_unit(t0, unit.parameters.optimal_angle,
                                                      stiffness))
        elif unit.activation.initial_level == 0.1:  # an antagonist: braced at 0.6 of the rise
            unit = replace(unit, activation=replace(unit.activation, ramps=tuple(
                replace(r, level=0.1 + 0.6 * (r.level - 0.1)) if r.level > 0.1 else r
                for r in unit.activation.ramps)))
        units.append(unit)

    def push(delay: float, hold: float) -> ActivationProfile:
        """As the squat jump's extensors, from a given 0.05 in the squat."""
        return ActivationProfile(0.05, (Ramp(delay, 0.05, 1.0), Ramp(hold, 0.05, 0.05)))

    units += [
        Unit("gastrocnemius", "ankle", 1, _leg_unit(100.0, 2.5, 1200.0), push(0.125, 0.06),
             second_joint="knee", second_arm=0.5),
        Unit("rectus_femoris", "knee", -1, _leg_unit(120.0, 0.3, 1300.0), push(0.045, 0.08),
             second_joint="hip", second_arm=-0.8),
        Unit("hamstrings", "hip", 1, _leg_unit(180.0, -0.7, 1700.0), push(0.03, 0.15),
             second_joint="knee", second_arm=0.5),
    ]
    return jump.replace(name="squat-jump-biarticular", units=tuple(units), notes=(
        *jump.notes,
        "Two-joint units (est.): gastrocnemius T0 100 N m at the ankle, moment arm at the knee "
        "half its arm at the ankle (r = 0.5, flexing the knee); rectus femoris 120 N m at the "
        "knee, r = -0.8 at the hip (flexing it); hamstrings 180 N m at the hip, r = 0.5 at the "
        "knee (flexing it). Their one-joint neighbours give up that strength (plantarflexors "
        "250, knee extensors 430, hip extensors 470 N m) and SE stiffness in proportion. Each "
        "switches on with its one-joint neighbour, from 0.05 in the squat (rectus femoris off "
        "50 ms sooner); optimal angles in the unit's own angle psi = q_j + d r q_j2 (2.5, 0.3 "
        "and -0.7 rad) near the middle of its range in the push. The antagonists' braces for "
        "the flight rise 0.6 as far as the squat jump's. Set by hand, not optimised: it "
        "leaves the ground less extended than the squat jump (knee 45, hip 33 deg flexed) "
        "and flies 0.25 m.",))


#: The drop landing's levels per unit: (brace, hold) for an extensor, (level,) for an
#: antagonist (`landing_activation`; chosen by scripts/tune_drop_landing.py).
LANDING_LEVELS = {"plantarflexors": (0.71, 0.17), "knee_extensors": (0.39, 0.02),
                  "hip_extensors": (0.2, 0.2), "dorsiflexors": (0.05,),
                  "knee_flexors": (0.12,), "hip_flexors": (0.12,)}


def landing_activation(levels: tuple[float, ...]) -> ActivationProfile:
    """A drop-landing unit's activation: from its standing level (equilibrium: the side a
    stand needs carries it, the other rests at 0) to ``levels[0]`` in 50 ms from touchdown;
    with a second level, held 30 ms, then to ``levels[1]`` in 100 ms (at 180 ms)."""
    ramps = (Ramp(0.0, 0.05, levels[0]),)
    if len(levels) > 1:
        ramps += (Ramp(0.03, 0.1, levels[1]),)
    return ActivationProfile(None, ramps)


def drop_landing() -> ChainModel:
    """A drop landing: the squat jump's body and units landing flat-footed from a 0.3 m drop
    (touchdown at 2.43 m/s, `ChainModel.landing_speed`) with knee 20° and hip 25° flexed, on
    shod contacts (10× softer than the jump's bare ones); the extensors brace in 50 ms, the
    knee flexes to ≈54° within 0.1 s and the body comes to rest over its feet, hip flexed
    ≈57°. The impact loads the contacts at their stiffest: the ground force peaks at ≈9
    body weights 13 ms after touchdown."""
    jump = squat_jump()
    landing = {"foot_ground": 62.28, "ankle": 108.0, "knee": 20.0, "hip": -25.0}  # deg
    joints = tuple(replace(j, initial_angle=math.radians(landing[j.name])) for j in jump.joints)
    units = tuple(replace(u, activation=landing_activation(LANDING_LEVELS[u.name]))
                  for u in jump.units)
    shod = tuple(replace(c, stiffness=5e5) for c in jump.contacts)
    return jump.replace(
        name="drop-landing", joints=joints, units=units, contacts=shod, duration=0.3,
        landing_speed=2.43,
        notes=(
            *jump.notes[:3],
            "Ground contacts at toe and heel as the squat jump's but shod: k = 5e5 N/m^1.5 "
            "(a sole and heel pad: 8 mm sink standing, est.), n = 1.5, c = 1 s/m, mu = 0.8, "
            "slip speed 0.15 m/s.",
            "Touchdown from a 0.3 m drop: 2.43 m/s straight down, both contacts touching at "
            "once (a flat-footed landing), in the posture of a static stand with the knee 20 "
            "and hip 25 deg flexed (ankle 108 deg) and the units as they would stand there.",
            "Every unit from its standing level (equilibrium: the side a stand needs carries "
            "it, the other rests) in 50 ms from touchdown: extensors to a brace "
            "(plantarflexors 0.71, knee extensors 0.39, hip extensors 0.2), held 30 ms, then "
            "in 100 ms to a hold (0.17, 0.02, 0.2); antagonists to 0.05 (dorsiflexors) and "
            "0.12 (knee and hip flexors). Levels chosen by CMA-ES (est.; "
            "scripts/tune_drop_landing.py) so that the body "
            "absorbs the fall without an end stop or a bounce and comes to rest over its feet; "
            "not fitted to a recorded landing, whose peak forces (often 3-6 body weights, "
            "landing on the forefoot first) it exceeds: the rigid flat foot and stiff SE "
            "springs pass the impact on at once.",))


PRESETS: dict[str, Callable[[], ChainModel]] = dict(zip(
    PRESET_NAMES, (elbow_curl, knee_extension, arm_raise, squat_jump, countermovement_jump,
                   squat_jump_biarticular, drop_landing), strict=True))


def is_preset(spec) -> bool:
    return isinstance(spec, str) and spec.startswith(PREFIX)


def preset(name: str) -> ChainModel:
    """The built-in model ``name`` (with or without the ``builtin:`` prefix)."""
    key = name[len(PREFIX):] if name.startswith(PREFIX) else name
    if key not in PRESETS:
        raise ModelError("model", f"{name!r} is not a built-in model; allowed: "
                         + ", ".join(PREFIX + k for k in PRESETS))
    return PRESETS[key]()
