"""Cold start: the first `torquesim simulate` and the first `torquesim fit` with Numba's cache
empty (each in a fresh temporary cache folder, NUMBA_CACHE_DIR), then the same commands warm.

    python benchmarks/bench_cold_start.py
    python benchmarks/bench_cold_start.py --baseline /path/to/older/checkout/src

Prints each command's wall time (whole process: interpreter, imports, compilation, the run)
and the load average before and after. Compilation is most of a cold start; the numbers move
with the machine's load, so compare them only within one run. With ``--baseline``, the same
commands also run on another source tree (put first on PYTHONPATH; e.g. a ``git worktree`` of
an older commit), alternating with this one, and the ratio this/baseline is printed.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

COMMANDS = {
    "simulate (monolithic, default curl)": ["simulate"],
    "simulate --method imex": ["simulate", "--method", "imex", "--step", "1ms"],
    "fit (builtin:curl)": ["fit", "--quiet", "--overwrite", "--out", "{tmp}/fit"],
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="source folder of the code to compare with")
    baseline = parser.parse_args().baseline
    print(f"cores: {os.cpu_count()}; load average at start: {os.getloadavg()[0]:.2f}")
    for label, args in COMMANDS.items():
        cold, warm = cold_and_warm(args)
        line = f"{label:40s} cold {cold:6.1f} s   warm {warm:5.1f} s"
        if baseline:
            base_cold, base_warm = cold_and_warm(args, baseline)
            line += (f"   baseline cold {base_cold:6.1f} s   warm {base_warm:5.1f} s"
                     f"   cold ratio {cold / base_cold:.2f}")
        print(line, flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
