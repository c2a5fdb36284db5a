"""Optimisation benchmarks of the optimise issue, all measured in one run.

Run:  python benchmarks/bench_optimise.py [--skip curl,jump,cluster] [--write-docs]

Prints, on this machine (compilation is done before any timing):

1. ``builtin:elbow-curl``, ``--minimise time_to:elbow=90deg`` (60 generations, seed 1): the
   time to 90° at start and optimum, both re-simulated with the reference solver, and the
   optimisation's wall time warm (the minimum of 3 runs; each the same search): the search's
   own (CMA-ES and its simulations, as the command's "wall time" line) and the whole call's
   (also the choice of technique, the reference runs and the parameters' effects).
2. ``builtin:squat-jump``, ``--maximise jump_height`` (60 generations, seed 1): plain (the
   minimum of 3 runs), and robust (worst of the run and 10 copies with ±10 ms onset errors
   on every ramp; one run). Jump
   heights at start and optimum with the reference solver; then start and both optima under
   the same 10 copies: the lowest jump among the copies that run and the copies that fail
   (with the reason).
3. A real Dask cluster of separate processes: ``dask scheduler`` and ``dask worker``
   (1 thread each) started in their own temporary folders. The same 96 jump candidates
   scored on 1 worker and on 2, interleaved, 3 repeats each, the minimum kept: simulations
   per second and their ratio (target ≥ 1.7 on an idle machine; the load is printed), and
   the optimum found on 2 workers against this process's (must be identical).

4. The spread of the optima across machines: the curl and the plain jump optimised again in
   fresh processes, once per OpenBLAS kernel set this CPU runs (``OPENBLAS_CORETYPE``:
   Prescott, Nehalem, Sandybridge, Haswell). CMA-ES draws its candidates through an
   eigendecomposition of its covariance (LAPACK, in OpenBLAS), whose last bits depend on the
   kernel set OpenBLAS picks for the CPU; the search is chaotic, so a same-seed optimum moves
   with the machine (measured: the curl 639.0 ms with Haswell's kernels, 641.7 ms with
   Prescott's). The Numba-compiled simulations do not (the same optimum with
   ``NUMBA_CPU_NAME=generic``). The spread is stated beside each number and written to
   ``docs/data/optimise_spread.json``, against which ``scripts/make_docs.py --check``
   compares a regenerated optimum.

With ``--write-docs`` the results go into the ``optimise-benchmark`` block of
docs/optimise.md (with the date and load) and the spread into its JSON file. With
``--figures`` the curl's and the plain jump's start-and-optimum figures (as ``optimise.png``
draws them) are written to docs/figures/optimise_curl.png and optimise_jump.png.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

import torquesim as ts
from torquesim.optimisation import OptimiseProblem, OptimiseSettings, goals_of

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from docblocks import measured_on, write_blocks  # noqa: E402

RESULTS: dict = {}


def curl() -> None:
    model = ts.load_model("builtin:elbow-curl")
    settings = OptimiseSettings(generations=60)
    ts.optimise(model.replace(duration=0.5), minimise="time_to:elbow=30deg",
                settings=OptimiseSettings(generations=1))  # compile
    walls, searches = [], []
    for _ in range(3):
        start = time.perf_counter()
        best = ts.optimise(model, minimise="time_to:elbow=90deg", settings=settings)
        walls.append(time.perf_counter() - start)
        searches.append(best.outcome.wall_time)
    goal = best.summary["goals"][0]
    print("1. builtin:elbow-curl, minimise time_to:elbow=90deg (60 generations)")
    print(f"   reference: start {goal['reference_start'] * 1e3:.1f} ms → optimum "
          f"{goal['reference_optimum'] * 1e3:.1f} ms ({goal['reference_gain_percent']:.1f} % "
          f"faster); {best.outcome.simulations} simulations; wall "
          f"{', '.join(f'{w:.2f}' for w in walls)} s (min {min(walls):.2f} s)")
    goal = {**goal, "_method": best.summary["method"], "_step": best.summary["step_s"]}
    RESULTS["curl"] = (goal, best.outcome.simulations, min(searches), min(walls))
    RESULTS["curl_best"] = best


def jump() -> None:
    model = ts.load_model("builtin:squat-jump")
    settings = OptimiseSettings(generations=60)
    print("2. builtin:squat-jump, maximise jump_height (60 generations)")
    ts.optimise(model, maximise="jump_height", settings=OptimiseSettings(generations=1))
    rows = {}
    for label, robust, repeats in (("plain", 0, 3), ("robust", 10, 1)):
        walls, searches = [], []
        for _ in range(repeats):  # the minimum of the repeats, as the curl's
            start = time.perf_counter()
            best = ts.optimise(model, maximise="jump_height", robust=robust, settings=settings)
            walls.append(time.perf_counter() - start)
            searches.append(best.outcome.wall_time)
        rows[label] = (best, min(searches), min(walls))
        goal = best.summary["goals"][0]
        print(f"   {label}: reference start {goal['reference_start'] * 100:.2f} cm → optimum "
              f"{goal['reference_optimum'] * 100:.2f} cm (+{goal['reference_gain_percent']:.1f}"
              f" %); {best.outcome.simulations} simulations, search "
              f"{', '.join(f'{w:.2f}' for w in searches)} s, whole call "
              f"{', '.join(f'{w:.2f}' for w in walls)} s")
    robust_problem = OptimiseProblem(model, goals_of(model, maximise="jump_height"), robust=10)
    copies = {}
    for label, x in (("start", robust_problem.x0), *((k, b.outcome.x) for k, (b, _, _) in
                                                     rows.items())):
        values, reasons, _ = robust_problem.goal_values(robust_problem.expand(x[None, :]))
        usable = values[:, 0][np.isfinite(values[:, 0])]
        failed = [r for r in reasons if r]
        copies[label] = (float(usable.min()), len(failed), sorted(set(failed)))
        print(f"   {label}: worst of the run and the 10 copies (±10 ms) "
              f"{copies[label][0] * 100:.2f} cm; failed copies {len(failed)}"
              + (f" ({'; '.join(copies[label][2])})" if failed else ""))
    RESULTS["jump"] = (rows, copies, _technique(robust_problem.method, robust_problem.step))
    RESULTS["jump_best"] = rows["plain"][0]


def _technique(method: str, step: float) -> str:
    return f"{method} {step * 1e3:.4g} ms"


def figures() -> None:
    """docs/figures/optimise_{curl,jump}.png: start (dashed) and optimum (solid) of the curl
    and the plain jump, as `torquesim optimise` draws them (reference solver)."""
    from torquesim.plots import plot_comparison, save_figure

    folder = Path(__file__).resolve().parent.parent / "docs" / "figures"
    for case, label in (("curl", "time to 90°"), ("jump", "jump height")):
        best = RESULTS.get(f"{case}_best")
        if best is None:
            continue
        runs = best.summary["_runs"]
        goal = best.summary["goals"][0]
        scale, unit = (1e3, "ms") if case == "curl" else (1e2, "cm")
        title = (f"torquesim optimise {best.summary['model']}: {label} "
                 f"{goal['reference_start'] * scale:.1f} → {goal['reference_optimum'] * scale:.1f}"
                 f" {unit} (reference solver)")
        save_figure(plot_comparison(runs["start"], runs["optimum"], title=title),
                    folder / f"optimise_{case}.png")
        print(f"wrote docs/figures/optimise_{case}.png")


#: OpenBLAS kernel sets tried for the spread (those this CPU cannot run are skipped).
CORE_TYPES = ("Prescott", "Nehalem", "Sandybridge", "Haswell")
SPREAD_FILE = Path(__file__).resolve().parent.parent / "docs" / "data" / "optimise_spread.json"
#: The optimisations whose spread is measured: name → (model, goal keyword, goal, unit scale).
SPREAD_CASES = {"curl": ("builtin:elbow-curl", "minimise", "time_to:elbow=90deg", 1e3),
                "jump": ("builtin:squat-jump", "maximise", "jump_height", 1e2)}
_SPREAD_RUN = r"""
import json, sys
import torquesim as ts
from torquesim.optimisation import OptimiseSettings
model, sense, goal = sys.argv[1:4]
best = ts.optimise(model, settings=OptimiseSettings(generations=60), **{sense: goal})
print(json.dumps(best.summary["goals"][0]["reference_optimum"]))
"""


def optimum_in_process(case: str, core_type: str | None = None) -> float | None:
    """The reference optimum (SI) of ``case`` (`SPREAD_CASES`, seed 1, 60 generations) in a
    fresh process, with OpenBLAS's ``core_type`` kernels (None: the CPU's own); None when this
    CPU cannot run them."""
    model, sense, goal, _ = SPREAD_CASES[case]
    env = dict(os.environ)
    if core_type:
        env["OPENBLAS_CORETYPE"] = core_type
    done = subprocess.run([sys.executable, "-c", _SPREAD_RUN, model, sense, goal], env=env,
                          capture_output=True, text=True)
    if done.returncode != 0:
        return None
    return float(done.stdout.strip().splitlines()[-1])


def spread() -> None:
    import json

    print("4. the same optima with each OpenBLAS kernel set (fresh processes)")
    found = {}
    for case, (_, _, goal, scale) in SPREAD_CASES.items():
        values = {}
        for core in CORE_TYPES:
            value = optimum_in_process(case, core)
            if value is not None:
                values[core] = value
        own = optimum_in_process(case)
        found[case] = {"goal": goal, "by_kernel_set": values, "this_machine": own,
                       "low": min([*values.values(), own]), "high": max([*values.values(), own])}
        print(f"   {case}: " + ", ".join(f"{k} {v * scale:.2f}" for k, v in values.items())
              + f"; this machine's own {own * scale:.2f}")
    RESULTS["spread"] = found
    RESULTS["spread_json"] = json.dumps(found, indent=1) + "\n"


def _start(args, folder, log):
    return subprocess.Popen(args, cwd=folder, stdout=log, stderr=subprocess.STDOUT)


def cluster() -> None:
    import distributed

    model = ts.load_model("builtin:squat-jump")
    problem = OptimiseProblem(model, goals_of(model, maximise="jump_height"))
    rng = np.random.default_rng(0)
    low, high = np.array(problem.space.lower), np.array(problem.space.upper)
    rows = np.array([problem.space.full(rng.uniform(low, high)[problem.space.free], problem.x0)
                     for _ in range(96)])
    from torquesim.optimisation.distributed import DaskScorer

    print("3. real Dask cluster (scheduler and workers: separate processes and folders)")
    with tempfile.TemporaryDirectory() as root:
        root = Path(root)
        folders = {name: root / name for name in ("scheduler", "worker-1", "worker-2")}
        for folder in folders.values():
            folder.mkdir()
        file = folders["scheduler"] / "scheduler.json"
        log = open(root / "cluster.log", "w")  # noqa: SIM115 - closed below
        procs = [_start(["dask", "scheduler", "--scheduler-file", str(file), "--port", "0",
                         "--no-dashboard"], folders["scheduler"], log)]
        try:
            while not file.exists():
                time.sleep(0.2)
            worker = ["dask", "worker", "--scheduler-file", str(file), "--nthreads", "1",
                      "--no-dashboard"]
            procs.append(_start(worker + ["--name", "w1"], folders["worker-1"], log))
            with distributed.Client(scheduler_file=str(file)) as client:
                client.wait_for_workers(1)
                one = DaskScorer(client, problem)
                one(rows[:4])  # warm: the worker loads the compiled kernels
                rates = {1: [], 2: []}
                procs.append(_start(worker + ["--name", "w2"], folders["worker-2"], log))
                for _repeat in range(3):
                    for n in (1, 2):
                        client.wait_for_workers(2)
                        scorer = DaskScorer(client, problem)
                        scorer.workers = n  # n chunks: one worker busy, or both
                        if _repeat == 0 and n == 2:
                            scorer(rows[:4])
                        start = time.perf_counter()
                        scorer(rows)
                        rates[n].append(len(rows) / (time.perf_counter() - start))
                best = {n: max(r) for n, r in rates.items()}
                print(f"   simulations per second: 1 worker {best[1]:.1f}, 2 workers "
                      f"{best[2]:.1f}; ratio {best[2] / best[1]:.2f} (target ≥ 1.7 idle)")
                settings = OptimiseSettings(generations=8)
                there = ts.optimise(model, maximise="jump_height", settings=settings,
                                    client=client)
            here = ts.optimise(model, maximise="jump_height", settings=settings)
            same = bool(np.array_equal(there.outcome.x, here.outcome.x))
            print(f"   8 generations on the cluster and in this process: same optimum {same}")
            RESULTS["cluster"] = (best, same)
        finally:
            for p in reversed(procs):
                p.terminate()
                p.wait(timeout=30)
            log.close()


def docs_block(load: float) -> str:
    lines = [f"Measured by `python benchmarks/bench_optimise.py --write-docs` "
             f"({measured_on(load)}; {numba.config.NUMBA_NUM_THREADS} Numba threads, "
             "compilation excluded). Goal values are the start and optimum re-simulated with "
             "the reference solver (Radau). Wall time: the search's, CMA-ES and its "
             "simulations (the command's `wall time` line), and in brackets the whole "
             "call's, also the choice of technique, the reference runs and the parameters' "
             "effects.", ""]
    spread = RESULTS.get("spread", {})

    def across(case: str, scale: float, unit: str) -> str:
        if case not in spread:
            return ""
        return (f" ({spread[case]['low'] * scale:.{1 if unit == 'ms' else 2}f}–"
                f"{spread[case]['high'] * scale:.{1 if unit == 'ms' else 2}f} {unit} across "
                "BLAS kernels)")

    if "curl" in RESULTS:
        goal, sims, search, wall = RESULTS["curl"]
        lines += ["| optimisation | technique (chosen) | start | optimum | gain | simulations "
                  "| wall (warm) |", "|---|---|---|---|---|---|---|",
                  f"| `builtin:elbow-curl`, minimise `time_to:elbow=90deg` | "
                  f"{_technique(goal['_method'], goal['_step'])} | "
                  f"{goal['reference_start'] * 1e3:.1f} ms | "
                  f"{goal['reference_optimum'] * 1e3:.1f} ms{across('curl', 1e3, 'ms')} | "
                  f"{goal['reference_gain_percent']:.1f} % faster | {sims} | "
                  f"**{search:.2f} s** ({wall:.2f} s) |"]
    if "jump" in RESULTS:
        rows, copies, copied_with = RESULTS["jump"]
        for label, (best, search, wall) in rows.items():
            goal = best.summary["goals"][0]
            what = ("maximise `jump_height`" if label == "plain" else
                    "maximise `jump_height --robust 10` (±10 ms)")
            spread_text = across("jump", 1e2, "cm") if label == "plain" else ""
            lines.append(f"| `builtin:squat-jump`, {what} | "
                         f"{_technique(best.summary['method'], best.summary['step_s'])} | "
                         f"{goal['reference_start'] * 100:.2f} cm | "
                         f"{goal['reference_optimum'] * 100:.2f} cm{spread_text} | "
                         f"+{goal['reference_gain_percent']:.1f} % | "
                         f"{best.outcome.simulations} | {search:.1f} s ({wall:.1f} s) |")
        lines += ["", "Each jump under the same 10 copies with random onset errors in ±10 ms on "
                  f"every ramp ({copied_with}): the lowest jump among the copies that run, "
                  "and the copies that fail:", "",
                  "| jump | lowest jump height | failed copies |", "|---|---|---|"]
        for label, (low, failed, reasons) in copies.items():
            why = f" ({'; '.join(reasons)})" if failed else ""
            lines.append(f"| {label} | {low * 100:.2f} cm | {failed} of 10{why} |")
    if spread:
        lines += ["", "A same-seed optimum is the same run to run but moves with the machine: "
                  "CMA-ES draws its candidates through an eigendecomposition of its covariance "
                  "(LAPACK in OpenBLAS), whose last bits depend on the kernels OpenBLAS picks "
                  "for the CPU, and the search amplifies them. The ranges above are the same "
                  "optimisations with each kernel set this CPU runs ("
                  + ", ".join(spread["curl"]["by_kernel_set"]) + "; `OPENBLAS_CORETYPE`); "
                  "`scripts/make_docs.py --check` holds a regenerated optimum to them."]
    if "cluster" in RESULTS:
        best, same = RESULTS["cluster"]
        lines += ["", "On a real Dask cluster (`dask scheduler` and `dask worker` processes "
                  "in separate folders, 1 thread each), the same 96 squat-jump candidates "
                  "(minimum of 3 interleaved repeats):", "",
                  "| 1 worker | 2 workers | ratio | same optimum as in-process (8 generations) "
                  "|", "|---|---|---|---|",
                  f"| {best[1]:.1f} simulations/s | {best[2]:.1f} simulations/s | "
                  f"**{best[2] / best[1]:.2f}×** | {'yes' if same else 'no'} |"]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip", default="",
                        help="comma-separated: curl, jump, cluster, spread")
    parser.add_argument("--write-docs", action="store_true",
                        help="write the results into docs/optimise.md")
    parser.add_argument("--figures", action="store_true",
                        help="write the curl's and the jump's figures into docs/figures/")
    args = parser.parse_args()
    skip = set(args.skip.split(","))
    load = os.getloadavg()[0]
    print(f"cores: {os.cpu_count()}; numba threads: {numba.config.NUMBA_NUM_THREADS}; "
          f"load average at start: {load:.2f}")
    if "cluster" not in skip:
        cluster()
    if "curl" not in skip:
        curl()
    if "jump" not in skip:
        jump()
    if "spread" not in skip:
        spread()
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    if args.figures:
        figures()
    if args.write_docs:
        write_blocks("docs/optimise.md", {"optimise-benchmark": docs_block(load)})
        if "spread_json" in RESULTS:
            SPREAD_FILE.parent.mkdir(parents=True, exist_ok=True)
            SPREAD_FILE.write_text(RESULTS["spread_json"])


if __name__ == "__main__":
    main()
