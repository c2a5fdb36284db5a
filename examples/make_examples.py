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
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

import torquesim as ts

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


if __name__ == "__main__":
    main()
