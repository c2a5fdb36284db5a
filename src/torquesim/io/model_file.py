"""Read and write a model as TOML.

A chain model (docs/model-files.md)::

    name = "arm-raise"
    duration = 3.0           # s
    gravity = 9.81           # m/s^2
    base_angle = 0.0         # rad
    notes = ["sources ..."]  # free text, kept on a round trip

    [[segments]]             # proximal to distal; segment k hangs from joint k
    name = "upper_arm"
    mass = 1.978             # kg
    com_distance = 0.1626    # m, from its proximal joint
    inertia_about_joint = 0.0650  # kg m^2
    length = 0.2817          # m, to the next joint
    loads = [{ name = "dumbbell", mass = 2.0, distance = 0.337, inertia = 0.009 }]

    [[joints]]               # one per segment, same order
    name = "shoulder"
    initial_angle = 0.1      # rad
    positive = "flexion"     # what a growing angle is (default flexion; the jump's hip:
                             # extension, its ankle: plantarflexion)
    endstop_torque = 1.0 ...

    [[units]]
    name = "shoulder_flexor"
    joint = "shoulder"
    direction = "flexor"     # or "extensor" (+1 / -1: towards the joint's positive way)
    isometric_torque = 60.0 ...  # every TorqueGeneratorUnit field
    [units.activation]
    initial_level = "equilibrium"   # or a number in [0, 1]
    ramps = [{ delay = 0.1, duration = 0.3, level = 0.5 }, ...]
    [units.activation_dynamics]     # optional: the profile is then the excitation
    activation_time = 0.015         # s
    deactivation_time = 0.050       # s

Every key is checked: an unknown or missing key, a wrong type or a value out of range is a
`ModelError` naming it. The elbow files of torquesim 0.1 (``[body]``,
``[flexor]``, ``[extensor]``) still load, as the one-segment chain they describe.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

from ..errors import ModelError
from ..model.activation import (
    DYNAMICS_FIELDS,
    PROFILE_FIELDS,
    RAMP_FIELDS,
    ActivationDynamics,
    ActivationProfile,
    Ramp,
)
from ..model.body import BodyParameters
from ..model.chain import (
    CHAIN_FIELDS,
    JOINT_FIELDS,
    LOAD_FIELDS,
    POSITIVE_MOTIONS,
    SEGMENT_FIELDS,
    UNIT_GEOMETRY_FIELDS,
    ChainModel,
    Joint,
    PointLoad,
    Segment,
    Unit,
)
from ..model.chain import OPPOSITE_MOTIONS as OPPOSITE
from ..model.contact import CONTACT_FIELDS, POINT_FIELDS, GroundContact, Point
from ..model.elbow import ElbowModel
from ..model.torque_generator import UNIT_FIELDS, TorqueGeneratorUnit
from .atomic import write_text_atomic

EQUILIBRIUM = "equilibrium"
DIRECTIONS = {"flexor": 1, "extensor": -1, 1: 1, -1: -1}

#: Every number of a model file, by the file's section: the tables of allowed values
#: (`Allowed`) that the classes' range checks read (docs/model-files.md shows them).
FIELD_TABLES = {
    "top level": CHAIN_FIELDS, "[[segments]]": SEGMENT_FIELDS, "loads": LOAD_FIELDS,
    "[[joints]]": JOINT_FIELDS, "[[units]]": {**UNIT_FIELDS, **UNIT_GEOMETRY_FIELDS},
    "[units.activation]": PROFILE_FIELDS, "ramps": RAMP_FIELDS,
    "[units.activation_dynamics]": DYNAMICS_FIELDS, "[[points]]": POINT_FIELDS,
    "[[contacts]]": CONTACT_FIELDS,
}
#: One-line documentation written beside each key: unit, meaning and allowed range, from
#: `FIELD_TABLES` (but the sections written without comments: a load's and a ramp's keys sit
#: in inline tables, the initial level is a number or "equilibrium"), and for the keys that
#: are not numbers.
FIELD_DOCS = {
    "coordinate": "output column / OpenSim coordinate name",
    "positive": "what a growing angle is: " + ", ".join(POSITIVE_MOTIONS),
    "base": "fixed (a pivot at the origin) or free (stands on its contacts)",
    "second_joint": "a two-joint unit: the adjacent joint it also spans",
    **{name: allowed.text() for section, table in FIELD_TABLES.items()
       if section not in ("loads", "[units.activation]", "ramps")
       for name, allowed in table.items()},
}
SEGMENT_KEYS = ("name", "mass", "com_distance", "inertia_about_joint", "length", "loads",
                "parent", "parent_distance")
POINT_KEYS = ("name", "segment", "distance", "offset")
CONTACT_KEYS = ("point", "stiffness", "exponent", "damping", "friction", "slip_speed")
LOAD_KEYS = ("name", "mass", "distance", "inertia")
JOINT_KEYS = ("name", "initial_angle", "endstop_torque", "endstop_angle_scale",
              "endstop_lower_angle", "endstop_upper_angle", "coordinate", "initial_speed",
              "positive")
UNIT_KEYS = ("name", "joint", "direction", "second_joint", "second_arm", "activation",
             "activation_dynamics", *TorqueGeneratorUnit.field_names())
DYNAMICS_KEYS = ("activation_time", "deactivation_time")
TOP_KEYS = ("name", "duration", "gravity", "base_angle", "notes", "base", "landing_speed",
            "segments", "joints", "units", "points", "contacts")
LEGACY_KEYS = ("initial_angle", "duration", "body", "flexor", "extensor")
REQUIRED_UNIT_KEYS = tuple(k for k in TorqueGeneratorUnit.field_names()
                           if k not in ("eccentric_slope_ratio", "ce_damping"))


def _number(key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelError(key, f"must be a number, got {value!r}")
    return float(value)


def _text(key: str, value) -> str:
    if not isinstance(value, str):
        raise ModelError(key, f"must be a string, got {value!r}")
    return value


def _table(key: str, value) -> dict:
    if not isinstance(value, dict):
        raise ModelError(key, "must be a table")
    return value


def _array_of_tables(key: str, value) -> list:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise ModelError(key, f"must be an array of tables ([[{key}]] entries)")
    return value


def _check_keys(prefix: str, table: dict, allowed, required=()) -> None:
    for key in table:
        if key not in allowed:
            name = f"{prefix}.{key}" if prefix else key
            raise ModelError(name, f"unknown key; allowed: {', '.join(sorted(allowed))}")
    for key in required:
        if key not in table:
            raise ModelError(f"{prefix}.{key}" if prefix else key, "is missing")


def _build(cls, prefix: str, table: dict, defaults: dict):
    _check_keys(prefix, table, defaults)
    values = dict(defaults)
    for key, value in table.items():
        values[key] = _number(f"{prefix}.{key}", value)
    try:
        return cls(**values)
    except ModelError as exc:
        raise exc.under(prefix) from None


def _profile(prefix: str, table: dict, default: ActivationProfile | None) -> ActivationProfile:
    _check_keys(prefix, table, ("initial_level", "ramps"))
    if default is None and "initial_level" not in table:
        raise ModelError(f"{prefix}.initial_level", 'is missing; allowed "equilibrium" or a '
                         "number in [0, 1]")
    fallback = EQUILIBRIUM if default is None or default.initial_level is None \
        else default.initial_level
    level = table.get("initial_level", fallback)
    if level == EQUILIBRIUM:
        level = None
    else:
        level = _number(f"{prefix}.initial_level", level)
    ramps = default.ramps if default is not None else ()
    if "ramps" in table:
        if not isinstance(table["ramps"], list):
            raise ModelError(f"{prefix}.ramps", "must be an array of {delay, duration, level}")
        ramps = []
        for i, item in enumerate(table["ramps"]):
            name = f"{prefix}.ramps[{i}]"
            item = _table(name, item)
            _check_keys(name, item, ("delay", "duration", "level"),
                        ("delay", "duration", "level"))
            try:
                ramps.append(Ramp(*(_number(f"{name}.{k}", item[k])
                                    for k in ("delay", "duration", "level"))))
            except ModelError as exc:
                raise exc.under(name) from None
    try:
        return ActivationProfile(level, tuple(ramps))
    except ModelError as exc:
        raise exc.under(prefix) from None


def _legacy_elbow(data: dict) -> ElbowModel:
    """An elbow model from the torquesim 0.1 layout (missing keys: docs/model.md defaults)."""
    default = ElbowModel()
    _check_keys("", data, LEGACY_KEYS)
    body = _build(BodyParameters, "body", _table("body", data.get("body", {})),
                  default.body.as_dict())
    units, profiles = {}, {}
    for name in ("flexor", "extensor"):
        table = dict(_table(name, data.get(name, {})))
        activation = _table(f"{name}.activation", table.pop("activation", {}))
        units[name] = _build(TorqueGeneratorUnit, name, table, getattr(default, name).as_dict())
        profiles[name] = _profile(f"{name}.activation", activation,
                                  getattr(default, f"{name}_activation"))
    kwargs = {}
    for key in ("initial_angle", "duration"):
        if key in data:
            kwargs[key] = _number(key, data[key])
    return ElbowModel(body=body, flexor=units["flexor"], extensor=units["extensor"],
                      flexor_activation=profiles["flexor"],
                      extensor_activation=profiles["extensor"], **kwargs)


def _segment(i: int, table: dict) -> Segment:
    prefix = f"segments[{i}]"
    _check_keys(prefix, table, SEGMENT_KEYS, ("name", "mass", "com_distance",
                                              "inertia_about_joint"))
    loads = []
    raw_loads = table.get("loads", [])
    for k, load in enumerate(_array_of_tables(f"{prefix}.loads", raw_loads)):
        where = f"{prefix}.loads[{k}]"
        _check_keys(where, load, LOAD_KEYS, ("name", "mass", "distance"))
        try:
            loads.append(PointLoad(_text(f"{where}.name", load["name"]),
                                   *(_number(f"{where}.{key}", load[key])
                                     for key in ("mass", "distance") if key in load),
                                   _number(f"{where}.inertia", load.get("inertia", 0.0))))
        except ModelError as exc:
            raise exc.under(where) from None
    where = table.get("parent_distance")
    try:
        return Segment(_text(f"{prefix}.name", table["name"]),
                       _number(f"{prefix}.mass", table["mass"]),
                       _number(f"{prefix}.com_distance", table["com_distance"]),
                       _number(f"{prefix}.inertia_about_joint", table["inertia_about_joint"]),
                       _number(f"{prefix}.length", table.get("length", 0.0)), tuple(loads),
                       _text(f"{prefix}.parent", table.get("parent", "")),
                       None if where is None else _number(f"{prefix}.parent_distance", where))
    except ModelError as exc:
        raise exc.under(prefix) from None


def _point(i: int, table: dict) -> Point:
    prefix = f"points[{i}]"
    _check_keys(prefix, table, POINT_KEYS, ("name", "segment", "distance"))
    try:
        return Point(_text(f"{prefix}.name", table["name"]),
                     _text(f"{prefix}.segment", table["segment"]),
                     _number(f"{prefix}.distance", table["distance"]),
                     _number(f"{prefix}.offset", table.get("offset", 0.0)))
    except ModelError as exc:
        raise exc.under(prefix) from None


def _contact(i: int, table: dict) -> GroundContact:
    prefix = f"contacts[{i}]"
    _check_keys(prefix, table, CONTACT_KEYS, ("point",))
    values = {key: (_text if key == "point" else _number)(f"{prefix}.{key}", value)
              for key, value in table.items()}
    try:
        return GroundContact(**values)
    except ModelError as exc:
        raise exc.under(prefix) from None


def _joint(i: int, table: dict) -> Joint:
    prefix = f"joints[{i}]"
    _check_keys(prefix, table, JOINT_KEYS, ("name", "initial_angle"))
    values = {key: (_text if key in ("name", "coordinate", "positive") else _number)(
        f"{prefix}.{key}", value) for key, value in table.items()}
    try:
        return Joint(**values)
    except ModelError as exc:
        raise exc.under(prefix) from None


def _unit(i: int, table: dict) -> Unit:
    prefix = f"units[{i}]"
    _check_keys(prefix, table, UNIT_KEYS, ("name", "joint", "direction", "activation",
                                           *REQUIRED_UNIT_KEYS))
    direction = table["direction"]
    if isinstance(direction, bool) or direction not in DIRECTIONS:
        raise ModelError(f"{prefix}.direction", f"{direction!r}; allowed \"flexor\", "
                         "\"extensor\", 1 or -1")
    params = {k: v for k, v in table.items() if k in TorqueGeneratorUnit.field_names()}
    parameters = _build(TorqueGeneratorUnit, prefix, params,
                        {k: params.get(k) for k in TorqueGeneratorUnit.field_names()
                         if k in params or k in REQUIRED_UNIT_KEYS})
    activation = _profile(f"{prefix}.activation",
                          _table(f"{prefix}.activation", table["activation"]), None)
    dynamics = None
    if "activation_dynamics" in table:
        key = f"{prefix}.activation_dynamics"
        defaults = ActivationDynamics()
        dynamics = _build(ActivationDynamics, key, _table(key, table["activation_dynamics"]),
                          {k: getattr(defaults, k) for k in DYNAMICS_KEYS})
    spans = {}
    if "second_joint" in table:
        spans["second_joint"] = _text(f"{prefix}.second_joint", table["second_joint"])
    if "second_arm" in table:
        spans["second_arm"] = _number(f"{prefix}.second_arm", table["second_arm"])
    try:
        return Unit(_text(f"{prefix}.name", table["name"]), _text(f"{prefix}.joint",
                                                                 table["joint"]),
                    DIRECTIONS[direction], parameters, activation, dynamics, **spans)
    except ModelError as exc:
        raise exc.under(prefix) from None


def model_from_dict(data: dict) -> ChainModel:
    """Build and validate a model from the parsed TOML mapping (chain or 0.1 elbow layout)."""
    if not any(key in data for key in ("segments", "joints", "units")) and \
            all(key in LEGACY_KEYS for key in data):
        return _legacy_elbow(data).to_chain()
    _check_keys("", data, TOP_KEYS)
    parts = {}
    for key, build in (("segments", _segment), ("joints", _joint), ("units", _unit)):
        _check_keys("", data, TOP_KEYS, (key,))  # in file order: report the first problem
        parts[key] = [build(i, t) for i, t in enumerate(_array_of_tables(key, data[key]))]
    segments, joints, units = parts["segments"], parts["joints"], parts["units"]
    for key, build in (("points", _point), ("contacts", _contact)):
        parts[key] = [build(i, t) for i, t in enumerate(_array_of_tables(key,
                                                                         data.get(key, [])))]
    notes = data.get("notes", [])
    if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
        raise ModelError("notes", "must be an array of strings")
    kwargs = {key: _number(key, data[key])
              for key in ("duration", "gravity", "base_angle", "landing_speed") if key in data}
    if "base" in data:
        kwargs["base"] = _text("base", data["base"])
    # Every field present before the whole-model checks (a missing length would otherwise
    # show as a posture that cannot stand): a joint at the default place needs that place.
    # (Parents are found by name: with duplicate names the model's own check speaks first.)
    names = [seg.name for seg in segments]
    for k, seg in enumerate(segments[1:] if len(set(names)) == len(names) else [], start=1):
        p = names.index(seg.parent) if seg.parent in names[:k] else k - 1
        if seg.parent_distance is None and "length" not in data["segments"][p]:
            raise ModelError(f"segments[{p}].length", "is missing: the distance to the next "
                             "joint, m; allowed [0, 10] (only a segment whose children give "
                             "their parent_distance may omit it)")
    return ChainModel(name=_text("name", data.get("name", "model")), segments=tuple(segments),
                      joints=tuple(joints), units=tuple(units), notes=tuple(notes),
                      points=tuple(parts["points"]), contacts=tuple(parts["contacts"]),
                      **kwargs)


def load_model(path) -> ChainModel:
    """Read a model TOML file, or a preset named ``builtin:NAME``; errors name the key and the
    allowed range."""
    from ..model.presets import is_preset, preset

    if is_preset(path):
        return preset(str(path))
    if not isinstance(path, (str, Path)):
        raise TypeError(f"path: expected a file name, got {type(path).__name__}")
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark is fine
    except OSError as exc:
        raise ModelError("model", f"cannot read {str(path)!r}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ModelError("model", f"{str(path)!r} is not UTF-8 text; allowed: a TOML model "
                         "file (docs/model-files.md)") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError("model", f"{str(path)!r} is not valid TOML: {exc}") from None
    if not data:
        raise ModelError("model", f"{str(path)!r} is empty; allowed: a TOML model file with "
                         "[[segments]], [[joints]] and [[units]] (write one with `torquesim "
                         "model NAME --out FILE`)")
    return model_from_dict(data)


def _value(x) -> str:
    if isinstance(x, str):
        return '"' + x.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(float(x))


def _line(key: str, value) -> str:
    doc = FIELD_DOCS.get(key)
    return f"{key} = {_value(value)}" + (f"  # {doc}" if doc else "")


def _direction_line(unit, positive: str) -> str:
    """A unit's direction: "flexor"/"extensor" at a joint whose positive way is flexion, else
    +1/−1 with the motion it pulls towards (the jump's hip extensors pull +1, extension)."""
    if positive == "flexion":
        return f"direction = {_value('flexor' if unit.direction == 1 else 'extensor')}"
    return (f"direction = {unit.direction}  # {'+' if unit.direction == 1 else '-'}1: pulls "
            f"towards {unit.joint} {positive if unit.direction == 1 else OPPOSITE[positive]}")


def model_to_toml(model) -> str:
    """The model (chain or elbow) as commented TOML in the chain layout (exact float round
    trip)."""
    from ..model.chain import as_chain

    m = as_chain(model)
    positive = {j.name: j.positive for j in m.joints}
    lines = ["# torquesim model: a planar chain. SI units, angles in radians.",
             "# Format: docs/model-files.md. Sources of the values: the notes below."]
    lines += [f"# {note}" for note in m.notes]
    lines += [f"name = {_value(m.name)}", _line("duration", m.duration),
              _line("gravity", m.gravity), _line("base_angle", m.base_angle)]
    if m.base != "fixed":
        lines.append(f"base = {_value(m.base)}  # {FIELD_DOCS['base']}")
    if m.landing_speed:
        lines.append(_line("landing_speed", m.landing_speed))
    if m.notes:
        lines.append("notes = [" + ", ".join(_value(n) for n in m.notes) + "]")
    for seg in m.segments:
        lines += ["", "[[segments]]", f"name = {_value(seg.name)}"]
        lines += [_line(k, getattr(seg, k)) for k in SEGMENT_KEYS[1:5]]
        loads = ", ".join(f"{{ name = {_value(ld.name)}, mass = {_value(ld.mass)}, distance = "
                          f"{_value(ld.distance)}, inertia = {_value(ld.inertia)} }}"
                          for ld in seg.loads)
        lines.append(f"loads = [{loads}]  # point loads on the segment axis (kg, m, kg m^2)")
        if seg.parent:
            lines.append(f"parent = {_value(seg.parent)}")
        if seg.parent_distance is not None:
            lines.append(_line("parent_distance", seg.parent_distance))
    for joint in m.joints:
        lines += ["", "[[joints]]", f"name = {_value(joint.name)}",
                  _line("initial_angle", joint.initial_angle)
                  + f" (= {math.degrees(joint.initial_angle):.4g} deg)"]
        lines += [_line(k, getattr(joint, k)) for k in JOINT_KEYS[2:-2]]
        if joint.initial_speed:
            lines.append(_line("initial_speed", joint.initial_speed)
                         + f" (= {math.degrees(joint.initial_speed):.4g} deg/s)")
        if joint.positive != "flexion":
            lines.append(_line("positive", joint.positive))
    for unit in m.units:
        lines += ["", "[[units]]", f"name = {_value(unit.name)}",
                  f"joint = {_value(unit.joint)}",
                  _direction_line(unit, positive[unit.joint])]
        if unit.second_joint is not None:
            lines += [f"second_joint = {_value(unit.second_joint)}  "
                      f"# {FIELD_DOCS['second_joint']}", _line("second_arm", unit.second_arm)]
        lines += [_line(k, v) for k, v in unit.parameters.as_dict().items()]
        profile = unit.activation
        lines += ["[units.activation]",
                  "# a(t): initial level, then quintic ramps (delay after the previous ramp "
                  "ends [s], duration [s], new level [0, 1])"]
        level = profile.initial_level
        lines.append("initial_level = " + ('"equilibrium"  # solved so the chain starts at '
                                           'rest' if level is None else _value(level)))
        lines.append("ramps = [")
        lines += [f"    {{ delay = {_value(r.delay)}, duration = {_value(r.duration)}, "
                  f"level = {_value(r.level)} }}," for r in profile.ramps]
        lines.append("]")
        if unit.activation_dynamics is not None:
            lines += ["[units.activation_dynamics]",
                      "# first-order activation dynamics (Thelen 2003): the profile above is the "
                      "excitation"]
            lines += [_line(k, getattr(unit.activation_dynamics, k)) for k in DYNAMICS_KEYS]
    for point in m.points:
        lines += ["", "[[points]]", f"name = {_value(point.name)}",
                  f"segment = {_value(point.segment)}", _line("distance", point.distance),
                  _line("offset", point.offset)]
    for contact in m.contacts:
        lines += ["", "[[contacts]]", f"point = {_value(contact.point)}"]
        lines += [_line(k, getattr(contact, k)) for k in CONTACT_KEYS[1:]]
    return "\n".join(lines) + "\n"


def save_model(model, path, field: str = "out") -> Path:
    """Write the model TOML atomically (a path that cannot be written is a ModelError under
    ``field``)."""
    return write_text_atomic(path, model_to_toml(model), field)
