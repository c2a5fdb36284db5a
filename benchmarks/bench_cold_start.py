"""Cold start: the first `torquesim simulate` and the first `torquesim fit` with Numba's cache
empty (each in a fresh temporary cache folder, NUMBA_CACHE_DIR), then the same commands warm.

    python benchmarks/bench_cold_start.py

Prints each command's wall time (whole process: interpreter, imports, compilation, the run)
and the load average before and after. Compilation is most of a cold start; the numbers move
with the machine's load, so compare them only within one run.
"""

from __future__ import annotations

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


def run(args, cache: str, tmp: str) -> float:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    argv = [sys.executable, "-m", "torquesim.cli", *(a.format(tmp=tmp) for a in args)]
    start = time.perf_counter()
    subprocess.run(argv, env=env, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    print(f"cores: {os.cpu_count()}; load average at start: {os.getloadavg()[0]:.2f}")
    for label, args in COMMANDS.items():
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as tmp:
            cold = run(args, cache, tmp)
            warm = run(args, cache, tmp)
        print(f"{label:40s} cold {cold:6.1f} s   warm {warm:5.1f} s")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
