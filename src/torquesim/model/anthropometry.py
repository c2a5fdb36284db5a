"""A built-in model made for one subject: segments from de Leva (1996), strengths scaled.

de Leva P (1996) Adjustments to Zatsiorsky–Seluyanov's segment inertia parameters. J Biomech
29:1223–1230, Table 4 (joint-centre endpoints): per sex, each segment's mean length, mass as a
fraction of body mass, centre of mass as a fraction of its length from the proximal end, and
radius of gyration about the sagittal axis as a fraction of its length. The means are of
Zatsiorsky's subjects: men 1.741 m and 73.0 kg, women 1.735 m and 61.9 kg.

The presets are built for de Leva's reference man (73 kg, 1.741 m). `for_subject` makes any of
them for a subject by the ratios of the subject's de Leva values to the reference man's, so that
the reference man gets the preset back exactly and a subject gets de Leva's proportions:

- a segment (or body-part load) that is a de Leva segment, or several laid end to end: its
  mass, length, centre of mass and inertia about the proximal joint times the ratio of the
  subject's de Leva values to the reference man's; loads and points on it move with its length;
- head-arms-trunk: the body mass left over (so the segments sum to the body mass), its centre
  of mass and length with the height, its inertia with mass × height²;
- external loads (a dumbbell, an ankle weight) keep their mass;
- each unit's T0 and T_max, and its SE stiffness (so the SE strain at T0 stays), times
  (body mass × height) / (73 kg × 1.741 m) × the ratio of Anderson et al.'s (2007) peak
  torque of the unit's exertion, for the subject's sex and age, to a young man's (see
  `strength_ratio`; a `torquesim strength` fit replaces the estimate).

Anderson DE, Madigan ML, Nussbaum MA (2007) Maximum voluntary joint torque as a function of
joint angle and angular velocity: model development and application to the lower limb. J
Biomech 40:3105–3113, Table 3: the mean peak isometric torque C1, normalised to body weight ×
height, of hip, knee and ankle extension and flexion, by sex, for ages 18–25, 55–65 and over
65 (their subjects' means stand here at 21.5, 60 and 70 years).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ModelError, check_range
from .yeadon_body import Part

SEXES = ("male", "female")
#: de Leva (1996) Table 4: (length m, mass fraction, CoM from proximal fraction, sagittal
#: radius of gyration fraction).
DE_LEVA = {
    "male": {
        "head": (0.2033, 0.0694, 0.5976, 0.362),
        "trunk": (0.5319, 0.4346, 0.4486, 0.372),
        "upper_arm": (0.2817, 0.0271, 0.5772, 0.285),
        "forearm": (0.2689, 0.0162, 0.4574, 0.276),
        "hand": (0.0862, 0.0061, 0.7900, 0.628),
        "thigh": (0.4222, 0.1416, 0.4095, 0.329),
        "shank": (0.4340, 0.0433, 0.4459, 0.255),
        "foot": (0.2581, 0.0137, 0.4415, 0.257),
    },
    "female": {
        "head": (0.2002, 0.0668, 0.5894, 0.330),
        "trunk": (0.5292, 0.4257, 0.4151, 0.357),
        "upper_arm": (0.2751, 0.0255, 0.5754, 0.278),
        "forearm": (0.2643, 0.0138, 0.4559, 0.261),
        "hand": (0.0780, 0.0056, 0.7474, 0.531),
        "thigh": (0.3685, 0.1478, 0.3612, 0.369),
        "shank": (0.4323, 0.0481, 0.4416, 0.271),
        "foot": (0.2283, 0.0129, 0.4014, 0.299),
    },
}
#: Segments that come in pairs (left and right).
PAIRED = ("upper_arm", "forearm", "hand", "thigh", "shank", "foot")
#: Mean stature of de Leva's (Zatsiorsky's) subjects, m.
STATURE = {"male": 1.741, "female": 1.735}
#: Anderson et al. (2007) Table 3, mean C1 (peak torque / (body weight × height)) by
#: (joint, direction) and sex, for the age groups 18–25, 55–65 and over 65.
ANDERSON_C1 = {
    ("hip", "extension"): {"male": (0.161, 0.171, 0.144), "female": (0.181, 0.140, 0.138)},
    ("hip", "flexion"): {"male": (0.113, 0.107, 0.101), "female": (0.127, 0.091, 0.081)},
    ("knee", "extension"): {"male": (0.163, 0.156, 0.137), "female": (0.159, 0.128, 0.124)},
    ("knee", "flexion"): {"male": (0.087, 0.081, 0.069), "female": (0.080, 0.060, 0.060)},
    ("ankle", "extension"): {"male": (0.095, 0.114, 0.106),
                             "female": (0.104, 0.093, 0.125)},
    ("ankle", "flexion"): {"male": (0.033, 0.028, 0.029), "female": (0.027, 0.024, 0.022)},
}
#: The age each of Anderson's groups stands for, years (18–25, 55–65, over 65; est.).
ANDERSON_AGES = (21.5, 60.0, 70.0)
#: The Anderson exertion of each preset unit (ankle extension is plantarflexion).
UNIT_EXERTION = {
    "hip_extensors": ("hip", "extension"), "hip_flexors": ("hip", "flexion"),
    "knee_extensors": ("knee", "extension"), "knee_extensor": ("knee", "extension"),
    "knee_flexors": ("knee", "flexion"), "knee_flexor": ("knee", "flexion"),
    "plantarflexors": ("ankle", "extension"), "dorsiflexors": ("ankle", "flexion"),
}

#: The subject the presets are built for.
REFERENCE_MASS, REFERENCE_HEIGHT, REFERENCE_SEX = 73.0, 1.741, "male"
#: The de Leva segments each preset segment or body-part load is, proximal first.
PRESET_PARTS = {
    "upper_arm": ("upper_arm",),
    "forearm_hand": ("forearm", "hand"),
    "shank_foot": ("shank",),
    "shank": ("shank",),
    "thigh": ("thigh",),
    "foot": ("foot",),
}
#: The segment that takes the body mass the others leave.
REMAINDER = "head_arms_trunk"


#: The bounds of a subject's measures: (low, high, unit), checked by `check_subject_value`.
SUBJECT_BOUNDS = {"body_mass": (20.0, 250.0, "kg"), "height": (1.0, 2.5, "m"),
                  "age": (18.0, 100.0, "years")}


def check_subject_value(field: str, value: float, name: str | None = None) -> None:
    """Refuse a subject's ``field`` (a key of `SUBJECT_BOUNDS`) outside its bounds, naming it
    ``name`` (default the field; the CLI gives its option)."""
    low, high, unit = SUBJECT_BOUNDS[field]
    check_range(name or field, value, low, high, unit=unit)


@dataclass(frozen=True)
class Subject:
    """A person a model is made for.

    Attributes
    ----------
    body_mass : float
        kg. Bounds [20, 250].
    height : float
        Standing height, m. Bounds [1.0, 2.5].
    sex : str
        "male" or "female" (de Leva's and Anderson's tables are by sex).
    age : float or None
        Years. Bounds [18, 100]. None: a young adult (Anderson's 18–25 group), as the
        presets' reference man.
    """

    body_mass: float
    height: float
    sex: str = "male"
    age: float | None = None

    def __post_init__(self) -> None:
        check_subject_value("body_mass", self.body_mass)
        check_subject_value("height", self.height)
        if self.sex not in SEXES:
            raise ModelError("sex", f"{self.sex!r}; allowed: {', '.join(SEXES)}")
        if self.age is not None:
            check_subject_value("age", self.age)


REFERENCE = Subject(REFERENCE_MASS, REFERENCE_HEIGHT, REFERENCE_SEX)


def segment_values(parts: tuple[str, ...], subject: Subject) -> tuple[float, float, float,
                                                                        float]:
    """(mass kg, length m, centre of mass from the proximal end m, inertia about the proximal
    end kg·m²) of de Leva segments ``parts`` laid end to end (e.g. forearm then hand), for
    ``subject``: lengths scaled by height/stature of the sex, masses by body mass."""
    table = DE_LEVA[subject.sex]
    scale = subject.height / STATURE[subject.sex]
    mass = moment = inertia = start = 0.0
    for part in parts:
        length, fraction, com, gyration = table[part]
        length *= scale
        m = fraction * subject.body_mass
        c = start + com * length
        mass += m
        moment += m * c
        inertia += m * ((gyration * length) ** 2 + c * c)
        start += length
    return mass, start, moment / mass, inertia


def strength_ratio(exertion: tuple[str, str] | None, sex: str, age: float | None) -> float:
    """Anderson et al.'s (2007) peak torque per body weight × height of ``exertion`` ((joint,
    direction), e.g. ("knee", "extension")) for ``sex`` at ``age`` (years; None: 21.5), over a
    young man's: linear in age between the groups' ages `ANDERSON_AGES`, constant beyond them.
    An exertion without a table (None: the elbow, the shoulder) takes the mean of the six
    lower-limb ratios (est.)."""
    years = ANDERSON_AGES[0] if age is None else age
    if exertion is None:
        return sum(strength_ratio(e, sex, years) for e in ANDERSON_C1) / len(ANDERSON_C1)
    table = ANDERSON_C1[exertion]
    return float(np.interp(years, ANDERSON_AGES, table[sex])) / table["male"][0]


def mass_fractions(sex: str) -> float:
    """The sum of de Leva's mass fractions over the whole body (paired segments twice)."""
    return sum(v[1] * (2 if k in PAIRED else 1) for k, v in DE_LEVA[sex].items())


def for_subject(model, subject: Subject):
    """``model`` (a preset, built for `REFERENCE`) made for ``subject`` (see the module's
    docstring for each rule). A model with a segment that is neither in `PRESET_PARTS` nor
    the remainder is refused."""
    _refuse_unknown(model)
    height_ratio = subject.height / REFERENCE.height
    length_ratio: dict[str, float] = {}
    segments = []
    body = 0.0
    for seg in model.segments:
        if seg.name == REMAINDER:
            segments.append(seg)
            length_ratio[seg.name] = height_ratio
            continue
        new = segment_values(PRESET_PARTS[seg.name], subject)
        old = segment_values(PRESET_PARTS[seg.name], REFERENCE)
        r_mass, r_length, r_com, r_inertia = (n / o for n, o in zip(new, old, strict=True))
        length_ratio[seg.name] = r_length
        loads = tuple(_scaled_load(load, subject, r_length) for load in seg.loads)
        body += seg.mass * r_mass + sum(ld.mass for ld in loads if ld.name in PRESET_PARTS)
        segments.append(replace(seg, mass=seg.mass * r_mass, length=seg.length * r_length,
                                com_distance=seg.com_distance * r_com,
                                inertia_about_joint=seg.inertia_about_joint * r_inertia,
                                loads=loads))
    for k, seg in enumerate(segments):
        if seg.name == REMAINDER:
            mass = subject.body_mass - body
            segments[k] = replace(seg, mass=mass, com_distance=seg.com_distance * height_ratio,
                                  length=seg.length * height_ratio,
                                  inertia_about_joint=seg.inertia_about_joint * mass / seg.mass
                                  * height_ratio ** 2)
    note = (f"Made for a {subject.sex} subject of {subject.body_mass:g} kg and "
            f"{subject.height:g} m: segments scaled from the preset (built for de Leva's 73 kg, "
            "1.741 m man) by the ratios of the subject's de Leva (1996, Table 4) segment masses, "
            "lengths, centres of mass and inertias to the reference man's; head-arms-trunk "
            "the body mass left over, its lengths with the height; external loads unchanged; ")
    return _finish(model, segments, length_ratio, subject, note)


def _refuse_unknown(model) -> None:
    """A model with a segment that is neither a de Leva part nor the remainder: one line."""
    unknown = [s.name for s in model.segments
               if s.name not in PRESET_PARTS and s.name != REMAINDER]
    if unknown:
        raise ModelError("body_mass", f"{model.name}: segment {unknown[0]!r} has no de Leva "
                         "segment; allowed: the built-in models")


def _finish(model, segments, length_ratio: dict, subject: Subject, note: str, joints=None):
    """The model with ``segments``; parent distances and points moved with their segment's
    length ratio; each unit's T0, T_max and SE stiffness times (body mass × height) / (73 kg ×
    1.741 m) × `strength_ratio` of its exertion for the subject's sex and age; ``note`` (with
    the factors appended) before the preset's notes."""
    out = []
    parents = model.parents
    for k, seg in enumerate(segments):
        if seg.parent_distance is not None and parents[k] >= 0:
            parent = model.segments[parents[k]].name
            seg = replace(seg, parent_distance=seg.parent_distance * length_ratio[parent])
        out.append(seg)
    points = tuple(replace(p, distance=p.distance * length_ratio[p.segment],
                           offset=p.offset * length_ratio[p.segment]) for p in model.points)
    size = (subject.body_mass * subject.height) / (REFERENCE.body_mass * REFERENCE.height)
    units, factors = [], []
    for u in model.units:
        ratio = strength_ratio(UNIT_EXERTION.get(u.name), subject.sex, subject.age)
        factor = size * ratio
        factors.append(f"{u.name} {factor:.4g}" + ("" if u.name in UNIT_EXERTION else
                                                   " (mean lower-limb ratio, est.)"))
        units.append(replace(u, parameters=replace(
            u.parameters, isometric_torque=u.parameters.isometric_torque * factor,
            eccentric_torque_max=u.parameters.eccentric_torque_max * factor,
            se_stiffness=u.parameters.se_stiffness * factor)))
    age = "a young adult (18-25)" if subject.age is None else f"{subject.age:g} years"
    note += (f"T0, T_max and SE stiffness times body mass x height ({size:.4g}) x Anderson et "
             f"al. (2007, Table 3) peak torque of the exertion for a {subject.sex} subject of "
             f"{age} over a young man's: {', '.join(factors)} (est.: fit strengths with "
             "torquesim strength). The notes below are the preset's, for its reference man.")
    return model.replace(segments=tuple(out), points=points, units=tuple(units),
                         joints=model.joints if joints is None else joints,
                         notes=(note, *model.notes))


#: The reference man's ankle-to-toe-tip distance, m: de Leva's foot (heel to toe tip, 0.2581 m)
#: less the preset's heel 5 cm behind the ankle, with the ankle 8 cm up (est.). A measured
#: foot's ankle-to-toe-tip over it scales the preset's foot points.
REFERENCE_ANKLE_TO_TOE_TIP = math.hypot(0.2581 - 0.05, 0.08)


def for_measured(model, body, body_mass: float | None = None, height: float | None = None,
                 sex: str = "male", age: float | None = None):
    """``model`` (a preset) made for a subject measured for Yeadon's inertia model (``body``:
    a `torquesim.model.yeadon_body.MeasuredBody`): each segment's mass, length, centre of
    mass and sagittal inertia about its proximal joint in the model are the measured parts'
    (times the number of sides the preset lumps, e.g. both legs); the foot's points scale
    with its ankle-to-toe-tip length; head-arms-trunk takes the body mass left over, its
    centre of mass and inertia measured, its drawn length with the height; external loads
    keep their mass. Strengths as `for_subject`'s (body mass × height × Anderson's ratio for
    ``sex`` and ``age``), the body mass and height being given or the measured body's."""
    subject = Subject(body.mass if body_mass is None else body_mass,
                      body.height if height is None else height, sex, age)
    _refuse_unknown(model)
    parts = body.parts
    length_ratio: dict[str, float] = {}
    segments = []
    others = 0.0
    for seg in model.segments:
        if seg.name == REMAINDER:
            segments.append(seg)
            continue
        names = PRESET_PARTS[seg.name]
        ref_mass, ref_length, ref_com, _ = segment_values(names, REFERENCE)
        sides = max(1, round(seg.mass / ref_mass))
        if names == ("foot",):
            foot = parts["foot"]
            length = seg.length * foot.length / REFERENCE_ANKLE_TO_TOE_TIP
            mass, com, inertia = foot.mass, foot.com, foot.inertia_about(foot.com)
        else:
            chain = [parts[n] for n in names]
            length = sum(p.length for p in chain)
            starts = [sum(p.length for p in chain[:i]) for i in range(len(chain))]
            mass = sum(p.mass for p in chain)
            com = sum(p.mass * (s + p.com) for p, s in zip(chain, starts, strict=True)) / mass
            # a preset segment may run the other way (the jump's shank from the ankle)
            if abs(seg.com_distance - (ref_length - ref_com)) < abs(seg.com_distance - ref_com):
                starts = [length - s - p.length for p, s in zip(chain, starts, strict=True)]
                chain = [Part(p.mass, p.length, p.length - p.com, p.offset, p.inertia)
                         for p in chain]
                com = length - com
            inertia = sum(p.inertia_about(s + p.com) for p, s in zip(chain, starts,
                                                                        strict=True))
        length_ratio[seg.name] = length / seg.length
        loads = tuple(_measured_load(load, parts, length_ratio[seg.name], sides)
                      for load in seg.loads)
        others += sides * mass + sum(ld.mass for ld in loads if ld.name in PRESET_PARTS)
        segments.append(replace(seg, mass=sides * mass, length=length, com_distance=com,
                                inertia_about_joint=sides * inertia, loads=loads))
    hat = parts["head_arms_trunk"]
    height_ratio = subject.height / REFERENCE.height
    out = []
    for seg in segments:
        if seg.name == REMAINDER:
            mass = subject.body_mass - others
            length_ratio[seg.name] = height_ratio
            seg = replace(seg, mass=mass, com_distance=hat.com,
                          length=seg.length * height_ratio,
                          inertia_about_joint=hat.inertia_about(hat.com) * mass / hat.mass)
        out.append(seg)
    note = (f"Made from Yeadon measurements, {body.source}, for a body of "
            f"{subject.body_mass:.4g} kg and {subject.height:.4g} m: each segment's mass, "
            "length, centre of mass and sagittal inertia from Yeadon's (1990) inertia model "
            "(the yeadon package), both sides where the preset lumps them; foot points scaled "
            f"by its ankle-to-toe-tip length over {REFERENCE_ANKLE_TO_TOE_TIP:.3f} m; "
            "head-arms-trunk the body mass left over, its centre of mass and inertia measured; "
            "external loads unchanged; ")
    joints, lean = _balanced(model, out)
    if lean:
        note += (f"the trunk leans {math.degrees(lean):+.1f} deg from the preset's squat so "
                 "that the centre of mass stays over the same point of the feet; ")
    return _finish(model, out, length_ratio, subject, note, joints)


def _com_x(model, segments, joints) -> float:
    """The horizontal centre of mass of ``segments`` posed at ``joints``' initial angles, from
    the base, m (the chain's geometry as `ChainModel.kinematics`, for segments not yet in a
    model)."""
    phi = [0.0] * len(segments)
    where = [0.0] * len(segments)
    moment = mass = 0.0
    for k, p in enumerate(model.parents):
        phi[k] = (model.base_angle if p < 0 else phi[p]) + joints[k].initial_angle
        if p >= 0:
            seg = segments[k]
            along = segments[p].length if seg.parent_distance is None else seg.parent_distance
            where[k] = where[p] + along * math.sin(phi[p])
        moment += segments[k].total_mass * where[k] + segments[k].first_moment * math.sin(phi[k])
        mass += segments[k].total_mass
    return moment / mass


def _balanced(model, segments):
    """(``model``'s joints with head-arms-trunk's joint turned so the measured body's centre
    of mass is as far forward of the base as the preset's, the turn in rad) on a free base; a
    fixed base unchanged. A standing body's balance depends on it: a lighter or shorter trunk
    shifts the centre of mass back off the forefoot the preset's units are set to hold."""
    if model.base != "free":
        return model.joints, 0.0
    from scipy.optimize import brentq

    k = next(i for i, seg in enumerate(model.segments) if seg.name == REMAINDER)
    joint = model.joints[k]
    goal = _com_x(model, model.segments, model.joints)

    def offset(turn: float) -> float:
        joints = list(model.joints)
        joints[k] = replace(joint, initial_angle=joint.initial_angle + turn)
        return _com_x(model, segments, joints) - goal

    low, high = joint.endstop_lower_angle - joint.initial_angle, \
        joint.endstop_upper_angle - joint.initial_angle
    low, high = max(low, -0.6), min(high, 0.6)
    if offset(low) * offset(high) > 0:
        raise ModelError("--measurements", "no trunk lean within 0.6 rad of the preset's puts "
                         "the measured body's centre of mass over the preset's; allowed: a body "
                         "whose proportions the preset's posture can hold")
    turn = brentq(offset, low, high, xtol=1e-12)
    joints = list(model.joints)
    joints[k] = replace(joint, initial_angle=joint.initial_angle + turn)
    return tuple(joints), turn


def _measured_load(load, parts, length_ratio: float, sides: int):
    """A body-part load (the knee model's foot) as the measured part; an external one only
    moved with its segment's length."""
    if load.name not in PRESET_PARTS:
        return replace(load, distance=load.distance * length_ratio)
    part = parts[PRESET_PARTS[load.name][0]]
    return replace(load, mass=sides * part.mass, distance=load.distance * length_ratio,
                   inertia=sides * part.inertia)


def _scaled_load(load, subject: Subject, length_ratio: float):
    """A body-part load (the knee model's foot) scaled as its de Leva segment; an external one
    (a dumbbell) only moved with its segment's length."""
    if load.name not in PRESET_PARTS:
        return replace(load, distance=load.distance * length_ratio)
    new = segment_values(PRESET_PARTS[load.name], subject)
    old = segment_values(PRESET_PARTS[load.name], REFERENCE)
    r_mass = new[0] / old[0]
    gyration_ratio = math.sqrt((new[3] / new[0] - new[2] ** 2) / (old[3] / old[0] - old[2] ** 2))
    return replace(load, mass=load.mass * r_mass, distance=load.distance * length_ratio,
                   inertia=load.inertia * r_mass * gyration_ratio ** 2)
