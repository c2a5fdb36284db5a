"""How the countermovement-jump preset's activation profiles were made (docs/presets.md).

    python scripts/tune_countermovement_jump.py [--out FOLDER] [--generations 120] [--seed 11]

Three steps, with torquesim's own tools, on the squat jump's body, units and contacts:

1. **A descent** (``FOLDER/descent.csv``, 1 kHz): quiet standing (knee 5°, hip 8° flexed, the
   centre of mass 4 cm ahead of the ankle) held 0.1 s, then each segment's absolute angle by
   minimum jerk over 0.65 s to the squat jump's squat, the trunk turned at each instant so that
   the centre of mass moves by minimum jerk from 4 cm ahead of the ankle to above it; the foot
   stays flat.
2. **The extensors' ramps for it**: ``torquesim fit`` of the standing model to that descent
   (IMEX 0.25 ms, 600 evaluations), the antagonists held at 0.1 (``--freeze`` of their levels),
   so that the body lowers itself with its extensors alone (0.64° RMS).
3. **The push**: each extensor's fitted descent ramps up to a time t_push, then the squat
   jump's push (to full activation in a shared rise, held, off in 50 ms) and the antagonists'
   braces for the flight. CMA-ES (the ``cmaes`` package) over t_push and 16 onsets, holds and
   levels, every value rounded to 1 ms and 0.001 as the preset holds them, minimises

       −h + 10·max(|v_x| − 0.1, 0) + 10·max(s − 0.045, 0) + 100·max(0.1325 − τ_c, 0)
       + 10·max(0.2 − d, 0) (+1 if it lands within the run)

   with h the flight v²/2g (m), v_x the forward speed at take-off (m/s), s the largest
   end-stop torque as a share of its joint's peak muscle torque and τ_c the contacts' smallest
   time constant (ms; 0.25 ms then stays within 0.7 of RK4's limit), d the centre of mass's
   drop before take-off (m).
4. **Three ramps a unit**, as ``fit`` and ``optimise`` take a model: ``torquesim fit`` of
   the model to step 3's motion (its reference run: angles, ground force and centre of mass
   at 200 Hz), each extensor's ramps held to down, up to full, off in 50 ms to 0.05, each
   antagonist's to a 50 ms brace and a 50 ms return to 0.1.
5. **The preset**: CMA-ES over those 26 onsets, durations, holds and levels (rounded to 1 ms
   and 0.001), step 3's score, from step 4's values.

Prints the best candidate's motion and its profiles as the preset writes them. About 25
minutes on 2 cores (the fits 4 and 8, the searches 6 and 7). The preset's values came from
these steps run one at a time (searches of 100-150 generations, several seeds, the drop term
added in step 5 where it first mattered); the script chains them.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from tune_squat_jump import measure  # scripts/ is on sys.path when this runs

import torquesim as ts
from torquesim.model.activation import ActivationProfile, Ramp

STILL, DESCENT = 0.1, 0.65  # s
#: Standing: the shank 0.06 rad and the thigh 0.027 rad forwards of upright, the centre of
#: mass this far ahead of the ankle (m).
STAND_SHANK, STAND_THIGH, STAND_COM = 0.06, 0.027, 0.04
EXTENSORS = {"plantarflexors": "ankle", "knee_extensors": "knee", "hip_extensors": "hip"}
ANTAGONISTS = {"dorsiflexors": "ankle", "knee_flexors": "knee", "hip_flexors": "hip"}
NAMES = ("push", "ankle_on", "knee_on", "hip_on", "rise", "knee_hold", "hip_hold",
         "ankle_hold", "knee_brace_on", "knee_brace", "knee_brace_hold", "hip_brace_on",
         "hip_brace", "hip_brace_hold", "ankle_brace_on", "ankle_brace")
START = (0.55, 0.12, 0.065, 0.01, 0.04, 0.1, 0.175, 0.075, 0.2, 0.47, 0.075, 0.21, 0.42,
         0.11, 0.24, 0.33)
LOW = (0.4, 0.0, 0.0, 0.0, 0.03, 0.0, 0.0, 0.0, 0.1, 0.1, 0.03, 0.1, 0.1, 0.03, 0.1, 0.1)
HIGH = (0.75, 0.25, 0.2, 0.2, 0.25, 0.3, 0.3, 0.3, 0.45, 1.0, 0.3, 0.45, 1.0, 0.3, 0.45, 1.0)


def standing(jump: ts.ChainModel, coordinates) -> ts.ChainModel:
    """The squat jump posed at joint ``coordinates`` (rad), in degrees to 0.01 as the preset
    writes them."""
    joints = tuple(replace(j, initial_angle=math.radians(round(math.degrees(float(q)), 2)))
                   for j, q in zip(jump.joints, coordinates, strict=True))
    return jump.replace(joints=joints)


def descent(jump: ts.ChainModel) -> np.ndarray:
    """Step 1: (time, foot, ankle, knee, hip) rows, s and rad, at 1 kHz."""
    from scipy.optimize import brentq

    squat = np.cumsum([j.initial_angle for j in jump.joints])  # absolute angles

    def com_ahead(phi) -> float:
        where = jump.kinematics(np.concatenate([[0.0, 0.0], np.diff(phi, prepend=0.0)]))
        return float(where["com"][0] - where["joints"][1][0])

    def trunk_for(phi, ahead) -> float:
        def gap(trunk):
            return com_ahead(np.array([*phi[:3], trunk])) - ahead
        return brentq(gap, phi[3] - 1.2, phi[3] + 0.6, xtol=1e-13)

    goal = com_ahead(squat)
    stand = np.array([squat[0], math.pi - STAND_SHANK, math.pi + STAND_THIGH, math.pi])
    stand[3] = trunk_for(stand, STAND_COM)
    rows = [stand] * int(round(STILL / 1e-3))
    for t in np.arange(0.0, DESCENT + 5e-4, 1e-3):
        s = t / DESCENT
        blend = s**3 * (10 - 15 * s + 6 * s * s)
        phi = stand + (squat - stand) * blend
        phi[3] = trunk_for(phi, STAND_COM + (goal - STAND_COM) * blend)
        rows.append(phi)
    angles = np.diff(np.array(rows), axis=1, prepend=0.0)
    return np.column_stack([np.arange(len(rows)) * 1e-3, angles])


def fit_descent(jump: ts.ChainModel, folder: Path) -> ts.ChainModel:
    """Step 2: the standing model with its extensors' ramps fitted to the descent."""
    from torquesim.cli import main as torquesim

    rows = descent(jump)
    np.savetxt(folder / "descent.csv", np.column_stack([rows[:, 0], np.degrees(rows[:, 1:])]),
               delimiter=",", header="time,foot_angle,ankle_angle,knee_angle,hip_angle",
               comments="", fmt="%.6f")
    model = standing(jump, rows[0, 1:])
    levels = dict(zip([u.name for u in model.units], model.initial_state().levels,
                      strict=True))
    held = tuple(replace(u, activation=ActivationProfile(u.activation.initial_level, tuple(
        Ramp(0.1, 0.1, float(levels[u.name])) for _ in range(3)))) for u in model.units)
    ts.save_model(model.replace(units=held, duration=round(rows[-1, 0], 3)),
                  folder / "standing.toml")
    frozen = [f"--freeze={u}.ramp{k}.level=0.1" for u in ANTAGONISTS for k in (1, 2, 3)]
    torquesim(["fit", "--model", str(folder / "standing.toml"), "--target",
               str(folder / "descent.csv"), "--step", "0.25ms", "--iterations", "600",
               "--quiet", "--overwrite", "--out", str(folder / "descent-fit"), *frozen])
    fitted = ts.load_model(str(folder / "descent-fit" / "fitted_model.toml"))
    return fitted.replace(units=tuple(replace(u, activation=ActivationProfile(
        u.activation.initial_level, tuple(Ramp(round(r.delay, 3), round(r.duration, 3),
                                               round(r.level, 3)) for r in u.activation.ramps)))
        for u in fitted.units))


def descent_ramps(unit, level: float, until: float) -> tuple[list[Ramp], float]:
    """The unit's descent ramps up to ``until`` s (a ramp running past it ends there at the
    level it has then), and when the last one ends."""
    profile = unit.activation
    out, end = [], 0.0
    for ramp, (start, stop) in zip(profile.ramps, profile.ramp_times(), strict=True):
        if start >= until:
            break
        if stop > until:
            now = round(float(profile(np.array([until]), level)[0]), 3)
            out.append(Ramp(round(start - end, 3), round(until - start, 3), now))
            return out, until
        out.append(ramp)
        end = stop
    return out, end


def candidate(lowered: ts.ChainModel, x, duration: float = 1.35) -> ts.ChainModel:
    """Step 3's model for the parameter vector ``x`` (`NAMES`)."""
    p = dict(zip(NAMES, np.round(np.clip(x, LOW, HIGH), 3), strict=True))
    levels = dict(zip([u.name for u in lowered.units], lowered.initial_state().levels,
                      strict=True))
    units = []
    for u in lowered.units:
        if u.name in EXTENSORS:
            j = EXTENSORS[u.name]
            ramps, end = descent_ramps(u, float(levels[u.name]), float(p["push"]))
            ramps += [Ramp(round(p["push"] - end + p[f"{j}_on"], 3), p["rise"], 1.0),
                      Ramp(p[f"{j}_hold"], 0.05, 0.05)]
            profile = ActivationProfile(None, tuple(ramps))
        else:
            j = ANTAGONISTS[u.name]
            ramps = [Ramp(round(p["push"] + p[f"{j}_brace_on"], 3), 0.05, p[f"{j}_brace"])]
            if j != "ankle":
                ramps.append(Ramp(p[f"{j}_brace_hold"], 0.05, 0.1))
            profile = ActivationProfile(0.1, tuple(ramps))
        units.append(replace(u, activation=profile))
    return lowered.replace(units=tuple(units), duration=duration)


def score(model) -> float:
    """Steps 3 and 5's score of a candidate model (lower is better)."""
    try:
        m = measure(model)
    except ts.ModelError:
        return 1e3
    if m is None or not np.isfinite(m["flight_m"]):
        return 1e3
    return (-m["flight_m"] + 10 * max(abs(m["vx_m_s"]) - 0.1, 0)
            + 10 * max(m["end_stop_share"] - 0.045, 0)
            + 100 * max(0.1325 - m["contact_tau_ms"], 0) + 10 * max(0.2 - m["drop_m"], 0)
            + (m["landing"] is not None))


#: Step 5's parameters: per extensor its fall (onset, duration, level), its rise to full
#: (onset, duration) and the hold before it switches off; per antagonist its brace.
THREE = tuple(f"{j}_{f}" for j in ("ankle", "knee", "hip")
              for f in ("down_on", "down", "low", "rise_on", "rise", "hold")) + (
    "knee_brace_on", "knee_brace", "knee_brace_hold", "hip_brace_on", "hip_brace",
    "hip_brace_hold", "ankle_brace_on", "ankle_brace")
THREE_LOW = (0.0, 0.02, 0.0, 0.2, 0.03, 0.0) * 3 + (0.5, 0.1, 0.03, 0.5, 0.1, 0.03, 0.5, 0.1)
THREE_HIGH = (0.7, 0.5, 0.6, 0.95, 0.5, 0.3) * 3 + (1.0, 1.0, 0.3, 1.0, 1.0, 0.3, 1.0, 1.0)


def three_ramps(base: ts.ChainModel, x, duration: float = 1.35) -> ts.ChainModel:
    """Step 5's model for the parameter vector ``x`` (`THREE`): every unit three ramps at
    most."""
    p = dict(zip(THREE, np.round(np.clip(x, THREE_LOW, THREE_HIGH), 3), strict=True))
    profiles = {}
    for unit, j in EXTENSORS.items():
        end = p[f"{j}_down_on"] + p[f"{j}_down"]
        profiles[unit] = ActivationProfile(None, (
            Ramp(p[f"{j}_down_on"], p[f"{j}_down"], p[f"{j}_low"]),
            Ramp(round(max(p[f"{j}_rise_on"] - end, 0.0), 3), p[f"{j}_rise"], 1.0),
            Ramp(p[f"{j}_hold"], 0.05, 0.05)))
    for unit, j in ANTAGONISTS.items():
        ramps = (Ramp(p[f"{j}_brace_on"], 0.05, p[f"{j}_brace"]),)
        if j != "ankle":
            ramps += (Ramp(p[f"{j}_brace_hold"], 0.05, 0.1),)
        profiles[unit] = ActivationProfile(0.1, ramps)
    return base.replace(units=tuple(replace(u, activation=profiles[u.name])
                                    for u in base.units), duration=duration)


def fit_three_ramps(model: ts.ChainModel, folder: Path) -> list[float]:
    """Step 4: `THREE`'s values of the three-ramp fit to ``model``'s motion."""
    from torquesim.cli import main as torquesim

    run = ts.simulate(model.replace(duration=1.04), "reference", output_step=0.005)
    c = run.columns()
    names = [j.coordinate for j in model.joints]
    table = np.column_stack([run.time, *(np.degrees(c[n]) for n in names),
                             *(c[n] for n in ("grf_x", "grf_y", "com_x", "com_y"))])
    np.savetxt(folder / "two-step.csv", table, delimiter=",", comments="", fmt="%.8g",
               header=",".join(["time", *names, "grf_x", "grf_y", "com_x", "com_y"]))
    start = [0.566, 0.052, 0.082, 0.632, 0.098, 0.06, 0.117, 0.174, 0.042, 0.533, 0.162, 0.085,
             0.045, 0.141, 0.032, 0.405, 0.281, 0.15, 0.748, 0.477, 0.105, 0.779, 0.266, 0.2,
             0.754, 0.409]
    padded = three_ramps(model, start, duration=1.04)
    padded = padded.replace(units=tuple(replace(u, activation=ActivationProfile(
        u.activation.initial_level, u.activation.ramps + (Ramp(0.0, 0.05, 0.1),) * (
            3 - len(u.activation.ramps)))) for u in padded.units))
    ts.save_model(padded, folder / "three-start.toml")
    held = [f"--freeze={u}.ramp2.level=1" for u in EXTENSORS]
    held += [f"--freeze={u}.ramp3.{f}" for u in EXTENSORS for f in ("level=0.05",
                                                                    "duration=0.05")]
    held += [f"--freeze={u}.ramp{k}.{f}" for u in ANTAGONISTS for k, f in (
        (1, "duration=0.05"), (2, "level=0.1"), (2, "duration=0.05"), (3, "level=0.1"))]
    torquesim(["fit", "--model", str(folder / "three-start.toml"), "--target",
               str(folder / "two-step.csv"), "--step", "0.25ms", "--iterations", "600",
               "--quiet", "--overwrite", "--out", str(folder / "three-fit"), *held])
    fitted = ts.load_model(str(folder / "three-fit" / "fitted_model.toml"))
    values = {}
    for u in fitted.units:
        r, (start_time, _) = u.activation.ramps, u.activation.ramp_times()[0]
        if u.name in EXTENSORS:
            j = EXTENSORS[u.name]
            rise_on = u.activation.ramp_times()[1][0]
            values.update({f"{j}_down_on": start_time, f"{j}_down": r[0].duration,
                           f"{j}_low": r[0].level, f"{j}_rise_on": rise_on,
                           f"{j}_rise": r[1].duration, f"{j}_hold": r[2].delay})
        else:
            j = ANTAGONISTS[u.name]
            values.update({f"{j}_brace_on": start_time, f"{j}_brace": r[0].level})
            if j != "ankle":
                values[f"{j}_brace_hold"] = min(r[1].delay, 0.3)
    return [values[name] for name in THREE]


def search(make, start, low, high, generations: int, seed: int, sigma: float):
    """CMA-ES over ``make(x)``'s `score` from ``start``: the best x."""
    import cmaes

    cma = cmaes.CMA(mean=np.array(start), sigma=sigma, bounds=np.array([low, high]).T,
                    seed=seed, population_size=12)
    best = (np.array(start), score(make(start)))
    print(f"start: score {best[1]:.4g}, {measure(make(start))}")
    for generation in range(generations):
        told = []
        for _ in range(cma.population_size):
            x = cma.ask()
            told.append((x, score(make(x))))
            best = min(best, told[-1], key=lambda b: b[1])
        cma.tell(told)
        if generation % 20 == 0:
            print(f"generation {generation}: best score {best[1]:.4g}")
    return best[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("cmj-tuning"))
    parser.add_argument("--generations", type=int, default=120)
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    lowered = fit_descent(ts.load_model("builtin:squat-jump"), args.out)
    pushed = search(lambda x: candidate(lowered, x), START, LOW, HIGH, args.generations,
                    args.seed, 0.02)
    two_step = candidate(lowered, pushed)
    print("steps 1-3:", measure(two_step))
    start = fit_three_ramps(two_step, args.out)
    best = search(lambda x: three_ramps(lowered, x), start, THREE_LOW, THREE_HIGH,
                  args.generations, args.seed, 0.01)
    model = three_ramps(lowered, best)
    print(measure(model))
    print("standing (deg):", [round(math.degrees(j.initial_angle), 2) for j in model.joints])
    for u in model.units:
        print(u.name, u.activation.initial_level,
              [(float(r.delay), float(r.duration), float(r.level)) for r in u.activation.ramps])


if __name__ == "__main__":
    main()
