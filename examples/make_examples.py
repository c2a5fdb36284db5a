"""Make the example data of the tutorial (run from the repository root; the files are
committed, so this only documents and reproduces them):

    python examples/make_examples.py

- ``arm-raise-ik.mot``: an OpenSim inverse-kinematics style motion (``inDegrees=yes``, 100 Hz,
  coordinate columns named as in OpenSim's arm models: ``r_shoulder_elev``, ``r_elbow_flex``,
  plus a few other coordinates an IK file carries) of a front raise with a curl, 3 s. Made by
  the arm-raise preset with its dumbbell 10 % lighter, sampled at 100 Hz, with 0.3° of
  Gaussian marker-like noise (seed 7): a motion the preset can fit but does not reproduce
  exactly.
- ``knee-extension.csv``: a seated knee extension in degrees (``time,knee_flexion``), 3 s at
  50 Hz, from the knee preset with its ankle weight 0.5 kg heavier, 0.3° noise (seed 11).
- ``batch.csv``: a batch manifest fitting the built-in curl and the two files above.
- ``dynamometer/``: knee-extensor trials of one invented subject on an isovelocity
  dynamometer, one CSV per trial (`dynamometer_trials`; its README lists them and the
  parameters they were made from).
- ``jump/``: a squat jump as a lab records it (`jump_recording`): a whole-body 3D inverse
  kinematics ``.mot`` at 120 Hz (gait2392 coordinates, both legs) and a two-plate force file
  at 960 Hz that starts 0.3 s earlier, in the quiet squat.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

import torquesim as ts
from torquesim.fitting.dynamometer import simulate_passive_trial, simulate_trial
from torquesim.fitting.strength import PassiveTorque
from torquesim.io.dynamometer import write_trial

HERE = Path(__file__).resolve().parent


def _lighter(model, factor=None, extra=None):
    segments = []
    for seg in model.segments:
        loads = tuple(replace(ld, mass=ld.mass * factor if factor else ld.mass + extra)
                      for ld in seg.loads)
        segments.append(replace(seg, loads=loads))
    return model.replace(segments=tuple(segments))


def main() -> None:
    rng = np.random.default_rng(7)
    arm = _lighter(ts.load_model("builtin:arm-raise"), factor=0.9)
    ref = ts.simulate(arm, "reference", output_step=0.01)
    shoulder = np.degrees(ref.angle("shoulder")) + rng.normal(0, 0.3, ref.time.size)
    elbow = np.degrees(ref.angle("elbow")) + rng.normal(0, 0.3, ref.time.size)
    columns = {"time": ref.time, "pelvis_tilt": np.zeros_like(ref.time),
               "r_shoulder_elev": shoulder, "r_shoulder_rot": np.zeros_like(ref.time),
               "r_elbow_flex": elbow, "pro_sup": np.full_like(ref.time, 10.0)}
    lines = ["Coordinates", "version=1", f"nRows={ref.time.size}",
             f"nColumns={len(columns)}", "inDegrees=yes", "",
             "Units are S.I. units (second, meters, Newtons, ...)",
             "If the header above contains a line with 'inDegrees', this indicates whether "
             "rotational values are in degrees (yes) or radians (no).", "", "endheader",
             "\t".join(columns)]
    data = np.column_stack(list(columns.values()))
    lines += ["\t".join(f"{v:.6f}" for v in row) for row in data]
    (HERE / "arm-raise-ik.mot").write_text("\n".join(lines) + "\n")

    rng = np.random.default_rng(11)
    knee = _lighter(ts.load_model("builtin:knee-extension"), extra=0.5)
    ref = ts.simulate(knee, "reference", output_step=0.02)
    angle = np.degrees(ref.angle("knee")) + rng.normal(0, 0.3, ref.time.size)
    text = ["# seated knee extension, degrees (flexion positive: 90 = shank hanging down)",
            "time,knee_flexion"]
    text += [f"{t:.2f},{a:.4f}" for t, a in zip(ref.time, angle, strict=True)]
    (HERE / "knee-extension.csv").write_text("\n".join(text) + "\n")

    (HERE / "batch.csv").write_text(
        "target,model,column\n"
        "builtin:curl,builtin:elbow-curl,\n"
        "knee-extension.csv,builtin:knee-extension,knee_flexion\n")
    dynamometer_trials()
    jump_recording()


#: The knee extensor the dynamometer examples were made from (the preset's, changed: a
#: stronger subject with a later optimum).
SUBJECT = {"isometric_torque": 240.0, "eccentric_torque_max": 336.0, "max_velocity": 20.0,
           "velocity_constant": 6.5, "min_differential_activation": 0.88,
           "differential_activation_rate": 0.6, "differential_activation_midpoint": 0.2,
           "optimal_angle": 1.2, "angle_curvature": 0.35}
#: Gravity torque of shank, foot and crank in the model's convention (knee flexion positive):
#: its largest moment (N·m) and the knee angle (deg) where it is reached (the shank horizontal,
#: knee straight, the weight pulling it towards flexion).
GRAVITY = (14.0, 0.0)
NOISE = 2.0  # N·m, standard deviation, white
RATE = 100.0  # Hz


def dynamometer_trials() -> None:
    """Isometric trials at 30, 50, 70 and 90° of knee flexion; concentric knee extension from
    100° to 15° at 60, 120, 180 and 240 °/s; eccentric (the crank flexing the knee against the
    extensors) from 15° to 100° at 30, 60 and 120 °/s; a passive trial from 10° to 110° at
    30 °/s. Made by the model (`torquesim.fitting.dynamometer.simulate_trial`: the unit at full
    activation, its SE and CE integrated on the crank's motion), with the gravity torque and
    white noise added, each trial with its own seed."""
    folder = HERE / "dynamometer"
    folder.mkdir(exist_ok=True)
    unit = ts.load_model("builtin:knee-extension").units[0]
    subject = replace(unit.parameters, **SUBJECT)
    gravity = PassiveTorque.given(GRAVITY[0], math.radians(GRAVITY[1]))
    rad = math.radians
    plan = ([(f"isometric_{a}.csv", a, a, 0) for a in (30, 50, 70, 90)]
            + [(f"concentric_{s}.csv", 100, 15, s) for s in (60, 120, 180, 240)]
            + [(f"eccentric_{s}.csv", 15, 100, s) for s in (30, 60, 120)])
    for seed, (name, start, end, speed) in enumerate(plan, start=1):
        trial = simulate_trial(name, subject, unit.direction, rad(start), rad(end), rad(speed),
                               rate=RATE, noise=NOISE, passive=gravity, seed=seed)
        write_trial(trial, folder / name)
    write_trial(simulate_passive_trial("passive.csv", rad(10), rad(110), gravity, rate=RATE,
                                       noise=0.5, seed=99), folder / "passive.csv")
    rows = "\n".join(f"| `{k}` | {v:g} |" for k, v in SUBJECT.items())
    (folder / "README.md").write_text(f"""# Dynamometer example: one subject's knee extensors

Made by `python examples/make_examples.py` (function `dynamometer_trials`): a knee-extensor
unit of `builtin:knee-extension` (SE stiffness {unit.parameters.se_stiffness:g} N·m/rad) with
the parameters below, at full activation on an isovelocity crank, sampled at {RATE:g} Hz, with
the gravity torque {GRAVITY[0]:g}·cos(θ − {GRAVITY[1]:g}°) N·m and white noise of
{NOISE:g} N·m (0.5 N·m on the passive trial) added.

Columns: `time` (s), `angle` (knee flexion, degrees; 0 = straight), `velocity` (°/s),
`torque` (N·m, positive towards flexion: the extensors' torque is negative).

Trials: isometric at 30, 50, 70, 90°; concentric extension 100° → 15° at 60, 120, 180,
240 °/s; eccentric 15° → 100° at 30, 60, 120 °/s; `passive.csv`, relaxed, 10° → 110°.

| parameter | value (SI) |
|---|---|
{rows}

Fit them with

    torquesim strength examples/dynamometer/*_*.csv \\
        --passive examples/dynamometer/passive.csv --unit knee_extensor
""")



#: The jumper of examples/jump: 72 kg, 1.78 m, female (de Leva), with the knee extensors the
#: dynamometer measured (`SUBJECT`, both legs: T0 and T_max doubled, as `strength --limbs 2`
#: writes them) and the hip and ankle switched on 20 ms later than the preset's.
JUMPER = (72.0, 1.78, "female")


def jump_recording() -> None:
    """A squat jump recorded as a lab would: ``jump/ik.mot`` (OpenSim inverse kinematics of a
    gait2392 model: pelvis, lumbar and both legs in degrees, 120 Hz, 0.3° of noise) and
    ``jump/grf.mot`` (two plates, one foot each, OpenSim external-loads names, 960 Hz, 4 N of
    noise, from 0.3 s before the first frame in the still squat). Made by the reference solver
    on the squat jump made for `JUMPER`, changed as its comment says; the IK coordinates from
    the planar angles by the gait2392 relations of docs/opensim.md."""
    from torquesim.model.activation import ActivationProfile, Ramp
    from torquesim.model.anthropometry import Subject, for_subject

    folder = HERE / "jump"
    folder.mkdir(exist_ok=True)
    model = for_subject(ts.load_model("builtin:squat-jump"), Subject(*JUMPER))
    units = []
    for unit in model.units:
        if unit.name == "knee_extensors":
            measured = {**SUBJECT, "isometric_torque": 2 * SUBJECT["isometric_torque"],
                        "eccentric_torque_max": 2 * SUBJECT["eccentric_torque_max"]}
            unit = replace(unit, parameters=replace(unit.parameters, **measured))
        if unit.name in ("hip_extensors", "plantarflexors"):
            first, second = unit.activation.ramps
            unit = replace(unit, activation=ActivationProfile(
                unit.activation.initial_level,
                (Ramp(first.delay + 0.02, first.duration, first.level), second)))
        units.append(unit)
    model = model.replace(units=tuple(units))
    run = ts.simulate(model, "reference", output_step=1 / 960)
    cols = run.columns()
    deg = {j.name: np.degrees(run.angle(j.name)) for j in model.joints}
    foot = math.degrees(model.joints[0].initial_angle)
    trunk = deg["foot_ground"] + deg["ankle"] + deg["knee"] + deg["hip"]
    lumbar = 0.3 * (trunk - 180.0)
    coordinates = {
        "pelvis_tilt": trunk - 180.0 - lumbar, "pelvis_list": 0.8, "pelvis_rotation": -1.5,
        "pelvis_tx": cols["hip_joint_x"], "pelvis_ty": cols["hip_joint_y"], "pelvis_tz": 0.0,
        "hip_flexion_r": lumbar - deg["hip"], "hip_adduction_r": -2.0, "hip_rotation_r": 3.0,
        "knee_angle_r": -deg["knee"], "ankle_angle_r": (180.0 - foot) - deg["ankle"],
        "subtalar_angle_r": 0.0, "mtp_angle_r": 0.0,
        "hip_flexion_l": lumbar - deg["hip"], "hip_adduction_l": -2.0, "hip_rotation_l": 3.0,
        "knee_angle_l": -deg["knee"], "ankle_angle_l": (180.0 - foot) - deg["ankle"],
        "subtalar_angle_l": 0.0, "mtp_angle_l": 0.0,
        "lumbar_extension": lumbar, "lumbar_bending": 0.5, "lumbar_rotation": 0.0,
    }
    rng = np.random.default_rng(31)
    every = slice(None, None, 8)  # 960 Hz → 120 Hz
    time = run.time[every]
    ik = {"time": time}
    for name, value in coordinates.items():
        value = np.broadcast_to(np.asarray(value, dtype=float), run.time.shape)[every]
        noise = 0.3 if not name.startswith("pelvis_t") else 0.002
        ik[name] = value + rng.normal(0.0, noise, time.size)
    _write_storage(folder / "ik.mot", "Coordinates", ik, in_degrees=True)

    before = np.arange(-0.3, 0.0, 1 / 960)
    time = np.concatenate([before, run.time])
    forces = {"time": time}
    share = 0.5 + 0.03 * np.sin(2 * np.pi * 3 * time)
    for prefix, part, z in (("", share, 0.1), ("1_", 1 - share, -0.1)):
        for axis in ("x", "y", "z"):
            total = cols[f"grf_{axis}"] if axis != "z" else np.zeros_like(run.time)
            total = np.concatenate([np.full(before.size, total[0]), total])
            forces[f"{prefix}ground_force_v{axis}"] = total * part + rng.normal(0, 4.0,
                                                                                time.size)
        cop = np.concatenate([np.full(before.size, cols["cop_x"][0]), cols["cop_x"]])
        forces[f"{prefix}ground_force_px"] = np.nan_to_num(cop, nan=0.0)
        forces[f"{prefix}ground_force_py"] = np.zeros_like(time)
        forces[f"{prefix}ground_force_pz"] = np.full_like(time, z)
    _write_storage(folder / "grf.mot", "ExternalLoads", forces, in_degrees=False)


def _write_storage(path, title: str, columns: dict, in_degrees: bool) -> None:
    data = np.column_stack(list(columns.values()))
    lines = [title, "version=1", f"nRows={data.shape[0]}", f"nColumns={data.shape[1]}",
             f"inDegrees={'yes' if in_degrees else 'no'}", "endheader", "\t".join(columns)]
    lines += ["\t".join(f"{v:.6f}" for v in row) for row in data]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
