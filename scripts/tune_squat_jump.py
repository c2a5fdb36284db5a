"""How the squat-jump preset's activation timings were chosen (docs/presets.md).

    python scripts/tune_squat_jump.py [--generations 120] [--seed 1]

CMA-ES (the ``cmaes`` package) over 15 timings and levels of the preset's profiles: each
extensor's onset and hold (plantarflexors, knee and hip extensors; a shared 50 ms rise, the
fall fixed at 50 ms) and each antagonist's brace for the flight (onset, level, hold;
dorsiflexors onset and level). Each candidate is the preset with those profiles, simulated by
IMEX at 0.25 ms; the score is

    100·(h − 0.285)² + 100·max(|v_x| − 0.04, 0)² + 100·max(s − 0.05, 0)²
    + 1000·max(0.135 ms − τ_c, 0)² (+1 if it lands within the run)

with h the flight v²/2g (m), v_x the forward speed at take-off (m/s), s the largest end-stop
torque as a share of its joint's peak muscle torque, τ_c the contacts' smallest time constant
(kept so that 0.25 ms stays within 0.7 of RK4's limit). The preset holds the best candidate
of such searches rounded to 5 ms and 0.01 (it starts from the preset's own values, so a run
now shows where they sit); its motion is in docs/presets.md (``make_docs.py --presets``).
Takes about a minute on 2 cores.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

import torquesim as ts
from torquesim.model.activation import ActivationProfile, Ramp

NAMES = ("ankle_on", "knee_on", "hip_on", "rise", "knee_hold", "hip_hold", "ankle_hold",
         "knee_brace_on", "knee_brace", "knee_brace_hold", "hip_brace_on", "hip_brace",
         "hip_brace_hold", "ankle_brace_on", "ankle_brace")
START = (0.125, 0.045, 0.03, 0.05, 0.13, 0.15, 0.06, 0.23, 0.44, 0.085, 0.235, 0.31, 0.11,
         0.235, 0.32)
LOW = (0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0, 0.15, 0.1, 0.03, 0.15, 0.1, 0.03, 0.15, 0.1)
HIGH = (0.2, 0.2, 0.2, 0.25, 0.3, 0.3, 0.3, 0.45, 1.0, 0.3, 0.45, 1.0, 0.3, 0.45, 1.0)
FALL = 0.05


def candidate(x) -> ts.ChainModel:
    """The preset with the profiles of parameter vector ``x`` (`NAMES`)."""
    p = dict(zip(NAMES, np.clip(x, LOW, HIGH), strict=True))

    def push(on, hold):
        return ActivationProfile(None, (Ramp(on, p["rise"], 1.0), Ramp(hold, FALL, 0.05)))

    def brace(on, level, hold=None):
        ramps = (Ramp(on, 0.05, level),) + (() if hold is None else (Ramp(hold, 0.05, 0.1),))
        return ActivationProfile(0.1, ramps)

    profiles = {
        "plantarflexors": push(p["ankle_on"], p["ankle_hold"]),
        "knee_extensors": push(p["knee_on"], p["knee_hold"]),
        "hip_extensors": push(p["hip_on"], p["hip_hold"]),
        "knee_flexors": brace(p["knee_brace_on"], p["knee_brace"], p["knee_brace_hold"]),
        "hip_flexors": brace(p["hip_brace_on"], p["hip_brace"], p["hip_brace_hold"]),
        "dorsiflexors": brace(p["ankle_brace_on"], p["ankle_brace"]),
    }
    model = ts.load_model("builtin:squat-jump")
    return model.replace(units=tuple(replace(u, activation=profiles[u.name])
                                     for u in model.units))


def measure(model) -> dict | None:
    """Take-off (s), flight (m), forward speed at take-off (m/s), largest end-stop share,
    the centre of mass's drop before take-off (m), landing, the contacts' smallest time
    constant (ms); None without a take-off. (scripts/tune_countermovement_jump.py uses it
    too.)"""
    run = ts.simulate(model, "imex", 2.5e-4, check=False, advise=False, tolerance=None)
    events = run.ground_events()
    if events is None or events.take_off is None:
        return None
    c = run.columns()
    i = int(np.searchsorted(run.time, events.take_off))
    share = max(np.abs(c[f"torque_passive_{j.name}"]).max()
                / np.abs(c[f"torque_net_{j.name}"]).max() for j in model.joints[1:])
    return {"take_off_s": events.take_off, "flight_m": events.flight_height,
            "vx_m_s": float(c["com_speed_x"][i]), "end_stop_share": float(share),
            "drop_m": float(c["com_y"][0] - c["com_y"][:i].min()), "landing": events.landing,
            "contact_tau_ms": 1e3 * run.settings.get("contact_time_constant_min_s", 1.0)}


def score(x) -> float:
    try:
        m = measure(candidate(x))
    except ts.ModelError:
        return 1e3
    if m is None or not np.isfinite(m["flight_m"]):
        return 1e3
    return (100 * (m["flight_m"] - 0.285) ** 2 + 100 * max(abs(m["vx_m_s"]) - 0.04, 0) ** 2
            + 100 * max(m["end_stop_share"] - 0.05, 0) ** 2
            + 1e3 * max(0.135 - m["contact_tau_ms"], 0) ** 2 + (m["landing"] is not None))


def main() -> None:
    import cmaes

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=120)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    search = cmaes.CMA(mean=np.array(START), sigma=0.02, bounds=np.array([LOW, HIGH]).T,
                       seed=args.seed, population_size=12)
    best = (np.array(START), score(START))
    print(f"start: score {best[1]:.4g}, {measure(candidate(START))}")
    for generation in range(args.generations):
        told = []
        for _ in range(search.population_size):
            x = search.ask()
            told.append((x, score(x)))
            best = min(best, told[-1], key=lambda b: b[1])
        search.tell(told)
        if generation % 20 == 0:
            print(f"generation {generation}: best score {best[1]:.4g}")
    print("best:", {k: round(float(v), 3) for k, v in zip(NAMES, best[0], strict=True)})
    print(measure(candidate(best[0])))


if __name__ == "__main__":
    main()
