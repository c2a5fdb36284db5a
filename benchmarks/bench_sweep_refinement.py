"""The cost of re-running inaccurate sweep samples at a halved step: the issue's example,
``batch sweep --vary forearm_hand.dumbbell.mass=uniform(2,8) --samples 200`` (IMEX 5 ms,
0.5° tolerance), in this tree and in a baseline tree, interleaved.

    python benchmarks/bench_sweep_refinement.py --baseline /path/to/older/checkout/src
    python benchmarks/bench_sweep_refinement.py --baseline ... --repeats 5 --samples 200

Each tree runs in its own process (the baseline's ``src`` first on PYTHONPATH, e.g. a
``git worktree`` of an older commit): one sweep to compile and warm up, then ``--repeats``
timed sweeps in process (no cluster: 200 samples are small work), alternating between the
trees; the minimum of each is kept (load only ever adds time) and the ratio this/baseline is
printed with the load average. Also printed: each tree's verdict counts and, for this tree,
how many samples were re-run and at which steps. Without ``--baseline`` only this tree runs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

WORKER = r"""
import json, sys, time
from torquesim.batch import sweep
vary, samples, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
sweep("builtin:elbow-curl", [vary], samples=samples, seed=1)  # compile, warm up
times = []
for _ in range(repeats):
    start = time.perf_counter()
    table, _ = sweep("builtin:elbow-curl", [vary], samples=samples, seed=1)
    times.append(time.perf_counter() - start)
counts = table["accuracy"].value_counts().to_dict()
steps = table["step_s"].value_counts().to_dict() if "step_s" in table else {}
print(json.dumps({"times": times, "counts": counts,
                  "steps_ms": {f"{k * 1e3:g}": int(v) for k, v in steps.items()}}))
"""


def run(src: str | None, vary: str, samples: int, repeats: int) -> dict:
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run([sys.executable, "-c", WORKER, vary, str(samples), str(repeats)],
                          env=env, capture_output=True, text=True, check=True,
                          cwd=Path(__file__).resolve().parent)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="src folder of another version")
    parser.add_argument("--samples", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2,
                        help="processes per tree, alternating")
    args = parser.parse_args()
    vary = "forearm_hand.dumbbell.mass=uniform(2,8)"
    here = str(Path(__file__).resolve().parent.parent / "src")
    print(f"load average at start: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    best = {"this": [], "baseline": []}
    last = {}
    for _ in range(args.rounds):
        for name, src in (("this", here), ("baseline", args.baseline)):
            if name == "baseline" and not args.baseline:
                continue
            got = run(src, vary, args.samples, args.repeats)
            best[name] += got["times"]
            last[name] = got
    for name, got in last.items():
        print(f"{name:8s} min {min(best[name]):.3f} s over {len(best[name])} sweeps; "
              f"verdicts {got['counts']}; steps (ms: samples) {got['steps_ms']}")
    if args.baseline:
        print(f"this / baseline: {min(best['this']) / min(best['baseline']):.2f}x")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
