"""The squat jump's cost: per step against the arm raise, and the runs to 0.1° … 0.001°.

Run:  python benchmarks/bench_jump.py [--repeats 7]

Prints, with the load average before and after (these machines are shared: lead with the
ratios, measured in one run with the two models interleaved and the minimum of the repeats
taken):
- wall time per step of builtin:squat-jump (4 segments on a free base, 6 units, 2 contacts)
  and builtin:arm-raise (2 segments, 4 units) with the same technique (monolithic RK4 at
  25 µs, IMEX at 0.1 ms), and their ratio (target ≤ 3×);
- the squat jump's max joint-angle error against Radau (rtol 1e-10) and warm wall time of the
  cheapest runs `torquesim compare` names (docs/study.md, "The study on a jump"): IMEX at
  0.25 ms for 0.1° and 0.01° (target for 0.1°: ≤ 50 ms warm on an idle 2-core machine), IMEX
  at 0.1 ms for 0.001°; and, for comparison, monolithic RK4 at 25 µs.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import torquesim as ts
from torquesim.io.provenance import load_average


def wall(model, method, step) -> float:
    start = time.perf_counter()
    ts.simulate(model, method, step, tolerance=None, check=False)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    print(f"load average at start: {load_average():.2f} (2 cores)")
    jump, arm = ts.load_model("builtin:squat-jump"), ts.load_model("builtin:arm-raise")
    for method, step in (("monolithic", 2.5e-5), ("imex", 1e-4)):
        for model in (jump, arm):  # compile outside the timing
            ts.simulate(model.replace(duration=0.01), method, step, tolerance=None,
                        check=False)
        per_step = {jump.name: math.inf, arm.name: math.inf}
        for _ in range(args.repeats):  # interleaved: load hits both alike
            for model in (jump, arm):
                steps = round(model.duration / step)
                per_step[model.name] = min(per_step[model.name],
                                           wall(model, method, step) / steps)
        ratio = per_step[jump.name] / per_step[arm.name]
        print(f"{method:10s} step {step * 1e3:g} ms: squat-jump {per_step[jump.name] * 1e9:.0f} "
              f"ns per step, arm-raise {per_step[arm.name] * 1e9:.0f} ns per step -> "
              f"{ratio:.2f}x (target <= 3x -> {'met' if ratio <= 3 else 'NOT met'})")
    reference = ts.simulate(jump, "reference", rtol=1e-10, atol=1e-12)
    for method, step, accuracy in (("imex", 2.5e-4, 0.1), ("imex", 1e-4, 0.001),
                                   ("monolithic", 2.5e-5, 0.001)):
        run = ts.simulate(jump, method, step, tolerance=None)
        k = int(round(1e-3 / step))
        error = math.degrees(float(np.max(np.abs(run.q[::k] - reference.q))))
        best = min(wall(jump, method, step) for _ in range(args.repeats))
        target = f" (target <= 50 ms -> {'met' if best <= 0.05 else 'NOT met'})" \
            if accuracy == 0.1 else ""
        print(f"to {accuracy:g} deg: {method} at {step * 1e3:g} ms, error {error:.3g} deg, "
              f"warm wall time {best * 1e3:.1f} ms (min of {args.repeats}){target}")
    print(f"load average at end: {load_average():.2f}")


if __name__ == "__main__":
    main()
