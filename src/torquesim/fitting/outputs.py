"""What a fit writes: fitted model, target-vs-simulated table, overlay figure, summary."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..io.atomic import write_text_atomic
from ..io.json_text import json_text
from ..io.model_file import save_model
from ..io.provenance import provenance
from ..io.tables import write_table
from ..solvers.simulation import simulate
from .fit import (
    AGREEMENT_DEG,
    AGREEMENT_FRACTION,
    FitOutcome,
    SearchSettings,
    agrees,
    reference_resimulation,
)
from .objective import FAILED_SCORE
from .problem import FitProblem

MODEL_FILE = "fitted_model.toml"
MOTION_FILE = "fit_motion.csv"
STORAGE_FILE = "fit_motion.sto"
FIGURE_FILE = "fit.png"
SUMMARY_FILE = "fit_summary.json"
CHECKPOINT_FILE = "fit_checkpoint.npz"
#: The files a fit leaves in its directory.
FIT_FILES = (MODEL_FILE, MOTION_FILE, STORAGE_FILE, FIGURE_FILE, SUMMARY_FILE, CHECKPOINT_FILE)


def summarise(problem: FitProblem, outcome: FitOutcome, settings: SearchSettings,
              refinements: list[dict] | None = None) -> dict:
    """Re-simulate the best candidate with the fit's technique and the reference solver and
    collect the figures of the fit: errors per joint, each unit's mean activation, and the
    step refinements of `fit_to_accuracy` (if any)."""
    model = problem.model_for(outcome.x)
    fitted = simulate(model, problem.method, problem.step, coupling=problem.coupling,
                      check=False)
    reference = reference_resimulation(problem, outcome.x)
    failed = {j: (math.inf, math.inf) for j in problem.target.joints}
    errors = problem.errors_deg(fitted) if fitted.success else failed
    ref_errors = problem.errors_deg(reference) if reference.success else failed
    rms, ref_rms = problem.overall_rms(errors), problem.overall_rms(ref_errors)
    warnings = []
    if outcome.score >= FAILED_SCORE:
        warnings.append("no candidate simulated usably (every run failed or broke the RK4 "
                        "stability limit): use --method imex or a smaller --step")
    elif not agrees({j: (errors[j][0], ref_errors[j][0]) for j in problem.target.joints}):
        worst = max(problem.target.joints,
                    key=lambda j: abs(ref_errors[j][0] - errors[j][0]))
        warnings.append(f"the reference re-simulation of {worst} differs from the fit's own "
                        f"({ref_errors[worst][0]:.3f} vs {errors[worst][0]:.3f} deg RMS, more "
                        f"than {AGREEMENT_FRACTION:.0%} or {AGREEMENT_DEG:g} deg): the fit "
                        "leans on the integrator's error; use a smaller --step")
    if outcome.capped:
        warnings.append(f"the search stopped on {outcome.capped}, not on its tolerance: the "
                        "fit may still improve; run it again with a larger --iterations "
                        "(e.g. twice) and --overwrite")
    if fitted.message:  # stability limit broken, or activation ramps not resolved
        warnings.append(fitted.message)
    free = set(problem.space.free.tolist())
    fields = fitted_fields(problem, outcome)
    for path, entry in fields.items():
        if entry["at_bound"]:
            warnings.append(f"{path} ended at its bound {entry['value']:g} {entry['unit']}: "
                            "the motion may want a value beyond it; widen its --bound")
    no_channels = {c: (math.inf, math.inf) for c in problem.target.channels}
    own = problem.channel_errors(fitted) if fitted.success else no_channels
    theirs = problem.channel_errors(reference) if reference.success else no_channels
    channels = {c: {"unit": "% body weight" if c.startswith("grf") else "cm",
                    "rms_error": own[c][0], "max_error": own[c][1],
                    "reference_rms_error": theirs[c][0], "reference_max_error": theirs[c][1]}
                for c in problem.target.channels}
    return {
        **provenance(),
        "target": {"source": problem.target.source, "samples": int(problem.target.time.size),
                   "duration_s": problem.target.duration,
                   "joints": list(problem.target.joints)},
        "model": problem.model.name,
        "method": fitted.method, "step_s": problem.step,
        "step_requested_s": problem.requested_step,
        "search": settings.search,
        "weights": {"joints": dict(zip(problem.target.joints, problem.weights.tolist(),
                                       strict=True)),
                    "velocity": problem.weight_velocity, "end_state": problem.weight_end,
                    "effort": problem.weight_effort,
                    **({"grf_deg_per_body_weight": problem.weight_grf,
                        "com_deg_per_m": problem.weight_com} if channels else {})},
        "initial_levels": dict(zip(problem.space.units, problem.levels.tolist(), strict=True)),
        "mean_activation": problem.mean_activations(outcome.x),
        "free_parameters": [n for i, n in enumerate(problem.space.names) if i in free],
        "fitted_fields": fields,
        "frozen": dict(problem.space.frozen),
        "rms_error_deg": rms, "max_error_deg": max(e[1] for e in errors.values()),
        "reference_rms_error_deg": ref_rms,
        "reference_max_error_deg": max(e[1] for e in ref_errors.values()),
        "joints": {j: {"rms_error_deg": errors[j][0], "max_error_deg": errors[j][1],
                       "reference_rms_error_deg": ref_errors[j][0],
                       "reference_max_error_deg": ref_errors[j][1]}
                   for j in problem.target.joints},
        "channels": channels,
        **({"take_off": take_off(problem, reference)} if reference.success
           and "grf_y" in problem.target.channels else {}),
        "start_speeds_deg_s": {j: math.degrees(v) for j, v in problem.start_speeds.items()},
        **({"landing_speed_m_s": model.landing_speed} if model.landing_speed else {}),
        "objective_deg": outcome.score, "initial_guess_objective_deg": outcome.initial_score,
        "simulations": outcome.simulations, "failed_simulations": outcome.failed_simulations,
        "wall_time_s": outcome.wall_time,
        "simulations_per_second": outcome.simulations / max(outcome.wall_time, 1e-9),
        "generations": outcome.generations_done, "polish_simulations": outcome.polish_done,
        "interrupted": outcome.interrupted,
        "history": {"columns": ["simulations", "wall_time_s", "best_objective_deg"],
                    "rows": outcome.history},
        "settings": settings.__dict__,
        "parameters": problem.space.table(outcome.x),
        "initial_guess": problem.space.table(outcome.initial_x),
        "step_refinements": refinements or [],
        "warnings": warnings,
        "_results": (fitted, reference),
        "_x": outcome.x,
    }


def fitted_fields(problem: FitProblem, outcome: FitOutcome) -> dict:
    """Each searched model field (`ParameterSpace.fields`): its fitted value, the start's,
    its SI unit, its bounds, and whether it ended at one (within 0.1 % of the range: the
    least-squares search approaches a bound from inside)."""
    from ..model.paths import allowed_at

    space, out = problem.space, {}
    for path in space.fields:
        i = space.names.index(path)
        low, high, value = space.lower[i], space.upper[i], float(outcome.x[i])
        out[path] = {"value": value, "start": float(outcome.initial_x[i]),
                     "unit": allowed_at(problem.model, path).unit, "bounds": [low, high],
                     "at_bound": i in space.free and min(value - low, high - value)
                     <= 1e-3 * (high - low)}
    return out


def take_off(problem: FitProblem, reference) -> dict | None:
    """Take-off of the target and of the reference re-simulation (`take_off_index` at
    `FLIGHT_FORCE` of body weight, the threshold the fit's start uses for flight), and the
    centre of mass's vertical speed then: the target's from the impulse of its force,
    ∫(F_y − m·g) dt / m from its first sample (at rest, as a fit starts), the reference's from
    its own motion. None when either does not leave the ground."""
    from scipy.integrate import trapezoid

    from ..model.contact import take_off_index
    from .initial_guess import FLIGHT_FORCE

    weight = problem.body_weight
    t, force = problem.target.elapsed, problem.target.channels["grf_y"]
    columns = reference.columns()
    i = take_off_index(force, FLIGHT_FORCE * weight)
    j = take_off_index(columns["grf_y"], FLIGHT_FORCE * weight)
    if i is None or j is None:
        return None
    target_speed = float(trapezoid(force[:i + 1] - weight, t[:i + 1])
                         * problem.model.gravity / weight)
    speed = float(columns["com_speed_y"][j])
    return {"target_s": float(t[i]), "target_speed_m_s": target_speed,
            "reference_s": float(reference.time[j]), "reference_speed_m_s": speed,
            "speed_error_percent": 100.0 * (speed - target_speed) / abs(target_speed)}


def motion_columns(problem: FitProblem, summary: dict, units: str) -> dict[str, np.ndarray]:
    """time; per joint the target (scored joints), fitted and reference angle; per target
    channel (a body on the ground) its target, fitted and reference values (N, m); per unit
    the activation. Angles in ``units`` ("deg" or "rad")."""
    fitted, reference = summary["_results"]
    convert = np.degrees if units == "deg" else np.asarray
    elapsed = problem.target.elapsed
    columns = {"time": problem.target.time}
    for j, joint in enumerate(fitted.model.joints):
        if joint.name in problem.target.joints:
            row = problem.target.joints.index(joint.name)
            columns[f"{joint.name}_target"] = convert(problem.target.angles[row])
        columns[f"{joint.name}_fitted"] = convert(np.interp(elapsed, fitted.time,
                                                            fitted.q[:, j]))
        columns[f"{joint.name}_reference"] = convert(np.interp(elapsed, reference.time,
                                                               reference.q[:, j]))
    fitted_columns, reference_columns = fitted.columns(), reference.columns()
    for name, goal in problem.target.channels.items():  # N and m, as they are
        columns[f"{name}_target"] = goal
        columns[f"{name}_fitted"] = np.interp(elapsed, fitted.time, fitted_columns[name])
        columns[f"{name}_reference"] = np.interp(elapsed, reference.time,
                                                 reference_columns[name])
    for unit, level in zip(fitted.model.units, problem.activations(summary["_x"]),
                           strict=True):
        columns[f"activation_{unit.name}"] = level
    return columns


def write_outputs(out_dir, problem: FitProblem, outcome: FitOutcome, summary: dict) -> list[str]:
    """Write model TOML, motion CSV (degrees) and OpenSim storage (radians), figure and
    summary JSON into ``out_dir`` (each atomically)."""
    from ..plots import plot_result, save_figure

    out = Path(out_dir)
    fitted, reference = summary["_results"]
    save_model(fitted.model.replace(notes=(*fit_notes(summary), *fitted.model.notes)),
               out / MODEL_FILE, "--out")
    channels = tuple(problem.target.channels)
    write_table(out / MOTION_FILE, {k if k == "time" or k.startswith(("activation", *channels))
                                    else f"{k}_deg": v for k, v in
                                    motion_columns(problem, summary, "deg").items()})
    write_table(out / STORAGE_FILE, motion_columns(problem, summary, "rad"),
                name="torquesim fit")
    elapsed = problem.target.elapsed
    figure = plot_result(reference, target={j: (elapsed, problem.target.angles[r])
                                            for r, j in enumerate(problem.target.joints)},
                         channels={c: (elapsed, v) for c, v in problem.target.channels.items()})
    figure.suptitle(f"torquesim fit: {problem.target.source}; RMS "
                    f"{summary['reference_rms_error_deg']:.3f}° (reference solver)")
    save_figure(figure, out / FIGURE_FILE, "--out")
    public = {k: v for k, v in summary.items() if not k.startswith("_")}
    write_text_atomic(out / SUMMARY_FILE, json_text(public))
    return [MODEL_FILE, MOTION_FILE, STORAGE_FILE, FIGURE_FILE, SUMMARY_FILE]


def fit_notes(summary: dict) -> list[str]:
    """What the fitted model file says of the fit that made it: target, date, errors per
    joint (the fit's and the reference re-simulation's), technique and search."""
    joints = "; ".join(f"{j} RMS {e['reference_rms_error_deg']:.3f} deg (reference), "
                       f"{e['rms_error_deg']:.3f} deg (fit)"
                       for j, e in summary["joints"].items())
    joints += "".join(f"; {c} RMS {e['reference_rms_error']:.3g} {e['unit']} (reference)"
                      for c, e in summary.get("channels", {}).items())
    settings = summary["settings"]
    return [f"Activation ramps fitted by torquesim {summary['torquesim_version']} on "
            f"{summary['created']} to {summary['target']['source']} "
            f"({summary['target']['samples']} samples, {summary['target']['duration_s']:g} s): "
            f"{joints}.",
            f"Fit settings: {summary['method']} at {summary['step_s'] * 1e3:.4g} ms, "
            f"{summary['search']} search, seed {settings.get('seed')}, "
            f"{summary['simulations']} simulations; the notes below are the starting model's."]


def summary_lines(summary: dict) -> list[str]:
    """The printed summary."""
    joints = summary["joints"]
    lines = [
        f"target        {summary['target']['source']} ({summary['target']['samples']} samples, "
        f"{summary['target']['duration_s']:g} s)",
        f"method        {summary['method']}, step {summary['step_s'] * 1e3:.4g} ms, "
        f"{summary['search']} search",
    ]
    steps = [r["step_s"] for r in summary.get("step_refinements", [])]
    if len(steps) > 1:
        lines.append("step          refined " + " → ".join(f"{h * 1e3:.4g} ms" for h in steps)
                     + " until the fit's own RMS and the reference re-simulation's agreed "
                     f"(within {AGREEMENT_FRACTION:.0%} or {AGREEMENT_DEG:g} deg per joint)")
    for joint, e in joints.items():
        lines.append(f"{joint:<13} RMS {e['rms_error_deg']:.3f} deg, max "
                     f"{e['max_error_deg']:.3f} deg; reference RMS "
                     f"{e['reference_rms_error_deg']:.3f} deg, max "
                     f"{e['reference_max_error_deg']:.3f} deg")
    if len(joints) > 1:
        lines.append(f"all joints    RMS {summary['rms_error_deg']:.3f} deg; reference RMS "
                     f"{summary['reference_rms_error_deg']:.3f} deg")
    for name, e in summary.get("channels", {}).items():
        lines.append(f"{name:<13} RMS {e['rms_error']:.3f} {e['unit']}, max "
                     f"{e['max_error']:.3f}; reference RMS {e['reference_rms_error']:.3f}, max "
                     f"{e['reference_max_error']:.3f} {e['unit']}")
    off = summary.get("take_off")
    if off:
        lines.append(f"take-off      target {off['target_s']:.3f} s, "
                     f"{off['target_speed_m_s']:.3f} m/s (from its force's impulse); reference "
                     f"{off['reference_s']:.3f} s, {off['reference_speed_m_s']:.3f} m/s "
                     f"({off['speed_error_percent']:+.1f} %)")
    moving = {j: v for j, v in summary.get("start_speeds_deg_s", {}).items() if v}
    if "landing_speed_m_s" in summary:
        lines.append(f"start motion  at touchdown, {summary['landing_speed_m_s']:.3g} m/s down "
                     "(the model's landing speed), the joints still")
    else:
        lines.append("start motion  " + ("moving: " + ", ".join(f"{j} {v:+.1f} deg/s"
                                                               for j, v in moving.items())
                                         + " (the target's speed at its first sample)"
                                         if moving else "at rest (the target starts still)"))
    for path, f in summary.get("fitted_fields", {}).items():
        lines.append(f"fitted        {path} {f['value']:.6g} {f['unit']} (from {f['start']:.6g}; "
                     f"bounds {f['bounds'][0]:g} to {f['bounds'][1]:g})")
    lines += [
        "reference     = the fitted model re-simulated with Radau",
        "activation    mean " + ", ".join(f"{u} {a:.3f}"
                                          for u, a in summary["mean_activation"].items()),
        f"start         {summary['initial_guess_objective_deg']:.3f} deg (the better of "
        "inverse dynamics and, on a free body, the model's own ramps)",
        f"simulations   {summary['simulations']} ({summary['failed_simulations']} failed), "
        f"{summary['simulations_per_second']:.0f} per second",
        f"wall time     {summary['wall_time_s']:.1f} s",
    ]
    return lines + [f"warning: {w}" for w in summary["warnings"]]


def fit_and_write(problem: FitProblem, settings: SearchSettings, out: Path, *,
                  resume: dict | None = None, progress=None, tick=None,
                  should_stop=lambda: False) -> tuple[FitProblem, FitOutcome, dict, list[str]]:
    """The whole fit into the folder ``out`` (created if needed), as ``torquesim fit`` and
    ``torquesim batch fit`` both run it: the folder's fit lock is held throughout (no two fits
    write one folder, wherever they run); the search with its checkpoint
    (``fit_checkpoint.npz``, resumed from ``resume``) and the integration-error control
    (`fit_to_accuracy`); then the summary and every output file, each replaced atomically.
    ``should_stop`` (polled) ends the search early with the best so far (the outcome says
    ``interrupted``).

    Returns (the problem at its final step, the outcome, the summary, the files written).
    """
    from ..io.lock import take_lock
    from .fit import fit_to_accuracy

    out.mkdir(parents=True, exist_ok=True)
    lock = take_lock(out)
    try:
        problem, outcome, refinements = fit_to_accuracy(
            problem, settings, checkpoint=out / CHECKPOINT_FILE, resume=resume,
            progress=progress, tick=tick, should_stop=should_stop)
        summary = summarise(problem, outcome, settings, refinements)
        files = write_outputs(out, problem, outcome, summary)
    finally:
        lock.unlink(missing_ok=True)
    return problem, outcome, summary, files
