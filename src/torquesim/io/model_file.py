"""Read and write a whole model as TOML.

Layout (every key optional; a missing key takes the built-in default, an unknown key is an
error)::

    initial_angle = 0.174533     # rad
    duration = 3.0               # s
    [body]            # BodyParameters fields
    [flexor]          # TorqueGeneratorUnit fields
    [flexor.activation]
    initial_level = "equilibrium"          # or a number in [0, 1]
    ramps = [{ delay = 0.058, duration = 0.311, level = 0.556 }, ...]
    [extensor] / [extensor.activation]     # the same
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

from ..errors import ModelError
from ..model.activation import ActivationProfile, Ramp
from ..model.body import BodyParameters
from ..model.elbow import ElbowModel
from ..model.torque_generator import TorqueGeneratorUnit
from .atomic import write_text_atomic

EQUILIBRIUM = "equilibrium"

#: One-line documentation written beside each key: unit and allowed range.
FIELD_DOCS = {
    "initial_angle": "rad, elbow flexion at t = 0 (0 = arm hanging straight). [-pi, pi]",
    "duration": "s, simulated time. (0, 600]",
    "gravity": "m/s^2. [0, inf)",
    "segment_mass": "kg, forearm + hand (de Leva 1996). (0, inf)",
    "segment_com_distance": "m, elbow to forearm+hand centre of mass. (0, inf)",
    "segment_inertia": "kg m^2, forearm + hand about the elbow. (0, inf)",
    "dumbbell_mass": "kg. [0, inf)",
    "dumbbell_distance": "m, elbow to dumbbell centre. (0, inf)",
    "dumbbell_inertia": "kg m^2, dumbbell about its own handle axis. [0, inf)",
    "endstop_torque": "N m, passive end-stop scale k_p (0 = abstract's Eq. 1). [0, inf)",
    "endstop_angle_scale": "rad, end-stop angular scale s_p. (0, inf)",
    "endstop_lower_angle": "rad, theta_lo. [-pi, 2pi]",
    "endstop_upper_angle": "rad, theta_hi (> theta_lo). [-pi, 2pi]",
    "isometric_torque": "N m, T0. (0, inf)",
    "eccentric_torque_max": "N m, T_max. (T0, inf)",
    "max_velocity": "rad/s, omega_max. (0, inf)",
    "velocity_constant": "rad/s, omega_c of the Hill hyperbola. (0, inf)",
    "min_differential_activation": "a_min of d(omega). [0, 1]",
    "differential_activation_rate": "rad/s, omega_r of d(omega). (0, inf)",
    "differential_activation_midpoint": "rad/s, omega_1 of d(omega). (-omega_max, omega_max)",
    "optimal_angle": "rad, theta_opt of the torque/angle curve. [-pi, 2pi]",
    "angle_curvature": "rad^-2, k2 of the torque/angle curve. [0, inf)",
    "se_stiffness": "N m/rad, series elastic element. (0, inf)",
    "eccentric_slope_ratio": "eccentric/concentric slope of T_omega at 0 (Yeadon 2006: 4.3)",
    "ce_damping": "N m s/rad, CE parallel damping beta (Millard 2013; 0 = abstract). [0, 1e4]",
}


def _number(key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelError(key, f"must be a number, got {value!r}")
    return float(value)


def _table(key: str, value) -> dict:
    if not isinstance(value, dict):
        raise ModelError(key, "must be a table")
    return value


def _check_keys(prefix: str, table: dict, allowed) -> None:
    for key in table:
        if key not in allowed:
            name = f"{prefix}.{key}" if prefix else key
            raise ModelError(name, f"unknown key; allowed: {', '.join(sorted(allowed))}")


def _build(cls, prefix: str, table: dict, defaults: dict):
    _check_keys(prefix, table, defaults)
    values = dict(defaults)
    for key, value in table.items():
        values[key] = _number(f"{prefix}.{key}", value)
    try:
        return cls(**values)
    except ModelError as exc:
        raise exc.under(prefix) from None


def _profile(prefix: str, table: dict, default: ActivationProfile) -> ActivationProfile:
    _check_keys(prefix, table, ("initial_level", "ramps"))
    level = table.get("initial_level", default.initial_level
                      if default.initial_level is not None else EQUILIBRIUM)
    if level == EQUILIBRIUM:
        level = None
    else:
        level = _number(f"{prefix}.initial_level", level)
    ramps = default.ramps
    if "ramps" in table:
        if not isinstance(table["ramps"], list):
            raise ModelError(f"{prefix}.ramps", "must be an array of {delay, duration, level}")
        ramps = []
        for i, item in enumerate(table["ramps"]):
            name = f"{prefix}.ramps[{i}]"
            item = _table(name, item)
            _check_keys(name, item, ("delay", "duration", "level"))
            for key in ("delay", "duration", "level"):
                if key not in item:
                    raise ModelError(f"{name}.{key}", "is missing")
            try:
                ramps.append(Ramp(*(_number(f"{name}.{k}", item[k])
                                    for k in ("delay", "duration", "level"))))
            except ModelError as exc:
                raise exc.under(name) from None
    try:
        return ActivationProfile(level, tuple(ramps))
    except ModelError as exc:
        raise exc.under(prefix) from None


def model_from_dict(data: dict) -> ElbowModel:
    """Build and validate a model from the parsed TOML mapping (missing keys: defaults)."""
    default = ElbowModel()
    _check_keys("", data, ("initial_angle", "duration", "body", "flexor", "extensor"))
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


def load_model(path) -> ElbowModel:
    """Read a model TOML file; errors name the key and the allowed range."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ModelError("model", f"cannot read {str(path)!r}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ModelError("model", f"{str(path)!r} is not UTF-8 text") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError("model", f"{str(path)!r} is not valid TOML: {exc}") from None
    return model_from_dict(data)


def _value(x: float) -> str:
    return repr(float(x))


def _line(key: str, value: float) -> str:
    doc = FIELD_DOCS.get(key)
    return f"{key} = {_value(value)}" + (f"  # {doc}" if doc else "")


def model_to_toml(model: ElbowModel) -> str:
    """The model as commented TOML (exact float round trip)."""
    lines = ["# torquesim model. SI units, angles in radians. Missing keys take the defaults.",
             _line("initial_angle", model.initial_angle)
             + f" (= {math.degrees(model.initial_angle):.4g} deg)",
             _line("duration", model.duration), "", "[body]"]
    lines += [_line(k, v) for k, v in model.body.as_dict().items()]
    for name in ("flexor", "extensor"):
        lines += ["", f"[{name}]"]
        lines += [_line(k, v) for k, v in getattr(model, name).as_dict().items()]
        profile = getattr(model, f"{name}_activation")
        lines += ["", f"[{name}.activation]",
                  "# a(t): initial level, then quintic ramps (delay after the previous ramp "
                  "ends [s], duration [s], new level [0, 1])"]
        level = profile.initial_level
        lines.append("initial_level = " + ('"equilibrium"  # from static equilibrium at '
                                           'initial_angle' if level is None else _value(level)))
        lines.append("ramps = [")
        lines += [f"    {{ delay = {_value(r.delay)}, duration = {_value(r.duration)}, "
                  f"level = {_value(r.level)} }}," for r in profile.ramps]
        lines.append("]")
    return "\n".join(lines) + "\n"


def save_model(model: ElbowModel, path) -> Path:
    """Write the model TOML atomically."""
    return write_text_atomic(path, model_to_toml(model))
