"""Batch benchmarks of the Dask issue, measured in one run on local clusters.

Run:  python benchmarks/bench_batch.py [--fits 8] [--samples 10000] [--skip fits,sweep]
          [--write-docs]

Prints, for a LocalCluster of 1 and of 2 worker processes (one thread each), started and
warmed up (kernels loaded, one task run) before any timing:

1. 8 elbow fits (min-jerk curls with peaks 100°–135°, default least-squares fit, IMEX 5 ms):
   wall time per cluster and the speed-up (target: 2 workers ≥ 1.7× one worker).
2. A sweep of the elbow curl over the flexor SE stiffness and the dumbbell mass (IMEX 5 ms,
   chunks of 1000): simulations per second per worker and per minute in all, the speed-up
   (targets: ≥ 1.6× and ≥ 50 000 simulations per minute on 2 workers), and the per-task
   overhead: the cluster's time per chunk minus the same chunk's time in this process, as a
   fraction of the latter (target < 5 %), and the round trip of an empty task.
3. The whole command, as a user runs it: ``torquesim batch sweep --samples 5000`` with
   ``--workers 1`` and ``--workers 2`` (cluster start-up, automatic chunks, writing the
   outputs included), interleaved, minimum of 4 runs each (target: 2 workers ≥ 1.6× one on an
   idle machine), and a 10-sample sweep (in process: no cluster started).

With ``--write-docs`` the results go into the ``batch-benchmark`` block of docs/batch.md
(with the date and load).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from distributed import Client, LocalCluster

import torquesim as ts
from torquesim.batch import fit_many, sweep
from torquesim.batch.sweep import parse_vary, sample_matrix, simulate_chunk

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from docblocks import measured_on, write_blocks  # noqa: E402

#: What each part measured, for docs/batch.md.
RESULTS: dict[str, dict] = {}
#: Interleaved repeats of each whole command; the minimum is reported.
REPEATS = 4
VARY = ["elbow_flexor.se_stiffness=normal(600,60)", "forearm_hand.dumbbell.mass=uniform(4,6)"]


def curl_targets(folder: Path, count: int) -> list[str]:
    paths = []
    t = np.arange(0.0, 3.0001, 0.01)
    for k, peak in enumerate(np.linspace(100.0, 135.0, count)):
        s = np.where(t <= 1.5, t / 1.5, (3.0 - t) / 1.5)
        angle = 10.0 + (peak - 10.0) * s**3 * (10 - 15 * s + 6 * s**2)
        path = folder / f"curl_{k}.csv"
        path.write_text("time,elbow\n" + "".join(f"{a:.2f},{b:.10g}\n" for a, b in zip(t, angle,
                                                                                  strict=True)))
        paths.append(str(path))
    return paths


def noop() -> None:
    return None


def warm(client: Client) -> None:
    """Load the kernels in every worker (the Numba cache) before timing."""
    model = ts.load_model("builtin:elbow-curl")
    values = np.full((2, 1), 600.0)
    futures = [client.submit(simulate_chunk, model, ["elbow_flexor.se_stiffness"], values,
                             "imex", 5e-3, pure=False, workers=[w])
               for w in client.scheduler_info()["workers"]]
    client.gather(futures)


def bench_fits(clients: dict, count: int) -> None:
    print(f"1. {count} elbow fits (default least squares, IMEX 5 ms)")
    with tempfile.TemporaryDirectory() as tmp:
        targets = curl_targets(Path(tmp), count)
        walls = {}
        for n, client in clients.items():
            start = time.perf_counter()
            table = fit_many(targets, out=Path(tmp) / f"out{n}", client=client)
            walls[n] = time.perf_counter() - start
            print(f"   {n} worker(s): {walls[n]:.1f} s; {int((table.status == 'done').sum())} "
                  f"done; reference RMS {table.reference_rms_deg.min():.3f}–"
                  f"{table.reference_rms_deg.max():.3f} deg")
        if len(walls) == 2:
            ratio = walls[1] / walls[2]
            print(f"   speed-up 2 vs 1 worker: {ratio:.2f}x (target ≥ 1.7: {ratio >= 1.7})")
            RESULTS["fits"] = {"count": count, "walls": walls, "ratio": ratio}


def bench_sweep(clients: dict, samples: int) -> None:
    print(f"2. sweep: {samples} elbow simulations (IMEX 5 ms), chunks of 1000")
    model = ts.load_model("builtin:elbow-curl")
    values = sample_matrix([parse_vary(v) for v in VARY], 1000, seed=1)
    start = time.perf_counter()
    simulate_chunk(model, [v.split("=")[0] for v in VARY], values, "imex", 5e-3)
    in_process = time.perf_counter() - start
    print(f"   one chunk of 1000 in this process: {in_process:.2f} s "
          f"({1000 / in_process:.0f} simulations/s)")
    rates = {}
    for n, client in clients.items():
        start = time.perf_counter()
        table, _ = sweep(model, VARY, samples=samples, method="imex", step=5e-3, chunk=1000,
                         client=client)
        wall = time.perf_counter() - start
        rates[n] = samples / wall
        tasks = samples / 1000
        overhead = (wall * n / tasks - in_process) / in_process
        print(f"   {n} worker(s): {wall:.1f} s, {rates[n]:.0f} simulations/s "
              f"({rates[n] / n:.0f} per worker, {60 * rates[n]:.0f} per minute); "
              f"{int((table.accuracy == 'ok').sum())} ok; time per chunk vs in-process "
              f"{overhead * 100:+.1f} %")
        trips = []
        for _ in range(20):
            t0 = time.perf_counter()
            client.submit(noop, pure=False).result()
            trips.append(time.perf_counter() - t0)
        trip = statistics.median(trips)
        print(f"   empty task round trip: {trip * 1e3:.1f} ms "
              f"({trip / in_process * 100:.2f} % of a chunk's work)")
        RESULTS.setdefault("sweep", {"samples": samples, "in_process": in_process})[n] = {
            "rate": rates[n], "ok": int((table.accuracy == "ok").sum()),
            "overhead": overhead, "trip": trip}
    if len(rates) == 2:
        ratio = rates[2] / rates[1]
        print(f"   speed-up 2 vs 1 worker: {ratio:.2f}x (target ≥ 1.6: {ratio >= 1.6}); "
              f"{60 * rates[2]:.0f} per minute on 2 workers (target ≥ 50 000: "
              f"{60 * rates[2] >= 50_000})")


def bench_command(samples: int) -> None:
    import subprocess
    import sys

    print(f"3. the whole command: torquesim batch sweep --samples {samples}")
    vary = [a for v in VARY for a in ("--vary", v)]
    best: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(REPEATS):
            for label, extra in (("1 worker", ["--workers", "1"]),
                                 ("2 workers", ["--workers", "2"]),
                                 ("10 samples, in process", [])):
                n = 10 if not extra else samples
                argv = [sys.executable, "-m", "torquesim.cli", "batch", "sweep", *vary,
                        "--samples", str(n), "--quiet", "--accept-inaccurate",
                        "--out", str(Path(tmp) / f"{label}-{repeat}"), *extra]
                start = time.perf_counter()
                subprocess.run(argv, check=True, capture_output=True)
                best[label] = min(best.get(label, float("inf")), time.perf_counter() - start)
    for label, wall in best.items():
        print(f"   {label}: {wall:.1f} s (minimum of {REPEATS}, interleaved)")
    ratio = best["1 worker"] / best["2 workers"]
    print(f"   speed-up 2 vs 1 worker, whole command: {ratio:.2f}x (target ≥ 1.6 on an idle "
          f"machine: {ratio >= 1.6})")
    RESULTS["command"] = {"samples": samples, "best": best, "ratio": ratio}


def docs_block(load: float) -> str:
    """The measured figures as a table for docs/batch.md."""
    lines = [f"Measured by `python benchmarks/bench_batch.py --write-docs` ({measured_on(load)};",
             "local clusters of worker processes with one thread each, warmed up before "
             "timing).", "", "| run | 1 worker | 2 workers | speed-up |", "|---|---|---|---|"]
    fits = RESULTS.get("fits")
    if fits:
        lines.append(f"| {fits['count']} elbow fits (least squares, IMEX 5 ms) | "
                     f"{fits['walls'][1]:.1f} s | {fits['walls'][2]:.1f} s | "
                     f"**{fits['ratio']:.2f}×** |")
    sw = RESULTS.get("sweep")
    if sw and 1 in sw and 2 in sw:
        lines.append(f"| sweep of {sw['samples']} curls (IMEX 5 ms, chunks of 1000) | "
                     f"{sw[1]['rate']:.0f} simulations/s | {sw[2]['rate']:.0f}/s "
                     f"({60 * sw[2]['rate']:.0f} per minute) | "
                     f"**{sw[2]['rate'] / sw[1]['rate']:.2f}×** |")
    cmd = RESULTS.get("command")
    if cmd:
        lines.append(f"| whole command `torquesim batch sweep --samples {cmd['samples']}` "
                     f"(minimum of {REPEATS} interleaved runs) | {cmd['best']['1 worker']:.1f} s"
                     f" | {cmd['best']['2 workers']:.1f} s | **{cmd['ratio']:.2f}×** |")
    if sw and 2 in sw:
        lines += ["", f"A chunk of 1000 takes {sw['in_process']:.2f} s in the client process; "
                  f"on a worker it takes {sw[2]['overhead'] * 100:+.0f} % of that, and an "
                  f"empty task's round trip is {sw[2]['trip'] * 1e3:.0f} ms "
                  f"({sw[2]['trip'] / sw['in_process'] * 100:.1f} % of a chunk). "
                  f"{sw[2]['ok']} of the {sw['samples']} samples are accurate at IMEX 5 ms; "
                  "the others are marked `inaccurate` (estimated max error above 0.5°)."]
    if cmd:
        lines += ["", f"A 10-sample sweep runs in process (no cluster) in "
                  f"{cmd['best']['10 samples, in process']:.1f} s."]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fits", type=int, default=8)
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--skip", default="", help="comma-separated: fits, sweep, command")
    parser.add_argument("--write-docs", action="store_true",
                        help="write the results into docs/batch.md")
    args = parser.parse_args()
    skip = set(args.skip.split(","))
    load = os.getloadavg()[0]
    print(f"cores: {os.cpu_count()}; load average at start: {load:.2f}")
    if "command" not in skip:
        bench_command(5000)
    clusters = {n: LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                dashboard_address=":0", silence_logs=40) for n in (1, 2)}
    clients = {n: Client(c) for n, c in clusters.items()}
    try:
        for client in clients.values():
            warm(client)
        if "fits" not in skip:
            bench_fits(clients, args.fits)
        if "sweep" not in skip:
            bench_sweep(clients, args.samples)
    finally:
        for n in clients:
            clients[n].close()
            clusters[n].close()
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    if args.write_docs:
        write_blocks("docs/batch.md", {"batch-benchmark": docs_block(load)})


if __name__ == "__main__":
    main()
