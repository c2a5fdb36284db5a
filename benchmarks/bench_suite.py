"""How long the README's test command takes from a cold Numba cache, idle and loaded.

Run:  python benchmarks/bench_suite.py [--hogs 2] [--write-docs]
      python benchmarks/bench_suite.py --versus "--dist loadgroup" --rounds 2 [--hogs 2]

Runs ``python -m pytest -q -p no:cacheprovider`` (the README's command; ``pyproject.toml``
makes it two processes with pytest-xdist) in this checkout with an empty Numba cache
(``NUMBA_CACHE_DIR`` a new temporary folder: every kernel compiles, as on a fresh install).
``--hogs N`` first starts N processes that spin on the CPU, so that the machine is loaded as
a shared CI machine is (the 1-minute load average, sampled every 15 s, is printed; on 2 cores
two hogs give about 4). Prints the wall time, the tests passed and the load. With
``--write-docs`` the figure goes into the ``test-suite`` blocks of README.md and
docs/index.md, with the date, cores and load beside it (idle and loaded runs each keep
their own line: run once without and once with ``--hogs``).

``--versus ARGS`` measures a change against a baseline in the same run: the suite with the
pytest arguments ARGS added (the baseline) and as the README runs it, alternately, for
``--rounds`` rounds; it prints each run's wall time and the CPU time of the suite's
processes, then the ratios of the minima (new / baseline). The CPU time counts the work
done (compiling, running), which the machine's load moves far less than the wall time.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import re
import resource
import shlex
import subprocess
import sys
import tempfile
import threading
import time
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
from docblocks import current_block, write_blocks  # noqa: E402

#: Where the last runs are remembered between an idle and a loaded run (in the repository,
#: so the block is regenerated from both).
RECORD = ROOT / "docs" / "data" / "test_suite.txt"


def spin(stop) -> None:
    while not stop.is_set():
        pass


def children_cpu() -> float:
    """User + system CPU time (s) of the waited-for child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_suite(hogs: int, extra: tuple[str, ...] = ()) -> dict:
    stop = multiprocessing.Event()
    spinners = [multiprocessing.Process(target=spin, args=(stop,), daemon=True)
                for _ in range(hogs)]
    for p in spinners:
        p.start()
    loads, done = [], threading.Event()

    def sample() -> None:
        while not done.wait(15.0):
            loads.append(os.getloadavg()[0])

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    with tempfile.TemporaryDirectory(prefix="numba-cold-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        start, cpu = time.perf_counter(), children_cpu()
        finished = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p",
                                   "no:cacheprovider", *extra], cwd=ROOT, env=env,
                                  capture_output=True, text=True)
        wall, cpu = time.perf_counter() - start, children_cpu() - cpu
    done.set()
    stop.set()
    for p in spinners:
        p.join()
    lines = finished.stdout.strip().splitlines()
    tail = lines[-1] if lines else ""
    for line in lines:
        if line.startswith(("FAILED", "ERROR")):
            print(line)
    passed = re.search(r"(\d+) passed", tail)
    return {"wall": wall, "cpu": cpu, "code": finished.returncode, "summary": tail,
            "passed": int(passed.group(1)) if passed else 0, "hogs": hogs,
            "load": (min(loads), sum(loads) / len(loads), max(loads)) if loads else (0, 0, 0)}


def describe(r: dict) -> str:
    minutes, seconds = divmod(round(r["wall"]), 60)
    low, mean, high = r["load"]
    what = ("with nothing else running" if r["hogs"] == 0 else
            f"beside {r['hogs']} processes spinning on the CPU")
    return (f"{minutes} min {seconds:02d} s from an empty Numba cache, {r['passed']} tests, "
            f"{what} (1-minute load average {low:.1f}–{high:.1f}, mean {mean:.1f}); "
            f"{datetime.now(UTC):%Y-%m-%d}, {os.cpu_count()} cores")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hogs", type=int, default=0)
    parser.add_argument("--write-docs", action="store_true")
    parser.add_argument("--versus", metavar="ARGS",
                        help="pytest arguments of a baseline run, compared in the same run")
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()
    if args.versus is not None:
        compare(args.hogs, tuple(shlex.split(args.versus)), args.rounds)
        return
    result = run_suite(args.hogs)
    line = describe(result)
    print(result["summary"])
    print(line)
    if result["code"] != 0:
        sys.exit(f"the suite failed (exit {result['code']}): nothing written")
    if args.write_docs:
        kept = {}
        if RECORD.exists():
            for row in RECORD.read_text().splitlines():
                key, _, text = row.partition("\t")
                kept[key] = text
        kept["loaded" if args.hogs else "idle"] = line
        RECORD.parent.mkdir(parents=True, exist_ok=True)
        RECORD.write_text("".join(f"{k}\t{v}\n" for k, v in sorted(kept.items())))
        write_docs(kept)


def compare(hogs: int, baseline: tuple[str, ...], rounds: int) -> None:
    """The suite with the ``baseline`` pytest arguments and as the README runs it,
    alternately (the baseline first in odd rounds), and the ratios of their minima."""
    runs = {"baseline": [], "new": []}
    for r in range(rounds):
        order = ("baseline", "new") if r % 2 == 0 else ("new", "baseline")
        for name in order:
            result = run_suite(hogs, baseline if name == "baseline" else ())
            runs[name].append(result)
            low, mean, high = result["load"]
            print(f"round {r + 1} {name:8s} wall {result['wall']:6.1f} s  CPU "
                  f"{result['cpu']:6.1f} s  load {mean:.1f}  {result['summary']}", flush=True)
    for what in ("wall", "cpu"):
        base = min(x[what] for x in runs["baseline"])
        new = min(x[what] for x in runs["new"])
        print(f"{what}: baseline min {base:.1f} s, new min {new:.1f} s, new/baseline "
              f"{new / base:.3f}")


def write_docs(kept: dict) -> None:
    """Write the recorded runs into the ``test-suite`` blocks of README.md and docs/index.md
    (a list, so a blank line before it: Markdown runs a list on from a paragraph's line into
    that paragraph)."""
    body = ("Measured by `python benchmarks/bench_suite.py --write-docs` (and `--hogs 2`): "
            "`python -m pytest` took\n\n"
            + "".join(f"- {kept[k]}\n" for k in ("idle", "loaded") if k in kept))
    for page in ("README.md", "docs/index.md"):
        if current_block(page, "test-suite") != body:
            write_blocks(page, {"test-suite": body})


if __name__ == "__main__":
    main()
