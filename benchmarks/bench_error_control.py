"""Error-controlled steps against fixed ones on the bodies on the ground (issue 33's figures).

Run:  python benchmarks/bench_error_control.py [--repeats 5] [--models squat-jump,drop-landing]

For each model and accuracy (max joint-angle error against Radau at rtol 1e-10, on the 1 ms
grid), the cheapest run of each technique that meets it, on two ladders of settings: the
study's (IMEX and imex-ros2 over the study's steps, imex-ros2-adaptive over its angle
tolerances, `CONTROLLED_TOLERANCES`: 1-2-5 a decade) and a fine one (10 settings a decade for
every technique: what each costs when its setting is chosen for the accuracy). Printed per
run: its setting, its true error, its counted work in body evaluations
(`torquesim.solvers.choice.WORK_UNITS`: counts, so independent of the machine's load) and
its warm wall time (the minimum of ``--repeats`` interleaved repeats); and the ratio of each
to IMEX at 0.25 ms (issue 33's baseline: within 0.1° at ≥ 5× less, within 0.01° at ≥ 3×
less). The load average is printed before and after: lead with the work ratios.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import torquesim as ts
from torquesim.io.provenance import load_average
from torquesim.solvers.choice import work_of
from torquesim.solvers.techniques import CONTROLLED_TOLERANCES
from torquesim.study.compare import default_steps

ACCURACIES_DEG = (0.1, 0.01)
BASELINE = ("imex", 0.25e-3)
ADAPTIVE = "imex-ros2-adaptive"
GRID = 1e-3


def run(model, method, setting):
    if method == ADAPTIVE:
        return ts.simulate(model, method, atol=setting, output_step=GRID, tolerance=None,
                           check=False)
    return ts.simulate(model, method, setting, tolerance=None, check=False, advise=False)


def error_deg(result, reference) -> float:
    if not result.success:
        return math.inf
    k = max(1, int(round(GRID / result.step))) if result.step else 1
    q = result.q[::k][: reference.q.shape[0]]
    return math.degrees(float(np.max(np.abs(q - reference.q[: q.shape[0]]))))


def ladders(model) -> dict[str, list[tuple[str, float]]]:
    """The runs of each ladder: the study's (its steps and `CONTROLLED_TOLERANCES`, with the
    baseline's step) and a fine one for every technique: the steps 1 ms/k (k = 1 … 20, each
    on the 1 ms output grid, 1 ms … 0.05 ms), 2 ms and 5 ms, and the tolerances 10^(k/10) rad
    (10 a decade, 2e-3 … 5e-6)."""
    steps = sorted(set(default_steps(model)) | {BASELINE[1]}, reverse=True)
    study = [(m, h) for m in ("imex", "imex-ros2") for h in steps] + \
        [(ADAPTIVE, a) for a in CONTROLLED_TOLERANCES]
    fine_steps = [5 * GRID, 2 * GRID] + [GRID / k for k in range(1, 21)]
    fine = [(m, h) for m in ("imex", "imex-ros2") for h in fine_steps] + \
        [(ADAPTIVE, 10.0 ** (k / 10.0)) for k in range(-27, -54, -1)]
    return {"the study's ladder (1-2-5)": study, "a fine ladder (10 a decade)": fine}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--models", default="squat-jump,drop-landing")
    args = parser.parse_args()
    print(f"load average at start: {load_average():.2f} (2 cores)")
    for name in args.models.split(","):
        model = ts.load_model(f"builtin:{name}")
        reference = ts.simulate(model, "reference", output_step=GRID)
        rows, chosen, runs = {}, {}, ladders(model)
        for ladder, jobs in runs.items():
            for job in jobs:
                if job not in rows:
                    result = run(model, *job)
                    rows[job] = {"error": error_deg(result, reference),
                                 "work": work_of(result, job[0]), "wall": math.inf}
            for accuracy in ACCURACIES_DEG:  # the cheapest run of each technique within it
                for method in ("imex", "imex-ros2", ADAPTIVE):
                    met = [job for job in jobs
                           if job[0] == method and rows[job]["error"] <= accuracy]
                    chosen[ladder, accuracy, method] = \
                        min(met, key=lambda job: rows[job]["work"]) if met else None
        timed = sorted({job for job in chosen.values() if job} | {BASELINE})
        for _ in range(args.repeats):  # interleaved: a change of load hits every run alike
            for job in timed:
                start = time.perf_counter()
                run(model, *job)
                rows[job]["wall"] = min(rows[job]["wall"], time.perf_counter() - start)
        base = rows[BASELINE]
        print(f"\n{name}: baseline {BASELINE[0]} at {BASELINE[1] * 1e3:g} ms: error "
              f"{base['error']:.4f}°, work {base['work']:.0f} body evaluations, "
              f"{base['wall'] * 1e3:.2f} ms")
        for ladder in runs:
            print(f"\nThe cheapest run of each technique on {ladder}:\n")
            print("| accuracy | technique | setting | error | work | work ratio | wall | "
                  "wall ratio |")
            print("|---|---|---|---|---|---|---|---|")
            for accuracy in ACCURACIES_DEG:
                for method in ("imex", "imex-ros2", ADAPTIVE):
                    job = chosen[ladder, accuracy, method]
                    if job is None:
                        print(f"| {accuracy:g}° | {method} | none within | | | | | |")
                        continue
                    r = rows[job]
                    setting = f"atol {job[1]:.3g} rad" if method == ADAPTIVE \
                        else f"{job[1] * 1e3:.4g} ms"
                    print(f"| {accuracy:g}° | {method} | {setting} | {r['error']:.4f}° | "
                          f"{r['work']:.0f} | {base['work'] / r['work']:.2f}× | "
                          f"{r['wall'] * 1e3:.2f} ms | {base['wall'] / r['wall']:.2f}× |")
    print(f"\nload average at end: {load_average():.2f}")


if __name__ == "__main__":
    main()
