"""Measure how well simulate()'s default checks catch wrong runs, and what they cost.

    python scripts/accuracy_checks.py [--out accuracy_checks.csv]

For the curl and the arm raise: every fixed-step technique (monolithic, IMEX, every coupling
variant) at 20, 10, 5, 2, 1, 0.5 and 0.25 ms with simulate()'s default arguments, against a
Radau reference. Prints the runs more than 0.1 rad off that were silent (goal: none), the
warnings on runs within 0.01 rad (false alarms), and the cost of the default check: the wall
time of IMEX at 5 ms with and without it, minimum of 15 interleaved repeats (the load is
printed beside it).
"""

from __future__ import annotations

import argparse
import csv
import os
import time

import torquesim as ts
from torquesim.solvers.simulation import DEFAULT_TOLERANCE
from torquesim.study.checks import check_study


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="CSV of every run")
    args = parser.parse_args()
    rows = []
    for name in ("builtin:elbow-curl", "builtin:arm-raise"):
        for row in check_study(ts.load_model(name)):
            rows.append({"model": name, **row})
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
    wrong = counts.get("caught", 0) + counts.get("missed", 0)
    right = counts.get("false alarm", 0) + sum(
        1 for r in rows if r["outcome"] == "quiet" and r["max_error_rad"] <= 0.01)
    print(f"{len(rows)} runs; {wrong} more than 0.1 rad off: {counts.get('missed', 0)} silent; "
          f"{right} within 0.01 rad: {counts.get('false alarm', 0)} with a warning")
    for r in rows:
        if r["outcome"] in ("missed", "false alarm"):
            est = r["estimated_error_rad"]
            print(f"  {r['outcome']}: {r['model']} {r['technique']} h {r['h_s'] * 1e3:g} ms: "
                  f"error {r['max_error_rad']:.3g} rad, estimate "
                  f"{'-' if est is None else f'{est:.3g}'} rad: {r['message'][:90]}")
    model = ts.load_model("builtin:elbow-curl")
    best = {"off": float("inf"), "on": float("inf")}
    for _ in range(15):
        for key, tolerance in (("off", None), ("on", DEFAULT_TOLERANCE)):
            start = time.perf_counter()
            ts.simulate(model, "imex", 5e-3, tolerance=tolerance)
            best[key] = min(best[key], time.perf_counter() - start)
    load = os.getloadavg()[0]
    print(f"cost of the default check (imex, 5 ms, curl): {best['on'] / best['off']:.2f}x the "
          f"run without it ({best['on'] * 1e3:.1f} vs {best['off'] * 1e3:.1f} ms, minimum of 15 "
          f"interleaved repeats, load average {load:.2f})")
    if args.out:
        with open(args.out, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
