"""The squat-jump fit on jumps the preset did not make: how far the fit gets from its
inverse-dynamics start when the target is not the preset's own motion.

Run:  python benchmarks/bench_jump_fit_unseen.py [--angles-only] [--starts N] [--write-docs]

Two targets, each made by `builtin:squat-jump` with other extensor timings and levels
(simulated by the reference solver, 200 Hz): "late-ankle" (plantarflexors at 150 ms and 0.9,
knee extensors at 45 ms and 0.95, hip extensors at 50 ms and 0.85) and "early-hip"
(110 ms / 1.0, 60 ms / 0.9, 10 ms / 1.0); the preset's 125, 45 and 30 ms at full level.
The fitted model has the same structure, so an exact
fit exists. Prints, per target, the fit's RMS per joint and of the vertical ground reaction
force (% of body weight) with the reference, simulations and wall time. With
``--angles-only`` the target holds only the four angles (the force is then reported, not
fitted). With ``--write-docs`` the results go into the ``jump-unseen`` block of
docs/fitting.md (with the date and load).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import torquesim as ts
from torquesim.fitting import FitProblem, SearchSettings, Target
from torquesim.fitting.fit import fit_to_accuracy
from torquesim.io.provenance import load_average
from torquesim.model.activation import ActivationProfile, Ramp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from docblocks import measured_on, write_blocks  # noqa: E402

#: Extensor (delay s, level) of each target.
TARGETS = {
    "late-ankle": {"plantarflexors": (0.15, 0.9), "knee_extensors": (0.045, 0.95),
                   "hip_extensors": (0.05, 0.85)},
    "early-hip": {"plantarflexors": (0.11, 1.0), "knee_extensors": (0.06, 0.9),
                  "hip_extensors": (0.01, 1.0)},
}


def made_by(model, timing) -> ts.ChainModel:
    """``model`` with its extensors switched on at other delays and levels (the preset's
    ramps and holds otherwise)."""
    def moved(unit):
        first, *rest = unit.activation.ramps
        delay, level = timing[unit.name]
        return replace(unit, activation=ActivationProfile(
            unit.activation.initial_level, (Ramp(delay, first.duration, level), *rest)))

    return model.replace(units=tuple(moved(u) if u.name in timing else u
                                     for u in model.units))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--angles-only", action="store_true")
    parser.add_argument("--starts", type=int, default=SearchSettings().starts)
    parser.add_argument("--write-docs", action="store_true",
                        help="write the results into docs/fitting.md")
    args = parser.parse_args()
    load = load_average()
    print(f"load average at start: {load:.2f} (2 cores)")
    rows = []
    model = ts.load_model("builtin:squat-jump")
    weight = model.weight
    for name, timing in TARGETS.items():
        # rtol 1e-9: at the default 1e-10 Radau stops 3 µs before the late-ankle jump's end
        # ("required step size is less than spacing between numbers")
        run = ts.simulate(made_by(model, timing), "reference", rtol=1e-9, output_step=0.005)
        columns = run.columns()
        channels = {} if args.angles_only else {c: columns[c] for c in
                                                 ("grf_x", "grf_y", "com_x", "com_y")}
        target = Target(run.time, run.q.T, tuple(j.name for j in model.joints), name,
                        channels)
        problem = FitProblem(target, base_model=model)
        problem.evaluate(np.array([problem.space.upper]))  # compile outside the timing
        problem.simulations = 0
        start = time.perf_counter()
        problem, outcome, _ = fit_to_accuracy(problem, SearchSettings(starts=args.starts))
        wall = time.perf_counter() - start
        fitted = ts.simulate(problem.model_for(outcome.x), "reference", output_step=0.005)
        joints = ", ".join(f"{j} {rms:.3f}°" for j, (rms, _) in
                           problem.errors_deg(fitted).items())
        force = np.interp(run.time, fitted.time, fitted.columns()["grf_y"]) - columns["grf_y"]
        percent = 100.0 * float(np.sqrt(np.mean(force**2))) / weight
        print(f"{name}: start {outcome.initial_score:.2f}, objective {outcome.score:.3f}; "
              f"RMS {joints}; vertical GRF {percent:.2f} % body weight"
              f"{' (not fitted)' if args.angles_only else ''}; {outcome.simulations} "
              f"simulations, {wall:.1f} s")
        worst = max(rms for rms, _ in problem.errors_deg(fitted).values())
        rows.append(f"| {name} | {outcome.initial_score:.2f}° | {outcome.score:.4f}° | "
                    f"{worst:.4f}° | {percent:.3f} % | {outcome.simulations} | {wall:.1f} s |")
    print(f"load average at end: {load_average():.2f}")
    if args.write_docs and not args.angles_only:
        block = (f"Measured by `python benchmarks/bench_jump_fit_unseen.py --write-docs` "
                 f"({measured_on(load)}). Each target is a jump made by the preset with other "
                 "extensor timings and levels (late-ankle: plantarflexors at 150 ms and 0.9, "
                 "knee extensors at 45 ms and 0.95, hip extensors at 50 ms and 0.85; early-hip: "
                 "110 ms / 1.0, 60 ms / 0.9, 10 ms / 1.0; the preset: 125, 45 and 30 ms at "
                 "full level), fitted with the defaults from the better of the "
                 "inverse-dynamics start and the preset's own ramps; errors with the reference "
                 "solver.\n\n"
                 "| target | start objective | objective | worst joint RMS | vertical GRF RMS "
                 "(body weight) | simulations | wall |\n|---|---|---|---|---|---|---|\n"
                 + "\n".join(rows) + "\n")
        write_blocks("docs/fitting.md", {"jump-unseen": block})


if __name__ == "__main__":
    main()
