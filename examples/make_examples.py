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


if __name__ == "__main__":
    main()
