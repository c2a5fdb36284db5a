"""Cold start: the first `torquesim simulate` (the elbow, and the squat jump: a chain on the
ground) and the first `torquesim fit` with Numba's cache empty (each in a fresh temporary
cache folder, NUMBA_CACHE_DIR), then the same commands warm.

    python benchmarks/bench_cold_start.py
    python benchmarks/bench_cold_start.py --baseline /path/to/older/checkout/src --repeats 3
    python benchmarks/bench_cold_start.py --repeats 2 --write-docs

Prints each command's wall time (whole process: interpreter, imports, compilation, the run)
and the load average before and after. Compilation is most of a cold start; the numbers move
with the machine's load, so compare them only within one run. With ``--baseline``, the same
commands also run on another source tree (put first on PYTHONPATH; e.g. a ``git worktree`` of
an older commit), alternating with this one, and the ratio this/baseline is printed. With
``--repeats N`` every measurement is repeated N times, the trees interleaved, and the minimum
kept (load only ever adds time). ``--loop-only`` adds, for the default simulate, its time
with every compiled function cached but the step loop, which the first run of a model and
method compiles in any case. ``--write-docs`` writes this tree's table (not the
baseline's) into the generated block ``cold-start`` of docs/tutorial.md
(`scripts/docblocks.py`).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from docblocks import measured_on, write_blocks  # noqa: E402

COMMANDS = {
    "`torquesim simulate` (the default curl, monolithic)": ["simulate"],
    "`torquesim simulate --method imex --step 1ms`": ["simulate", "--method", "imex", "--step",
                                                      "1ms"],
    "`torquesim simulate` (the squat jump, IMEX at 0.25 ms)":
        ["simulate", "--model", "builtin:squat-jump", "--method", "imex", "--step", "0.25ms"],
    "`torquesim fit` (builtin:curl)": ["fit", "--quiet", "--overwrite", "--out", "{tmp}/fit"],
}


def run(args, cache: str, tmp: str, src: str | None = None) -> float:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    if src:
        env["PYTHONPATH"] = src
    argv = [sys.executable, "-m", "torquesim.cli", *(a.format(tmp=tmp) for a in args)]
    start = time.perf_counter()
    subprocess.run(argv, env=env, check=True, capture_output=True)
    return time.perf_counter() - start


def cold_and_warm(args, src=None) -> tuple[float, float]:
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as tmp:
        return run(args, cache, tmp, src), run(args, cache, tmp, src)


def loop_only(args) -> float:
    """The command with every compiled function cached but the step loop (`rk4_monolithic`,
    whose cache files are deleted after a first run): the least a cold start can cost while
    the loop is compiled at the first run, whatever else is cut."""
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as tmp:
        run(args, cache, tmp)
        for path in Path(cache).rglob("*rk4_monolithic*"):
            path.unlink()
        return run(args, cache, tmp)


def docs_block(rows, load: float, repeats: int) -> str:
    """The measured table of this tree as the generated block ``cold-start`` (a comparison
    with ``--baseline`` is printed, not written: the page describes this version)."""
    lines = [f"Measured by `python benchmarks/bench_cold_start.py --repeats {repeats} "
             f"--write-docs` ({measured_on(load)}; the whole command, interpreter and imports "
             f"included; the fastest of {repeats} interleaved repeats):", "",
             "| first run | cold (empty Numba cache) | warm |", "|---|---|---|"]
    for name, cold, warm, _ in rows:
        lines.append(f"| {name} | {cold:.1f} s | {warm:.1f} s |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="source folder of the code to compare with")
    parser.add_argument("--repeats", type=int, default=1,
                        help="interleaved repeats per measurement; the minimum is kept")
    parser.add_argument("--loop-only", action="store_true",
                        help="also time the default simulate with only its step loop to "
                             "compile (every other function cached)")
    parser.add_argument("--write-docs", action="store_true",
                        help="write the table into docs/tutorial.md (block cold-start)")
    options = parser.parse_args()
    baseline, repeats = options.baseline, max(1, options.repeats)
    load = os.getloadavg()[0]
    print(f"cores: {os.cpu_count()}; load average at start: {load:.2f}")
    rows = []
    for name, args in COMMANDS.items():
        cold, warm, base_cold = [], [], []
        for _ in range(repeats):
            c, w = cold_and_warm(args)
            cold.append(c)
            warm.append(w)
            if baseline:
                base_cold.append(cold_and_warm(args, baseline)[0])
        line = f"{name:55s} cold {min(cold):6.1f} s   warm {min(warm):5.1f} s"
        if baseline:
            line += (f"   baseline cold {min(base_cold):6.1f} s"
                     f"   cold ratio {min(cold) / min(base_cold):.2f}")
        if options.loop_only and args == ["simulate"]:
            line += f"   loop only {min(loop_only(args) for _ in range(repeats)):5.1f} s"
        print(line, flush=True)
        rows.append((name, min(cold), min(warm), min(base_cold) if baseline else None))
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    if options.write_docs:
        write_blocks("docs/tutorial.md",
                     {"cold-start": docs_block(rows, load, repeats)})


if __name__ == "__main__":
    main()
