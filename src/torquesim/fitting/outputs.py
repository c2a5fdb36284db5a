"""What a fit writes: fitted model, target-vs-simulated table, overlay figure, summary."""

from __future__ import annotations

import json
import math
import platform
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from .. import __version__
from ..io.atomic import write_text_atomic
from ..io.model_file import save_model
from ..io.tables import write_table
from ..solvers.simulate import simulate
from .fit import FitOutcome, SearchSettings, parameter_table
from .objective import FAILED_SCORE
from .problem import FitProblem

MODEL_FILE = "fitted_model.toml"
MOTION_FILE = "fit_motion.csv"
FIGURE_FILE = "fit.png"
SUMMARY_FILE = "fit_summary.json"
CHECKPOINT_FILE = "fit_checkpoint.npz"
#: The files a fit leaves in its directory.
FIT_FILES = (MODEL_FILE, MOTION_FILE, FIGURE_FILE, SUMMARY_FILE, CHECKPOINT_FILE)
#: The fit's own error and the reference re-simulation's may differ by this much (deg RMS)
#: before the summary warns that the fit leans on the integrator's error.
TRUST_MARGIN_DEG = 0.25


def summarise(problem: FitProblem, outcome: FitOutcome, settings: SearchSettings) -> dict:
    """Re-simulate the best candidate with the fit's technique and the reference solver and
    collect the figures of the fit."""
    model = problem.model_for(outcome.x)
    fitted = simulate(model, problem.method, problem.step, coupling=problem.coupling,
                      check=False)
    reference = simulate(model, "reference", output_step=problem.step, check=False)
    rms, worst = problem.errors_deg(fitted) if fitted.success else (math.inf, math.inf)
    ref_rms, ref_worst = (problem.errors_deg(reference) if reference.success
                          else (math.inf, math.inf))
    warnings = []
    if outcome.score >= FAILED_SCORE:
        warnings.append("no candidate simulated usably (every run failed or broke the RK4 "
                        "stability limit): use --method imex or a smaller --step")
    elif not ref_rms <= rms + TRUST_MARGIN_DEG:
        warnings.append(f"the reference re-simulation is worse ({ref_rms:.3f} vs "
                        f"{rms:.3f} deg RMS): the fit leans on the integrator's error; use a "
                        "smaller --step or --method imex")
    if fitted.message:  # stability limit broken, or activation ramps not resolved
        warnings.append(fitted.message)
    return {
        "torquesim_version": __version__,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "target": {"source": problem.target.source, "samples": int(problem.target.time.size),
                   "duration_s": problem.target.duration},
        "method": fitted.method, "step_s": problem.step,
        "step_requested_s": problem.requested_step,
        "weights": {"velocity": problem.weight_velocity, "end_state": problem.weight_end},
        "extensor_rest_level": problem.space.extensor_rest,
        "flexor_initial_level": problem.level_f,
        "free_parameters": [n for i, n in enumerate(parameter_table(outcome.x))
                            if i in set(problem.space.free.tolist())],
        "frozen": dict(problem.space.frozen),
        "rms_error_deg": rms, "max_error_deg": worst,
        "reference_rms_error_deg": ref_rms, "reference_max_error_deg": ref_worst,
        "objective_deg": outcome.score, "initial_guess_objective_deg": outcome.initial_score,
        "simulations": outcome.simulations, "failed_simulations": outcome.failed_simulations,
        "wall_time_s": outcome.wall_time,
        "simulations_per_second": outcome.simulations / max(outcome.wall_time, 1e-9),
        "generations": outcome.generations_done, "polish_simulations": outcome.polish_done,
        "interrupted": outcome.interrupted,
        "history": {"columns": ["simulations", "wall_time_s", "best_objective_deg"],
                    "rows": outcome.history},
        "settings": settings.__dict__,
        "parameters": parameter_table(outcome.x),
        "initial_guess": parameter_table(outcome.initial_x),
        "warnings": warnings,
        "machine": {"python": platform.python_version(), "platform": platform.platform()},
        "_results": (fitted, reference),
        "_x": outcome.x,
    }


def write_outputs(out_dir, problem: FitProblem, outcome: FitOutcome, summary: dict) -> list[str]:
    """Write model TOML, motion CSV, figure and summary JSON into ``out_dir`` (atomically)."""
    from ..plots import plot_result, save_figure

    out = Path(out_dir)
    fitted, reference = summary["_results"]
    save_model(fitted.model, out / MODEL_FILE)
    times = problem.target.time
    elapsed = problem.target.elapsed
    columns = {"time": times, "target_deg": np.degrees(problem.target.angle),
               "fitted_deg": np.degrees(np.interp(elapsed, fitted.time, fitted.theta)),
               "reference_deg": np.degrees(np.interp(elapsed, reference.time,
                                                     reference.theta))}
    elbow = problem.model_for(summary["_x"])
    a_f, a_e = (elbow.flexor_activation(elapsed, problem.level_f),
                elbow.extensor_activation(elapsed))
    columns["activation_flexor"] = a_f
    columns["activation_extensor"] = a_e
    write_table(out / MOTION_FILE, columns)
    figure = plot_result(reference, target=(elapsed, problem.target.angle))
    figure.suptitle(f"torquesim fit: {problem.target.source}; RMS "
                    f"{summary['reference_rms_error_deg']:.3f}° (reference solver)")
    save_figure(figure, out / FIGURE_FILE)
    public = {k: v for k, v in summary.items() if not k.startswith("_")}
    write_text_atomic(out / SUMMARY_FILE, json.dumps(public, indent=2, default=float) + "\n")
    return [MODEL_FILE, MOTION_FILE, FIGURE_FILE, SUMMARY_FILE]


def summary_lines(summary: dict) -> list[str]:
    """The printed summary."""
    return [
        f"target        {summary['target']['source']} ({summary['target']['samples']} samples, "
        f"{summary['target']['duration_s']:g} s)",
        f"method        {summary['method']}, step {summary['step_s'] * 1e3:.4g} ms",
        f"angle error   RMS {summary['rms_error_deg']:.3f} deg, max "
        f"{summary['max_error_deg']:.3f} deg",
        f"reference     RMS {summary['reference_rms_error_deg']:.3f} deg, max "
        f"{summary['reference_max_error_deg']:.3f} deg (fitted model re-simulated with Radau)",
        f"start         {summary['initial_guess_objective_deg']:.3f} deg (inverse dynamics)",
        f"simulations   {summary['simulations']} ({summary['failed_simulations']} failed), "
        f"{summary['simulations_per_second']:.0f} per second",
        f"wall time     {summary['wall_time_s']:.1f} s",
    ] + [f"warning: {w}" for w in summary["warnings"]]
