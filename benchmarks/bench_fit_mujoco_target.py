"""The arm-raise fit on a motion MuJoCo's muscles made: how close the least-squares fit gets,
in this tree and (optionally) in another version of torquesim, on the same target.

Run:  pip install mujoco    # not a dependency of torquesim; 3.14 was used
      python benchmarks/bench_fit_mujoco_target.py [--baseline OTHER/src] [--keep DIR]

The target is made by MuJoCo (RK4, 0.5 ms) on the arm raise's two segments and dumbbell (their
masses, centres of mass and inertias read from ``builtin:arm-raise``), moved by four MuJoCo
``muscle`` actuators on the shoulder and the elbow: MuJoCo's own force-length-velocity curves,
passive force and first-order activation (15/50 ms), a constant 3 cm moment arm, none of it
torquesim's torque generator. Two motions:

- ``open-loop``: the preset's activation histories (simulated by torquesim) fed to MuJoCo as
  excitations, the flexors' maximum forces set so the raise reaches about 63° and 70°; the
  muscles are not in equilibrium at t = 0, so the arm starts still and accelerates at once;
- ``tracked``: excitations from a PD law with gravity compensation tracking minimum-jerk
  raises (shoulder 5° → 70°, elbow 10° → 70°, hold, lowering), as a subject's control would.

Each target (100 Hz, degrees) is fitted by ``torquesim fit --model builtin:arm-raise`` in its own
process, this tree and then the ``--baseline`` tree (its ``src`` first on PYTHONPATH, its own
Numba cache). Printed per fit: each joint's RMS with the reference re-simulation, the
simulations, how the refining least squares ended, the wall time. Wall times move with load
(stated); the RMS and the simulation counts do not.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import torquesim as ts
from torquesim.io.provenance import load_average

#: Moment arm of every MuJoCo muscle, m, and the maximum isometric forces, N (flexors of the
#: open-loop motion scaled by `OPEN_LOOP_FLEXOR_SCALE`).
MOMENT_ARM = 0.03
FORCES = {"shoulder_flexor": 2200.0, "shoulder_extensor": 2400.0, "elbow_flexor": 2600.0,
          "elbow_extensor": 2000.0}
OPEN_LOOP_FLEXOR_SCALE = {"shoulder_flexor": 0.7, "elbow_flexor": 0.6}
TIMESTEP = 0.0005
SAMPLE = 0.01


def mjcf(model, forces: dict[str, float]) -> str:
    """The arm raise as MuJoCo XML: hinges about y, segments hanging along −z at zero angle,
    each segment's inertia about its centre of mass from torquesim's inertia about its joint."""
    upper, forearm = model.segments
    dumbbell = forearm.loads[0]
    joints = {j.name: j for j in model.joints}

    def inertia(seg):
        return seg.inertia_about_joint - seg.mass * seg.com_distance**2

    def hinge(name):
        j = joints[name]
        return (f'<joint name="{name}" type="hinge" axis="0 1 0" limited="true" '
                f'range="{j.endstop_lower_angle} {j.endstop_upper_angle}"/>')

    muscles = "\n".join(
        f'<muscle name="{u.name}" joint="{u.joint}" gear="{-u.direction * MOMENT_ARM}" '
        f'force="{forces[u.name]}" timeconst="0.015 0.05"/>' for u in model.units)
    return f"""<mujoco>
 <compiler angle="radian"/>
 <option timestep="{TIMESTEP}" integrator="RK4" gravity="0 0 -9.81"/>
 <worldbody>
  <body name="{upper.name}">
   {hinge("shoulder")}
   <inertial pos="0 0 {-upper.com_distance}" mass="{upper.mass}"
             diaginertia="{inertia(upper)} {inertia(upper)} 0.001"/>
   <body name="{forearm.name}" pos="0 0 {-upper.length}">
    {hinge("elbow")}
    <inertial pos="0 0 {-forearm.com_distance}" mass="{forearm.mass}"
              diaginertia="{inertia(forearm)} {inertia(forearm)} 0.001"/>
    <body name="{dumbbell.name}" pos="0 0 {-dumbbell.distance}">
     <inertial pos="0 0 0" mass="{dumbbell.mass}"
               diaginertia="{dumbbell.inertia} {dumbbell.inertia} {dumbbell.inertia}"/>
    </body>
   </body>
  </body>
 </worldbody>
 <actuator>
  {muscles}
 </actuator>
</mujoco>"""


def min_jerk(t, t0, t1, a, b):
    s = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return a + (b - a) * (10 * s**3 - 15 * s**4 + 6 * s**5)


def desired(t):
    """The tracked motion's joint angles, rad: raise, hold, lower."""
    shoulder = min_jerk(t, 0.1, 1.3, 5, 70) + min_jerk(t, 1.7, 2.9, 0, -65)
    elbow = min_jerk(t, 0.1, 1.3, 10, 70) + min_jerk(t, 1.7, 2.9, 0, -60)
    return np.radians([shoulder, elbow])


def make_target(kind: str, path: Path) -> None:
    """Simulate the ``kind`` motion with MuJoCo and write it as CSV (time s, angles deg)."""
    import mujoco

    model = ts.load_model("builtin:arm-raise")
    forces = dict(FORCES)
    if kind == "open-loop":
        forces.update({k: v * FORCES[k] for k, v in OPEN_LOOP_FLEXOR_SCALE.items()})
        run = ts.simulate(model, "imex", step=TIMESTEP)
        columns = run.columns()
        excitation = np.array([columns[f"activation_{u.name}"] for u in model.units])
    mj = mujoco.MjModel.from_xml_string(mjcf(model, forces))
    data = mujoco.MjData(mj)
    data.qpos[:] = [j.initial_angle for j in model.joints]
    if kind == "open-loop":
        data.act[:] = excitation[:, 0]
    steps = int(round(model.duration / TIMESTEP))
    every = int(round(SAMPLE / TIMESTEP))
    times, angles = [], []
    gains, damping = np.array([300.0, 200.0]), np.array([30.0, 20.0])
    for i in range(steps + 1):
        if i % every == 0:
            times.append(data.time)
            angles.append(np.degrees(data.qpos.copy()))
        if i == steps:
            break
        if kind == "open-loop":
            data.ctrl[:] = excitation[:, i]
        else:
            mujoco.mj_forward(mj, data)
            t = data.time
            speed = (desired(t + 1e-3) - desired(t - 1e-3)) / 2e-3
            torque = (data.qfrc_bias + gains * (desired(t) - data.qpos)
                      + damping * (speed - data.qvel))
            ctrl = np.full(4, 0.05)
            for k, unit in enumerate(model.units):
                j = 0 if unit.joint == "shoulder" else 1
                if unit.direction * torque[j] > 0:
                    ctrl[k] += abs(torque[j]) / 60.0
            data.ctrl[:] = np.clip(ctrl, 0.0, 1.0)
        mujoco.mj_step(mj, data)
    header = "time," + ",".join(j.coordinate for j in model.joints)
    np.savetxt(path, np.column_stack([times, angles]), delimiter=",", header=header,
               comments="", fmt="%.6f")


def fit(target: Path, out: Path, src: str | None) -> dict:
    """``torquesim fit`` of ``target`` in a process of its own (``src``: another tree)."""
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = src
        env["NUMBA_CACHE_DIR"] = str(Path(tempfile.gettempdir()) / "torquesim-baseline-numba")
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "torquesim.cli", "fit", "--model",
                           "builtin:arm-raise", "--target", str(target), "--out", str(out)],
                          env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    summary = json.loads((out / "fit_summary.json").read_text())
    ends = [line.split("refined: ")[1] for line in (done.stdout + done.stderr).splitlines()
            if "refined:" in line]
    return {"summary": summary, "wall": wall, "ends": ends}


def reference_rms(summary: dict) -> str:
    joints = summary["joints"]
    return ", ".join(f"{j} {v['reference_rms_error_deg']:.3f}°" for j, v in joints.items())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="src folder of another version, fitted second")
    parser.add_argument("--keep", help="write the targets and the fits here")
    parser.add_argument("--motions", default="open-loop,tracked")
    args = parser.parse_args()
    print(f"load average at start: {load_average():.2f} (2 cores)")
    folder = Path(args.keep or tempfile.mkdtemp(prefix="mujoco-arm-"))
    folder.mkdir(parents=True, exist_ok=True)
    for kind in args.motions.split(","):
        target = folder / f"arm_{kind}.csv"
        make_target(kind, target)
        print(f"{kind}: target {target}")
        for name, src in (("this", None), ("baseline", args.baseline)):
            if name == "baseline" and not src:
                continue
            got = fit(target, folder / f"{kind}_{name}", src)
            s = got["summary"]
            print(f"  {name:8s} RMS (reference) {reference_rms(s)}; "
                  f"{s['simulations']} simulations, {got['wall']:.1f} s")
            for line in got["ends"]:
                print(f"           refined: {line}")
    print(f"load average at end: {load_average():.2f}")


if __name__ == "__main__":
    main()
