"""The cost of ``torquesim strength`` on one joint's trials (issue 31: ≤ 10 s warm for 10–20
trials): the shipped knee-extensor examples (11 trials and a passive one, 100 Hz), and the
same subject's 20 trials at 1 kHz (made by the model, 2 N·m noise).

    python benchmarks/bench_strength.py [--repeats 3]

Each case is fitted once to compile and warm up, then ``--repeats`` times in process; the
minimum wall time (load only adds time) is printed beside the work counted (residual
evaluations, samples) and the load average, with the RMS difference and T0 so that a faster
fit that fits worse shows. Work counts do not depend on load; times do (2–10× on a shared
machine).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _cases():
    import torquesim as ts
    from torquesim.fitting.dynamometer import simulate_passive_trial, simulate_trial
    from torquesim.fitting.strength import PassiveTorque
    from torquesim.io.dynamometer import read_trial

    sys.path.insert(0, str(ROOT / "examples"))
    import make_examples

    folder = ROOT / "examples" / "dynamometer"
    unit = ts.load_model("builtin:knee-extension").units[0]
    shipped = [read_trial(p) for p in sorted(folder.glob("*_*.csv"))]
    passive = PassiveTorque.from_trial(read_trial(folder / "passive.csv"))
    subject = replace(unit.parameters, **make_examples.SUBJECT)
    gravity = PassiveTorque.given(*make_examples.GRAVITY[:1], 0.0)
    rad = math.radians
    plan = ([(a, a, 0) for a in (20, 30, 40, 50, 60, 70, 80, 90)]
            + [(100, 15, s) for s in (30, 60, 120, 180, 240, 300)]
            + [(15, 100, s) for s in (15, 30, 60, 90, 120, 150)])
    many = [simulate_trial(f"t{i}", subject, -1, rad(a), rad(b), rad(s), rate=1000.0,
                           noise=2.0, passive=gravity, seed=i)
            for i, (a, b, s) in enumerate(plan)]
    many_passive = PassiveTorque.from_trial(simulate_passive_trial(
        "p", rad(10), rad(110), gravity, rate=1000.0, noise=0.5, seed=99))
    return unit, {"shipped examples (11 trials, 100 Hz)": (shipped, passive),
                  "20 trials at 1 kHz": (many, many_passive)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    from torquesim.fitting.strength import StrengthSettings, fit_strength

    unit, cases = _cases()
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at start")
    for name, (trials, passive) in cases.items():
        fit_strength(trials, unit.parameters, unit.direction, StrengthSettings(), passive)
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            fit = fit_strength(trials, unit.parameters, unit.direction, StrengthSettings(),
                               passive)
            times.append(time.perf_counter() - start)
        print(f"{name}: {min(times):.2f} s warm (min of {args.repeats}), "
              f"{fit.evaluations} evaluations of {fit.fitted.size} samples, RMS "
              f"{fit.rms:.3g} N·m, T0 {fit.parameters.isometric_torque:.1f} N·m")
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
