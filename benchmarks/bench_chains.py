"""Chains: the elbow against the elbow-only code it replaced, and cost per step against the
number of segments.

Run:  python benchmarks/bench_chains.py [--repeats 15] [--rounds 3] [--against COMMIT]
                                       [--write-docs]

1. **The elbow is unchanged and no slower.** The elbow-only implementation (torquesim 0.1,
   git commit ``FROZEN_COMMIT``) is extracted from the repository's history into a temporary
   folder (``git archive``) and run in its own process with its own Numba cache; the current
   code runs the same curl in another process. Both print the median wall time of
   ``--repeats`` runs per method after compilation; the two processes alternate for
   ``--rounds`` rounds (so machine load hits both alike) and the ratio current/frozen is
   printed per round. The trajectories of both are compared (max |Δy|, target ≤ 1e-12 rad).
   Target: monolithic at 0.1 ms within 1.2× of the frozen code. ``--against COMMIT`` compares
   with another commit instead (a refactoring's before and after; target 1.05×).
2. **Cost per RK4 step against chain length.** Chains of 1 to 6 segments (two units per
   joint, constant activations, 1 s at 0.1 ms, monolithic RK4) in this process; ns per step
   and the ratio to the elbow preset, timed alternately with it (median of paired ratios).
   Targets: 2 segments ≤ 2.5×, 6 segments ≤ 8× the elbow's per-step cost.

``--write-docs`` (against the frozen code, with the chains) writes the figures into the
``chains-benchmark`` block of README.md.
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

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from docblocks import measured_on, write_blocks  # noqa: E402  (scripts/)

FROZEN_COMMIT = "d52e451"
#: The per-step targets: chain length (segments) → at most this many times the elbow's cost.
CHAIN_TARGETS = {2: 2.5, 6: 8.0}
ROOT = Path(__file__).resolve().parent.parent
METHODS = {  # name: (method, step s, coupling keyword arguments)
    "monolithic 0.1 ms": ("monolithic", 1e-4, None),
    "partitioned 0.1 ms": ("partitioned", 1e-4, None),
    "imex 5 ms": ("imex", 5e-3, None),
}

TIMER = r"""
import json, sys, time
import numpy as np
import torquesim as ts
methods = json.loads(sys.argv[1]); repeats = int(sys.argv[2]); save = sys.argv[3]
model = ts.default_model()
out, states = {}, {}
for name, (method, step, _) in methods.items():
    ts.simulate(model, method, step)
    walls = [ts.simulate(model, method, step).cost.wall_time for _ in range(repeats)]
    out[name] = float(np.median(walls))
    states[name] = ts.simulate(model, method, step).states
np.savez(save, **states)
print(json.dumps(out))
"""


def run_timer(src: Path, cache: Path, repeats: int, save: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(cache))
    proc = subprocess.run([sys.executable, "-c", TIMER, json.dumps(METHODS), str(repeats),
                           str(save)], env=env, capture_output=True, text=True, check=True,
                          cwd=save.parent)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def frozen_against_current(repeats: int, rounds: int, commit: str = FROZEN_COMMIT) -> dict:
    """Time the elbow with this tree and with ``commit``'s (module docstring, part 1); print
    and return {method: (median ratio current/frozen, per-round ratios)} and "max_diff"."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        frozen = tmp / "frozen"
        frozen.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit, "src"],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(frozen)], input=archive, check=True)
        sources = {"frozen": frozen / "src", "current": ROOT / "src"}
        results = {k: [] for k in sources}
        for r in range(rounds):
            for label, src in sources.items():
                results[label].append(run_timer(src, tmp / f"cache-{label}", repeats,
                                                tmp / f"{label}.npz"))
            last = {k: v[-1] for k, v in results.items()}
            ratios = ", ".join(f"{name} {last['current'][name] / last['frozen'][name]:.2f}×"
                               for name in METHODS)
            print(f"round {r + 1}: current/frozen median wall time: {ratios}")
        for name in METHODS:
            frozen_t = np.median([x[name] for x in results["frozen"]])
            current_t = np.median([x[name] for x in results["current"]])
            print(f"{name:20s} frozen {frozen_t * 1e3:7.2f} ms, current {current_t * 1e3:7.2f} ms"
                  f" -> {current_t / frozen_t:.2f}× (median over rounds)")
        old, new = np.load(tmp / "frozen.npz"), np.load(tmp / "current.npz")
        worst = max(float(np.max(np.abs(old[n] - new[n]))) for n in METHODS)
        print(f"max |y_current − y_frozen| over these runs: {worst:.3g} (target ≤ 1e-12)")
        rounds = {name: [x[name] / y[name] for x, y in
                         zip(results["current"], results["frozen"], strict=True)]
                  for name in METHODS}
        mono = float(np.median(rounds["monolithic 0.1 ms"]))
        limit = 1.2 if commit == FROZEN_COMMIT else 1.05
        print(f"target monolithic within {limit:g}× of {commit}: {mono:.2f}× -> "
              f"{'met' if mono <= limit else 'NOT met'}")
        return {**{name: (float(np.median(r)), r) for name, r in rounds.items()},
                "max_diff": worst}


def test_chain(n: int):
    """An n-segment chain, two units per joint (flexor held from equilibrium, extensor at a
    constant 0.1), hanging slightly flexed."""
    import torquesim as ts

    flexor, extensor = ts.TorqueGeneratorUnit.flexor_default(), \
        ts.TorqueGeneratorUnit.extensor_default()
    segments, joints, units = [], [], []
    for k in range(n):
        mass = 4.0 / (k + 1)
        segments.append(ts.Segment(f"s{k}", mass, 0.15, mass * 0.15**2 + 0.01, 0.3))
        joints.append(ts.Joint(f"j{k}", initial_angle=0.2, endstop_lower_angle=-1.0))
        units += [ts.Unit(f"f{k}", f"j{k}", 1, flexor, ts.ActivationProfile(None)),
                  ts.Unit(f"e{k}", f"j{k}", -1, extensor, ts.ActivationProfile(0.1))]
    return ts.ChainModel(f"chain{n}", tuple(segments), tuple(joints), tuple(units),
                         duration=1.0)


def cost_per_segment_count(repeats: int) -> dict[int, float]:
    """Per-step cost of chains of 1–6 segments against the elbow preset. The elbow and the
    chain are timed alternately, run by run, and the median of the paired ratios is printed
    (and returned, by segment count), so a change of machine load between the two does not
    enter the ratio."""
    import torquesim as ts

    def per_step(model) -> float:
        run = ts.simulate(model, "monolithic", 1e-4, check=False)
        return run.cost.wall_time / run.cost.steps

    elbow = ts.load_model("builtin:elbow-curl")
    per_step(elbow)
    ratios = {}
    for n in range(1, 7):
        chain = test_chain(n)
        per_step(chain)
        pairs = [(per_step(elbow), per_step(chain)) for _ in range(repeats)]
        ratio = float(np.median([c / e for e, c in pairs]))
        ratios[n] = ratio
        cost = float(np.median([c for _, c in pairs]))
        elbow_cost = float(np.median([e for e, _ in pairs]))
        verdict = ""
        if n in CHAIN_TARGETS:
            verdict = (f" (target ≤ {CHAIN_TARGETS[n]:g}× -> "
                       f"{'met' if ratio <= CHAIN_TARGETS[n] else 'NOT met'})")
        print(f"{n} segment{'s' if n > 1 else ' '}, {2 * n:2d} units: {cost * 1e9:7.0f} ns per "
              f"step (elbow {elbow_cost * 1e9:5.0f} ns alongside), {ratio:5.2f}× the elbow"
              f"{verdict}")
    return ratios


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--against", default=FROZEN_COMMIT,
                        help="commit to compare the elbow with (default: the frozen 0.1 code)")
    parser.add_argument("--skip-chains", action="store_true",
                        help="only the comparison with the other commit")
    parser.add_argument("--write-docs", action="store_true",
                        help="write the figures into README.md's chains-benchmark block "
                             "(against the frozen code, with the chains)")
    args = parser.parse_args()
    if args.write_docs and (args.skip_chains or args.against != FROZEN_COMMIT):
        parser.error("--write-docs measures against the frozen code, with the chains")
    start = time.perf_counter()
    load = os.getloadavg()[0]
    print(f"load average at start: {load:.2f} (2 cores)")
    elbow = frozen_against_current(args.repeats, args.rounds, args.against)
    if not args.skip_chains:
        chains = cost_per_segment_count(args.repeats)
    print(f"load average at end: {os.getloadavg()[0]:.2f}; "
          f"benchmark took {time.perf_counter() - start:.0f} s")
    if args.write_docs:
        mono, rounds = elbow["monolithic 0.1 ms"]
        verdict = {n: "met" if chains[n] <= t else "not met" for n, t in CHAIN_TARGETS.items()}
        block = (
            f"Measured by `python benchmarks/bench_chains.py --write-docs` ({measured_on(load)}, "
            f"{args.rounds} rounds): monolithic at 0.1 ms **{mono:.2f}×** the frozen code's "
            f"time (target ≤ 1.2×: {'met' if mono <= 1.2 else 'not met'}; rounds "
            + ", ".join(f"{r:.2f}×" for r in rounds)
            + f"), partitioned {elbow['partitioned 0.1 ms'][0]:.2f}×, IMEX at 5 ms "
            f"{elbow['imex 5 ms'][0]:.2f}×; trajectories identical to "
            f"{elbow['max_diff']:.2g} (max difference). Cost per RK4 step against chain "
            f"length, each chain timed alternately with the elbow (median of paired ratios): "
            f"2 segments **{chains[2]:.2f}×** the elbow's (target ≤ {CHAIN_TARGETS[2]:g}×: "
            f"{verdict[2]}), 6 segments **{chains[6]:.2f}×** (target ≤ {CHAIN_TARGETS[6]:g}×: "
            f"{verdict[6]}; 6 segments carry 6× the elbow's units).\n")
        write_blocks("README.md", {"chains-benchmark": block})


if __name__ == "__main__":
    main()
