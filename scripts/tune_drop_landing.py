"""How the drop-landing preset's activation levels were chosen (docs/presets.md).

    python scripts/tune_drop_landing.py [--generations 100] [--seed 1]

CMA-ES (the ``cmaes`` package, σ 0.08) over 8 levels of the preset's profiles: each
extensor's brace (reached 50 ms after touchdown, held 30 ms) and hold (reached in 100 ms
more, at 180 ms; ramps of 50 ms or more, which a fit and an optimisation take as they are), the
dorsiflexors' level and the knee and hip flexors' shared level (each antagonist from its
standing level, equilibrium, in 50 ms), each within [0.02, 1]. It
starts from a brace of 0.35, holds of 0.15 and 0.12 and antagonists at 0.1. Each candidate
is the preset with those levels, simulated by imex-ros2 at 0.25 ms; the score is

    100·(x_com − x_feet)²/0.01 + (v_x² + v_y²)/0.01 + |q̇|²
    + max(40° − κ, 0)²/10 + max(κ − 55°, 0)²/10 + max(−55° − η, 0)²/10
    + 10·Σ_j s_j + 20·(f_heel + f_toe) + 10·n_air + 0.1·(range of the foot angle, °)

at the end of the run (0.3 s): the centre of mass's distance (m) from the middle of toe and
heel, its velocity (m/s) and the joints' speeds (rad/s); with κ the knee's largest flexion,
η the hip's smallest angle (most flexed), s_j each joint's largest end-stop torque as a
share of its peak net torque, f the share of samples on which a contact carries nothing and
n_air the samples on which the body is off the ground. The preset holds the best candidate
rounded to 0.01; its motion is in docs/presets.md (``make_docs.py --presets``). Takes about
15 s on 2 cores.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

import torquesim as ts
from torquesim.model.presets import landing_activation

EXTENSORS = ("plantarflexors", "knee_extensors", "hip_extensors")
NAMES = ("plantarflexors_brace", "knee_extensors_brace", "hip_extensors_brace",
         "plantarflexors_hold", "knee_extensors_hold", "hip_extensors_hold", "flexors",
         "dorsiflexors")
START = (0.35, 0.35, 0.35, 0.15, 0.12, 0.12, 0.1, 0.1)
LOW, HIGH = 0.02, 1.0


def landing(x) -> ts.ChainModel:
    """The preset with the levels ``x`` (in the order of `NAMES`)."""
    model = ts.load_model("builtin:drop-landing")
    levels = {name: (float(x[k]), float(x[k + 3])) for k, name in enumerate(EXTENSORS)}
    levels |= {"dorsiflexors": (float(x[7]),), "knee_flexors": (float(x[6]),),
               "hip_flexors": (float(x[6]),)}
    return model.replace(units=tuple(replace(u, activation=landing_activation(levels[u.name]))
                                     for u in model.units))


def score(x) -> float:
    if np.any(np.asarray(x) < LOW) or np.any(np.asarray(x) > HIGH):
        return 1e3
    try:
        model = landing(x)
        run = ts.simulate(model, "imex-ros2", 2.5e-4, tolerance=None, check=False,
                          advise=False)
    except ts.ModelError:
        return 1e3
    if not run.success:
        return 1e3
    c = run.columns()
    feet = 0.5 * (c["toe_x"][-1] + c["heel_x"][-1])
    knee = math.degrees(c["knee_angle"].max())
    hip = math.degrees(c["hip_angle"].min())
    total = 100 * (c["com_x"][-1] - feet) ** 2 / 0.01 \
        + (c["com_speed_x"][-1] ** 2 + c["com_speed_y"][-1] ** 2) / 0.01 \
        + float(np.sum(run.states[-1, model.layout.speeds] ** 2))
    total += max(0.0, 40 - knee) ** 2 / 10 + max(0.0, knee - 55) ** 2 / 10 \
        + max(0.0, -55 - hip) ** 2 / 10
    for joint in model.joints[1:]:
        total += 10 * np.abs(c[f"torque_passive_{joint.name}"]).max() \
            / np.abs(c[f"torque_net_{joint.name}"]).max()
    total += 20 * np.mean(c["grf_y_heel"][1:] <= 0) + 20 * np.mean(c["grf_y_toe"][1:] <= 0)
    total += 10 * np.sum(c["grf_y"][1:] <= 0) + 0.1 * np.ptp(np.degrees(c["foot_angle"]))
    return float(total)


def main() -> None:
    from cmaes import CMA

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    start = np.array(START)
    best = (score(start), start)
    print(f"start: score {best[0]:.4g}")
    search = CMA(mean=start, sigma=0.08, seed=args.seed)
    for generation in range(args.generations):
        tried = []
        for _ in range(search.population_size):
            x = search.ask()
            value = score(x)
            tried.append((x, value))
            if value < best[0]:
                best = (value, x)
        search.tell(tried)
        if generation % 10 == 0:
            print(f"generation {generation}: best score {best[0]:.4g}", flush=True)
    print(f"best score {best[0]:.4g}:")
    for name, value in zip(NAMES, best[1], strict=True):
        print(f"  {name} {value:.3f}")
    print(f"rounded to 0.01: score {score(np.round(best[1], 2)):.4g}")


if __name__ == "__main__":
    main()
