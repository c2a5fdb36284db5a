"""The arm-raise fit on a target another muscle model made: how close the least-squares fit
gets, and whether it stops on its evaluation cap.

Run:  python benchmarks/bench_fit_other_model.py [--jacobian forward|central|both]

The target is the arm raise simulated (reference solver, 100 Hz) by a model with other muscle
physics than the one fitted: first-order activation dynamics (Thelen 2003, τ 15/50 ms) on
every unit, series elastic elements 1.2× stiffer, and ramps of other timings and levels. The
fitted model (`builtin:arm-raise`) has none of these, so no exact fit exists, as with a motion
from OpenSim or MuJoCo. Prints, per Jacobian scheme,
each joint's RMS with the reference re-simulation of the fitted model, the simulations, the
wall time and how the refining least squares ended (on its tolerance, or on its cap). Wall
times move with load (stated); the RMS and the simulation counts do not.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

import torquesim as ts
from torquesim.fitting import FitProblem, SearchSettings, Target
from torquesim.fitting.fit import fit_to_accuracy
from torquesim.io.provenance import load_average
from torquesim.model.activation import ActivationDynamics, ActivationProfile, Ramp


def weaker_model(model: ts.ChainModel) -> ts.ChainModel:
    """``model`` with every unit 10 % weaker, its optimal angle 0.1 rad later and other
    activation timings: no activation dynamics, so the fitted model's family is closer."""
    units = []
    for k, unit in enumerate(model.units):
        ramps = tuple(Ramp(r.delay * (1.1 if k % 2 else 0.9), r.duration * 1.05, r.level)
                      for r in unit.activation.ramps)
        p = unit.parameters
        parameters = replace(p, isometric_torque=0.9 * p.isometric_torque,
                             eccentric_torque_max=0.9 * p.eccentric_torque_max,
                             optimal_angle=p.optimal_angle + 0.1)
        units.append(replace(unit, parameters=parameters, activation=ActivationProfile(
            unit.activation.initial_level, ramps)))
    return model.replace(units=tuple(units))


def other_model(model: ts.ChainModel) -> ts.ChainModel:
    """``model`` with other muscle physics and other activation timings (module docstring)."""
    units = []
    for k, unit in enumerate(model.units):
        profile = unit.activation
        ramps = tuple(Ramp(r.delay * (1.1 if k % 2 else 0.9), r.duration * 1.05,
                           min(1.0, r.level * (1.08 if k % 2 == 0 else 0.95)))
                      for r in profile.ramps)
        parameters = replace(unit.parameters, se_stiffness=1.2 * unit.parameters.se_stiffness)
        units.append(replace(unit, parameters=parameters,
                             activation=ActivationProfile(profile.initial_level, ramps),
                             activation_dynamics=ActivationDynamics()))
    return model.replace(units=tuple(units))


def fit_once(model, target, scheme: str, settings) -> dict:
    problem = FitProblem(target, base_model=model)
    problem.evaluate(np.array([problem.space.upper]))  # compile outside the timing
    problem.simulations = 0
    lines = []
    start = time.perf_counter()
    problem, outcome, refinements = fit_to_accuracy(problem, settings, progress=lines.append)
    wall = time.perf_counter() - start
    fitted = ts.simulate(problem.model_for(outcome.x), "reference", output_step=0.01)
    rms = {j.name: float(np.sqrt(np.mean(np.degrees(fitted.angle(j.name) - target.angles[k])
                                         ** 2))) for k, j in enumerate(model.joints)}
    ends = [line for line in lines if "refined" in line]
    return {"rms": rms, "simulations": outcome.simulations, "wall": wall, "ends": ends,
            "step_ms": problem.step * 1e3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jacobian", choices=("forward", "central", "both"), default="both")
    parser.add_argument("--write-target", help="also write the target as a .mot file here")
    parser.add_argument("--target", choices=("activation-dynamics", "weaker"),
                        default="activation-dynamics",
                        help="the other model: activation dynamics and stiffer SE, or every "
                             "unit 10 %% weaker with its optimal angle moved")
    parser.add_argument("--iterations", type=int, default=SearchSettings().iterations,
                        help="residual evaluations of the refining least squares (its cap)")
    args = parser.parse_args()
    print(f"load average at start: {load_average():.2f} (2 cores)")
    model = ts.load_model("builtin:arm-raise")
    made_by = other_model if args.target == "activation-dynamics" else weaker_model
    run = ts.simulate(made_by(model), "reference", output_step=0.01)
    target = Target(run.time, run.q.T, tuple(j.name for j in model.joints), "other-model")
    if args.write_target:
        from torquesim.io.tables import write_table

        write_table(args.write_target, {"time": run.time, **{
            j.coordinate: run.angle(j.name) for j in model.joints}}, name="other-model")
    schemes = ("forward", "central") if args.jacobian == "both" else (args.jacobian,)
    for scheme in schemes:
        got = fit_once(model, target, scheme, SearchSettings(iterations=args.iterations,
                                                              jacobian=scheme))
        rms = ", ".join(f"{j} {v:.3f}°" for j, v in got["rms"].items())
        print(f"{scheme:8s} RMS (reference) {rms}; {got['simulations']} simulations, "
              f"{got['wall']:.1f} s, final step {got['step_ms']:.3g} ms")
        for line in got["ends"]:
            print(f"         {line}")
    print(f"load average at end: {load_average():.2f}")


if __name__ == "__main__":
    main()
