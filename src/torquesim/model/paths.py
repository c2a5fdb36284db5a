"""Parameter paths: one vocabulary for naming a number in a model, shared by
``torquesim compare --vary``, ``torquesim batch sweep --vary``, ``torquesim fit --bound`` /
``--freeze`` and the Python API.

A path is dot-separated:

==============================  ==========================================================
``UNIT.FIELD``                  a torque generator parameter of a unit, e.g.
                                ``elbow_flexor.se_stiffness`` (units by name or alias:
                                ``flexor``, ``elbow.extensor``; see `ChainModel.unit_aliases`)
``UNIT.initial_level``          a unit's initial activation (when it has one)
``UNIT.second_arm``             a two-joint unit's moment-arm ratio r at its second joint
``UNIT.activation_time``,       τ_act, τ_deact of a unit with activation dynamics (s)
``UNIT.deactivation_time``
``UNIT.rampN.delay|duration|level``  the N-th activation ramp of a unit (N from 1)
``JOINT.FIELD``                 a joint's field, e.g. ``elbow.initial_angle`` (rad)
``SEGMENT.FIELD``               a segment's field, e.g. ``forearm_hand.mass`` (kg)
``SEGMENT.LOAD.FIELD``          a point load's mass, distance or inertia
``POINT.distance|offset``       where a named point sits on its segment (m)
``POINT.FIELD``                 the ground contact at a point: ``stiffness``, ``exponent``,
                                ``damping``, ``friction`` or ``slip_speed``, e.g.
                                ``toe.stiffness``
``gravity``, ``base_angle``,    the model's own numbers (``landing_speed``: a drop
``landing_speed``               landing's touchdown speed, m/s)
==============================  ==========================================================

Optional leading ``units.``, ``joints.``, ``segments.``, ``points.`` or ``contacts.`` are
accepted. Values are SI (the
units of the model file); a value that makes the model invalid is a `ModelError` naming the
path.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import fields, replace

from ..errors import ModelError
from . import activation, chain, contact
from .chain import ChainModel
from .fields import Allowed
from .torque_generator import UNIT_FIELDS, TorqueGeneratorUnit

#: The numbers each kind of path reaches, from the tables of allowed values (`Allowed`):
#: a ramp's, activation dynamics', a joint's, a segment's, a point load's, a point's and the
#: ground contact's at a point.
RAMP_FIELDS = tuple(activation.RAMP_FIELDS)
DYNAMICS_FIELDS = tuple(activation.DYNAMICS_FIELDS)
JOINT_FIELDS = tuple(chain.JOINT_FIELDS)
SEGMENT_FIELDS = tuple(chain.SEGMENT_FIELDS)
LOAD_FIELDS = tuple(chain.LOAD_FIELDS)
POINT_FIELDS = tuple(contact.POINT_FIELDS)
CONTACT_FIELDS = tuple(contact.CONTACT_FIELDS)
_RAMP = re.compile(r"ramp(\d+)")


#: The model's own numbers, each a path of one word.
MODEL_FIELDS = ("gravity", "base_angle", "landing_speed")
#: Every form of path, for the messages that say what a path may be.
HELP = (f"UNIT.FIELD, UNIT.initial_level, UNIT.second_arm (two-joint), "
        f"UNIT.rampN.{'|'.join(RAMP_FIELDS)}, UNIT.{'|'.join(DYNAMICS_FIELDS)}, "
        f"JOINT.{'|'.join(JOINT_FIELDS)}, SEGMENT.{'|'.join(SEGMENT_FIELDS)}, "
        f"SEGMENT.LOAD.{'|'.join(LOAD_FIELDS)}, POINT.{'|'.join(POINT_FIELDS)}, "
        f"POINT.{'|'.join(CONTACT_FIELDS)} (its contact), {', '.join(MODEL_FIELDS)}")
#: The optional first word of a path naming the kind of thing it names.
GROUPS = ("units", "joints", "segments", "points", "contacts")


def _parts(path: str) -> list[str]:
    parts = path.strip().split(".")
    if parts[0] in GROUPS and len(parts) >= 3:
        parts = parts[1:]
    return parts


def without_group(path: str) -> str:
    """``path`` stripped, without its optional leading ``units.``, ``joints.``, … (the form
    the fit's and the optimiser's parameter names take)."""
    return ".".join(_parts(path))


def _unit_names(model: ChainModel) -> dict[str, str]:
    return {u.name: u.name for u in model.units} | model.unit_aliases()


#: The allowed values of each kind of path's fields (`_locate`'s kinds).
_TABLES = {"model": chain.CHAIN_FIELDS, "unit": UNIT_FIELDS | activation.PROFILE_FIELDS,
           "geometry": chain.UNIT_GEOMETRY_FIELDS, "dynamics": activation.DYNAMICS_FIELDS,
           "ramp": activation.RAMP_FIELDS, "joint": chain.JOINT_FIELDS,
           "segment": chain.SEGMENT_FIELDS, "load": chain.LOAD_FIELDS,
           "point": contact.POINT_FIELDS, "contact": contact.CONTACT_FIELDS}


def _vocabulary(model: ChainModel) -> list[str]:
    """Every path the vocabulary could name on ``model``'s units and parts, in the order of
    the model file (some hold no number on this model: a one-joint unit's second arm)."""
    paths = list(MODEL_FIELDS)
    for s in model.segments:
        paths += [f"{s.name}.{f}" for f in SEGMENT_FIELDS]
        paths += [f"{s.name}.{ld.name}.{f}" for ld in s.loads for f in LOAD_FIELDS]
    paths += [f"{j.name}.{f}" for j in model.joints for f in JOINT_FIELDS]
    for u in model.units:
        paths += [f"{u.name}.{f}" for f in (*_TABLES["unit"], "second_arm", *DYNAMICS_FIELDS)]
        paths += [f"{u.name}.ramp{n}.{f}" for n in range(1, len(u.activation.ramps) + 1)
                  for f in RAMP_FIELDS]
    paths += [f"{p.name}.{f}" for p in model.points for f in POINT_FIELDS]
    return paths + [f"{c.point}.{f}" for c in model.contacts for f in CONTACT_FIELDS]


def model_paths(model: ChainModel) -> list[str]:
    """Every path of ``model`` that holds a number, by unit and part names, in the order of
    the model file: its own numbers, segments (and their loads), joints, units (parameters,
    initial level, second arm, activation dynamics, ramps), points and their contacts."""
    found = []
    for path in _vocabulary(model):
        try:
            _find(model, path, "path")
        except ModelError:  # a field this model leaves out (one-joint unit, no dynamics, …)
            continue
        found.append(path)
    return found


def allowed_at(model: ChainModel, path: str, field: str = "path") -> Allowed:
    """The unit, meaning and bounds (`Allowed`) of the number at ``path``."""
    kind, _, rest = _locate(model, path, field)
    return _TABLES[kind][rest[-1]]


def limits_at(model: ChainModel, path: str, field: str = "path") -> tuple[float, float, bool,
                                                                          bool]:
    """(low, high, low_open, high_open): the values ``model`` allows at ``path``, a bound
    that is another field's value read from ``model`` (`allowed_at`)."""
    allowed = allowed_at(model, path, field)
    owner = canonical_path(model, path, field).rpartition(".")[0]
    related = {b[1]: get_parameter(model, f"{owner}.{b[1]}" if owner else b[1], field)
               for b in (allowed.low, allowed.high) if isinstance(b, tuple)}
    return (*allowed.limits(related), allowed.low_open, allowed.high_open)


def _not_a_path(model: ChainModel, path: str, field: str) -> ModelError:
    if _parts(path) == ["duration"]:
        return ModelError(field, f"{path!r}: the run's length is no parameter to vary or "
                          "search (every candidate and sample runs the same steps); allowed: "
                          "simulate --duration, or the model file's duration")
    if _parts(path)[0] == "base":
        return ModelError(field, f"{path!r}: the base's start is no field; a free base starts "
                          "in static equilibrium on its ground contacts, or at touchdown with "
                          "landing_speed; allowed: base_angle, landing_speed, a joint's "
                          "initial_angle or initial_speed")
    close = difflib.get_close_matches(without_group(path), _vocabulary(model), n=3, cutoff=0.6)
    return ModelError(field, f"{path!r} is not a numeric model field"
                      + (f" (closest: {', '.join(close)})" if close else "")
                      + f"; allowed: {HELP} (units {', '.join(_unit_names(model))}; every "
                      "path of a model: torquesim model NAME --paths)")


def canonical_path(model: ChainModel, path: str, field: str = "path") -> str:
    """``path`` with a unit alias replaced by the unit's name and the optional leading
    ``units.``/``joints.``/``segments.`` dropped; a `ModelError` (on ``field``) if it names no
    number of ``model``."""
    kind, owner, rest, _ = _find(model, path, field)
    if kind == "ramp":
        return f"{owner}.ramp{rest[0] + 1}.{rest[1]}"
    return ".".join([owner, *rest] if owner else rest)


def _locate(model: ChainModel, path: str, field: str):
    """(kind, owner name, rest of the path) of ``path`` in ``model``."""
    parts = _parts(path)
    if len(parts) == 1 and parts[0] in MODEL_FIELDS:
        return "model", "", parts
    units = _unit_names(model)
    unit_fields = {f.name for f in fields(TorqueGeneratorUnit)}
    for cut in range(len(parts) - 1, 0, -1):  # unit names and aliases may contain dots
        head, rest = ".".join(parts[:cut]), parts[cut:]
        if head in units:
            unit = model.units[model.unit_index(units[head])]
            if len(rest) == 1 and rest[0] in unit_fields | {"initial_level"}:
                return "unit", unit.name, rest
            if rest == ["second_arm"]:
                if unit.second_joint is None:
                    raise ModelError(field, f"{path!r}: unit {unit.name} spans one joint; "
                                     "allowed: a two-joint unit (one with a second_joint)")
                return "geometry", unit.name, rest
            if len(rest) == 1 and rest[0] in DYNAMICS_FIELDS:
                if unit.activation_dynamics is None:
                    raise ModelError(field, f"{path!r}: unit {unit.name} has no activation "
                                     "dynamics; allowed: a unit with [units.activation_dynamics]")
                return "dynamics", unit.name, rest
            found = _RAMP.fullmatch(rest[0]) if len(rest) == 2 else None
            if found and rest[1] in RAMP_FIELDS:
                n = int(found.group(1))
                if not 1 <= n <= len(unit.activation.ramps):
                    raise ModelError(field, f"{path!r}: unit {unit.name} has "
                                     f"{len(unit.activation.ramps)} ramps; allowed ramp1"
                                     f"…ramp{len(unit.activation.ramps)}")
                return "ramp", unit.name, [n - 1, rest[1]]
    joints = {j.name for j in model.joints}
    if len(parts) == 2 and parts[0] in joints and parts[1] in JOINT_FIELDS:
        return "joint", parts[0], parts[1:]
    segments = {s.name: s for s in model.segments}
    if len(parts) == 2 and parts[0] in segments and parts[1] in SEGMENT_FIELDS:
        return "segment", parts[0], parts[1:]
    if len(parts) == 3 and parts[0] in segments and parts[2] in LOAD_FIELDS:
        if parts[1] in {ld.name for ld in segments[parts[0]].loads}:
            return "load", parts[0], parts[1:]
    if len(parts) == 2 and parts[1] in POINT_FIELDS and \
            parts[0] in {p.name for p in model.points}:
        return "point", parts[0], parts[1:]
    if len(parts) == 2 and parts[1] in CONTACT_FIELDS:
        if parts[0] in {c.point for c in model.contacts}:
            return "contact", parts[0], parts[1:]
        if parts[0] in {p.name for p in model.points}:
            raise ModelError(field, f"{path!r}: point {parts[0]} has no ground contact; "
                             f"allowed: {', '.join(c.point for c in model.contacts) or 'none'}")
    raise _not_a_path(model, path, field)


def _value(model: ChainModel, kind: str, owner: str, rest: list, field: str):
    """The number `_locate` found (None for a unit's "equilibrium" initial level; a segment's
    parent distance left to the model is its parent's length)."""
    if kind == "model":
        return getattr(model, rest[0])
    if kind == "unit":
        unit = model.units[model.unit_index(owner)]
        return unit.activation.initial_level if rest == ["initial_level"] else \
            getattr(unit.parameters, rest[0])
    if kind == "ramp":
        return getattr(model.units[model.unit_index(owner)].activation.ramps[rest[0]],
                       rest[1])
    if kind == "dynamics":
        return getattr(model.units[model.unit_index(owner)].activation_dynamics, rest[0])
    if kind == "geometry":
        return getattr(model.units[model.unit_index(owner)], rest[0])
    if kind == "joint":
        return getattr(model.joints[model.joint_index(owner)], rest[0])
    if kind == "point":
        return getattr(next(p for p in model.points if p.name == owner), rest[0])
    if kind == "contact":
        return getattr(next(c for c in model.contacts if c.point == owner), rest[0])
    segment = next(s for s in model.segments if s.name == owner)
    if kind == "segment":
        if rest == ["parent_distance"] and segment.parent_distance is None:
            k = [s.name for s in model.segments].index(owner)  # at the parent's length
            if model.parents[k] < 0:
                raise ModelError(field, f"{owner}.parent_distance: segment {owner} hangs "
                                 "from the base, not from a parent; allowed: a segment with a "
                                 "parent")
            return model.segments[model.parents[k]].length
        return getattr(segment, rest[0])
    return getattr(next(ld for ld in segment.loads if ld.name == rest[0]), rest[1])


def _find(model: ChainModel, path: str, field: str):
    """`_locate` of a path that holds a number (an "equilibrium" initial level does not)."""
    kind, owner, rest = _locate(model, path, field)
    value = _value(model, kind, owner, rest, field)
    if value is None:
        raise ModelError(field, f"{path!r}: unit {owner} starts from static equilibrium "
                         "(no initial level to read or change)")
    return kind, owner, rest, float(value)


def get_parameter(model: ChainModel, path: str, field: str = "path") -> float:
    """The number at ``path`` in ``model`` (SI)."""
    return _find(model, path, field)[3]


def set_parameter(model: ChainModel, path: str, value: float,
                  field: str = "path") -> ChainModel:
    """``model`` with the number at ``path`` set to ``value`` (SI); the changed model is
    validated, and a value that makes it invalid is a `ModelError` naming ``path``."""
    kind, owner, rest, _ = _find(model, path, field)
    value = float(value)
    try:
        if kind == "model":
            return model.replace(**{rest[0]: value})
        if kind == "unit":
            unit = model.units[model.unit_index(owner)]
            if rest == ["initial_level"]:
                return model.replace_unit(owner, activation=replace(unit.activation,
                                                                    initial_level=value))
            return model.replace_unit(owner, parameters=replace(unit.parameters,
                                                                **{rest[0]: value}))
        if kind == "geometry":
            return model.replace_unit(owner, **{rest[0]: value})
        if kind == "dynamics":
            dynamics = model.units[model.unit_index(owner)].activation_dynamics
            return model.replace_unit(owner, activation_dynamics=replace(dynamics,
                                                                         **{rest[0]: value}))
        if kind == "ramp":
            profile = model.units[model.unit_index(owner)].activation
            ramps = list(profile.ramps)
            ramps[rest[0]] = replace(ramps[rest[0]], **{rest[1]: value})
            return model.replace_unit(owner, activation=replace(profile, ramps=tuple(ramps)))
        if kind == "joint":
            return model.replace_joint(owner, **{rest[0]: value})
        if kind == "segment":
            return model.replace_segment(owner, **{rest[0]: value})
        if kind == "point":
            return model.replace(points=tuple(replace(p, **{rest[0]: value})
                                              if p.name == owner else p for p in model.points))
        if kind == "contact":
            return model.replace(contacts=tuple(replace(c, **{rest[0]: value})
                                                if c.point == owner else c
                                                for c in model.contacts))
        segment = next(s for s in model.segments if s.name == owner)
        loads = [replace(ld, **{rest[1]: value}) if ld.name == rest[0] else ld
                 for ld in segment.loads]
        return model.replace_segment(owner, loads=tuple(loads))
    except ModelError as exc:
        raise ModelError(path, f"{value:g} gives an invalid model: {exc.reason}") from None


def parse_assignment(text: str, field: str, example: str) -> tuple[str, str]:
    """``PATH=RIGHT`` → (PATH, RIGHT), both stripped: the one syntax of ``--vary``,
    ``--bound`` and ``--freeze`` (what RIGHT holds is the option's)."""
    path, eq, right = text.partition("=")
    if not eq or not path.strip() or not right.strip():
        raise ModelError(field, f"{text!r}; allowed PATH=..., e.g. {example}")
    return path.strip(), right.strip()
