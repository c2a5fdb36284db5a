"""The fit benchmark of the fitting issue: builtin:curl with default settings.

Run:  python benchmarks/bench_fit.py [--no-repeat] [--no-baseline]

Prints, on this machine:
- the default fit (IMEX at 5 ms, inverse-dynamics start, differential evolution 300
  generations, Nelder-Mead 4000 simulations, seed 1): RMS/max angle error in the fit and
  re-simulated with the reference solver (Radau, rtol 1e-10), simulations, simulations per
  second, wall time (target: ≤ 1.0° RMS with the reference, ≤ 60 s on 2 cores);
- the same fit run again with the same seed, and whether the parameters are bit-identical;
- a baseline measured in the same run with the same wall time: plain SciPy differential
  evolution (random Latin-hypercube start, default settings) over the 9 flexor parameters,
  extensor at rest, explicit monolithic RK4 at 0.25 ms (the largest step that is accurate on
  this model), using torquesim's own compiled objective, so the difference is the method.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from scipy.optimize import differential_evolution

from torquesim.fitting import FitProblem, ParameterSpace, SearchSettings, min_jerk_curl, run_fit
from torquesim.fitting.parameters import PARAMETER_NAMES


def default_fit():
    problem = FitProblem(min_jerk_curl())
    problem.evaluate(problem.space.clip(np.array(problem.space.upper)))  # compile first
    problem.simulations = problem.failed_simulations = 0
    start = time.perf_counter()
    outcome = run_fit(problem, SearchSettings())
    wall = time.perf_counter() - start
    ref_rms, ref_max = problem.reference_errors_deg(outcome.x)
    return problem, outcome, wall, ref_rms, ref_max


def baseline(seconds: float):
    """Plain DE over the 9 flexor parameters, RK4 at 0.25 ms, for ``seconds`` of wall time."""
    frozen = {n: 0.0 if n.endswith("delay") else 0.3 if n.endswith("duration") else 0.1
              for n in PARAMETER_NAMES if n.startswith("extensor")}
    problem = FitProblem(min_jerk_curl(), ParameterSpace(frozen=frozen), method="monolithic",
                         step=2.5e-4)
    base = problem.space.full(np.zeros(9), np.zeros(18))
    problem.evaluate(base)
    problem.simulations = 0
    start = time.perf_counter()
    best = [np.inf, None]

    def objective(x):
        score = problem.evaluate(problem.space.full(x, base))[0][0]
        if score < best[0]:
            best[:] = [score, x.copy()]
        return score

    def timeout(intermediate_result):
        return time.perf_counter() - start > seconds

    differential_evolution(objective, problem.space.bounds(), rng=1, polish=False,
                           callback=timeout, maxiter=100_000)
    wall = time.perf_counter() - start
    ref_rms, _ = problem.reference_errors_deg(problem.space.full(best[1], base))
    return problem.simulations, wall, best[0], ref_rms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-repeat", action="store_true", help="skip the reproducibility run")
    parser.add_argument("--no-baseline", action="store_true", help="skip the baseline")
    args = parser.parse_args()
    print(f"cores: {os.cpu_count()}; numba threads: "
          f"{__import__('numba').config.NUMBA_NUM_THREADS}")
    problem, outcome, wall, ref_rms, ref_max = default_fit()
    print("default fit on builtin:curl (imex, 5 ms, seed 1)")
    print(f"  fit objective       {outcome.score:.3f} deg RMS (start {outcome.initial_score:.3f})")
    print(f"  reference re-sim    {ref_rms:.3f} deg RMS, {ref_max:.3f} deg max")
    print(f"  simulations         {outcome.simulations} "
          f"({outcome.simulations / wall:.0f} per second)")
    print(f"  wall time           {wall:.1f} s")
    if not args.no_repeat:
        _, again, wall2, _, _ = default_fit()
        same = np.array_equal(again.x, outcome.x)
        print(f"  same seed again     {again.score:.3f} deg RMS in {wall2:.1f} s; parameters "
              f"{'bit-identical' if same else 'DIFFERENT'}")
    if not args.no_baseline:
        sims, bwall, bscore, bref = baseline(wall)
        print("baseline: plain DE, 9 flexor parameters, monolithic RK4 0.25 ms, same wall time")
        print(f"  reached             {bscore:.3f} deg RMS (reference {bref:.3f}) after {sims} "
              f"simulations ({sims / bwall:.0f} per second) in {bwall:.1f} s")
        print(f"  ratio               torquesim error {ref_rms / bref:.2f}x the baseline's; "
              f"{(outcome.simulations / wall) / (sims / bwall):.0f}x the simulations per second")


if __name__ == "__main__":
    main()
