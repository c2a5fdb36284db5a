"""What a searched model field costs a fit's population (`fit --bound PATH=LOW,HIGH` with a
model field; `optimise --bound` runs the same candidates).

Run:  python benchmarks/bench_model_fields.py [--repeats 5] [--candidates 64]

For the elbow (the flexor's SE stiffness; target ``builtin:curl``) and the squat jump (the
toe contact's stiffness; its built-in target with forces), the residuals of one population
of candidates near the inverse-dynamics guess, three ways, in one run:

1. the ramps alone (every candidate shares the model's start and packed arrays);
2. the field searched, every candidate at the model's value (one start made for all: what
   a least-squares Jacobian's ramp columns cost);
3. the field searched, every candidate at a value of its own (a start made per candidate:
   what a population of the global search or CMA-ES costs).

Prints the minimum over interleaved repeats (the machine is shared: the minimum is the
least disturbed), the ratios to (1), and max |r(2) − r(1)|, which must be 0: a candidate
at the model's value is the same run. Compilation happens before any timing.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import torquesim as ts
from torquesim.fitting import FitProblem, ParameterSpace, load_target
from torquesim.fitting.initial_guess import initial_guess

CASES = (("builtin:elbow-curl", "builtin:curl", "elbow_flexor.se_stiffness", 200.0, 900.0),
         ("builtin:squat-jump", "builtin:squat-jump", "toe.stiffness", 1e6, 1e7))


def populations(name, target_spec, path, low, high, m, rng):
    base = ts.load_model(name)
    target = load_target(target_spec, base, None, None)
    plain = FitProblem(target, ParameterSpace.for_model(base), base)
    searched = FitProblem(target, ParameterSpace.for_model(base).with_bounds(path, low, high,
                                                                             base), base)
    x = initial_guess(plain)
    ramps = np.clip(x + 0.01 * rng.normal(size=(m, x.size)), plain.space.lower,
                    plain.space.upper)
    own = searched.space.field_values(searched.model)[0]
    shared = np.column_stack([ramps, np.full(m, own)])
    distinct = np.column_stack([ramps, rng.uniform(low, high, m)])
    return plain, searched, ramps, shared, distinct


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--candidates", type=int, default=64)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    print(f"load average at start: {os.getloadavg()[0]:.2f}; {args.candidates} candidates, "
          f"min of {args.repeats} interleaved repeats")
    for case in CASES:
        plain, searched, ramps, shared, distinct = populations(*case, args.candidates, rng)
        r_plain, _ = plain.residuals(ramps)  # compiles, and the check below
        r_shared, _ = searched.residuals(shared)
        gap = float(np.max(np.abs(r_plain - r_shared)))
        times = {"ramps": [], "shared": [], "distinct": []}
        for _ in range(args.repeats):
            for key, problem, rows in (("ramps", plain, ramps), ("shared", searched, shared),
                                       ("distinct", searched, distinct)):
                problem.own_starts.kept.clear()  # no start made by an earlier repeat
                begin = time.perf_counter()
                problem.residuals(rows)
                times[key].append(time.perf_counter() - begin)
        best = {key: min(value) for key, value in times.items()}
        print(f"{case[0]} with {case[2]} searched: ramps alone {best['ramps'] * 1e3:.1f} ms; "
              f"field at the model's value {best['shared'] * 1e3:.1f} ms "
              f"({best['shared'] / best['ramps']:.2f}x); a value per candidate "
              f"{best['distinct'] * 1e3:.1f} ms ({best['distinct'] / best['ramps']:.2f}x); "
              f"max |r(field at its value) - r(ramps)| = {gap:.1e}")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
