"""What ``torquesim strength`` writes: the model with the fitted unit, the samples table, the
figure and the summary."""

from __future__ import annotations

import math
from pathlib import Path

from ..io.atomic import write_text_atomic
from ..io.json_text import json_text
from ..io.model_file import save_model
from ..io.provenance import provenance
from ..io.tables import write_rows
from .strength import FITTED_FIELDS, PassiveTorque, StrengthFit, StrengthSettings

MODEL_FILE = "strength_model.toml"
SAMPLES_FILE = "strength_samples.csv"
FIGURE_FILE = "strength_fit.png"
SUMMARY_FILE = "strength_summary.json"
STRENGTH_FILES = (MODEL_FILE, SAMPLES_FILE, FIGURE_FILE, SUMMARY_FILE)
#: Units of the fitted fields, as the summary prints them.
UNITS = {"isometric_torque": "N·m", "eccentric_torque_max": "N·m", "max_velocity": "rad/s",
         "velocity_constant": "rad/s", "min_differential_activation": "",
         "differential_activation_rate": "rad/s", "differential_activation_midpoint": "rad/s",
         "optimal_angle": "rad", "angle_curvature": "rad^-2"}


def strength_summary(fit: StrengthFit, *, unit: str, model: str, trials: list[str],
                     passive: PassiveTorque, settings: StrengthSettings,
                     wall_time: float, limbs: int = 1) -> dict:
    """The summary of a strength fit (of one limb's trials) as JSON-ready data (SI units; the
    optimal angle also in degrees); with ``limbs`` > 1 it also gives the torques the model gets
    (``limbs`` times the limb's)."""
    t0 = fit.parameters.isometric_torque
    kinds: dict[str, int] = {}
    for phase in fit.phases:
        kinds[phase.kind] = kinds.get(phase.kind, 0) + 1
    return {
        **provenance(),
        "unit": unit, "model": model, "trials": trials,
        "phases": {k: kinds.get(k, 0) for k in ("isometric", "concentric", "eccentric")},
        "samples": int(fit.fitted.size),
        "parameters": {f: {"value": getattr(fit.parameters, f), "unit": UNITS[f],
                           "status": fit.status[f],
                           "interval_95": list(fit.intervals[f]) if f in fit.intervals
                           else None} for f in FITTED_FIELDS},
        "optimal_angle_deg": math.degrees(fit.parameters.optimal_angle),
        "se_stiffness": fit.parameters.se_stiffness,
        "rms_N_m": fit.rms, "weighted_rms_N_m": fit.weighted_rms,
        "weighted_rms_percent_of_T0": 100.0 * fit.weighted_rms / t0,
        "above_weight": fit.above_weight, "residual_skewness_plain_fit": fit.skewness,
        "fraction_beneath": fit.fraction_beneath,
        "residual_autocorrelation": fit.autocorrelation,
        "gravity_and_passive": passive.source,
        "settings": {"velocity_tolerance": settings.velocity_tolerance,
                     "min_velocity_tolerance_deg_s": math.degrees(
                         settings.min_velocity_tolerance),
                     "isometric_speed_deg_s": math.degrees(settings.isometric_speed),
                     "plateau": settings.plateau, "above_weight": settings.above_weight,
                     "starts": settings.starts, "seed": settings.seed,
                     "hold": dict(settings.hold)},
        "limbs": limbs,
        "model_torques_N_m": {"isometric_torque": limbs * t0,
                              "eccentric_torque_max": limbs
                              * fit.parameters.eccentric_torque_max},
        "evaluations": fit.evaluations, "wall_time_s": wall_time,
        "notes": list(fit.notes),
    }


def _shown(field: str, value: float) -> str:
    if field == "optimal_angle":
        return f"{math.degrees(value):.4g}°"
    return f"{value:.4g}"


def summary_lines(summary: dict) -> list[str]:
    """The printed summary: one line per parameter with its interval, then the scores."""
    phases = summary["phases"]
    lines = [f"unit          {summary['unit']} of {summary['model']}: "
             f"{len(summary['trials'])} trials ({phases['isometric']} isometric, "
             f"{phases['concentric']} concentric, {phases['eccentric']} eccentric phases), "
             f"{summary['samples']} samples",
             f"gravity       {summary['gravity_and_passive']}",
             f"SE stiffness  {summary['se_stiffness']:.6g} N·m/rad (held"
             + (", per limb)" if summary["limbs"] > 1 else ")")]
    for field, entry in summary["parameters"].items():
        value, unit = entry["value"], entry["unit"]
        if entry["interval_95"] is not None:
            low, high = entry["interval_95"]
            where = f"[{_shown(field, low)}, {_shown(field, high)}]"
        else:
            where = entry["status"]
        unit = "" if field == "optimal_angle" else unit
        lines.append(f"{field:<33} {_shown(field, value):>9} {unit:<7} {where}")
    lines += [
        "intervals     simultaneous 95 % (Bonferroni), linearised at the optimum",
        f"RMS           {summary['weighted_rms_N_m']:.3g} N·m weighted "
        f"({summary['weighted_rms_percent_of_T0']:.2g} % of T0; samples above the function "
        f"weigh {summary['above_weight']:g}), {summary['rms_N_m']:.3g} N·m plain",
        f"beneath       {100 * summary['fraction_beneath']:.0f} % of the samples lie at or "
        "beneath the fitted function",
        f"wall time     {summary['wall_time_s']:.1f} s ({summary['evaluations']} evaluations)",
    ]
    if summary["limbs"] > 1:
        torques = summary["model_torques_N_m"]
        lines.insert(-1, f"limbs         the unit stands for {summary['limbs']}: the model gets "
                     f"T0 {torques['isometric_torque']:.4g} N·m, T_max "
                     f"{torques['eccentric_torque_max']:.4g} N·m (the values above are one "
                     "limb's)")
    return lines + [f"note: {n}" for n in summary["notes"]]


def strength_notes(summary: dict) -> list[str]:
    """What the model file says of the fit that made its unit."""
    fitted = ", ".join(f"{f} {_shown(f, e['value'])} ({e['status']})"
                       for f, e in summary["parameters"].items())
    return [f"{summary['unit']}: maximum voluntary torque fitted by torquesim strength "
            f"{summary['torquesim_version']} on {summary['created']} to "
            f"{len(summary['trials'])} dynamometer trials ({', '.join(summary['trials'])}); "
            f"weighted RMS {summary['weighted_rms_N_m']:.3g} N·m "
            f"({summary['weighted_rms_percent_of_T0']:.2g} % of T0), plain RMS "
            f"{summary['rms_N_m']:.3g} N·m; SE stiffness "
            f"{summary['se_stiffness']:.6g} N·m/rad held"
            + (f" per limb, {summary['limbs']} limbs (T0 and T_max times {summary['limbs']})"
               if summary["limbs"] > 1 else "") + "; gravity and passive torque "
            f"{summary['gravity_and_passive']}; {fitted}."]


def write_strength(out: Path, fit: StrengthFit, model, unit: str, summary: dict) -> list[str]:
    """Write the model with the fitted unit (and a note), the samples table, the figure and
    the summary into ``out``, each atomically."""
    from ..plots import plot_strength_fit, save_figure

    fitted_model = model.replace_unit(unit, parameters=fit.parameters)
    save_model(fitted_model.replace(notes=(*strength_notes(summary), *model.notes)),
               out / MODEL_FILE, "--out")
    columns = ("trial", "phase", "time", "angle_deg", "velocity_deg_s", "torque",
               "ce_angle_deg", "ce_velocity_deg_s", "fitted", "residual")
    rows, start = [], 0
    for phase in fit.phases:
        fitted = fit.fitted[start:start + phase.rows.size]
        start += phase.rows.size
        for i, row in enumerate(phase.rows):
            rows.append((phase.trial, phase.kind, int(row), math.degrees(phase.theta[i]),
                         math.degrees(phase.omega[i]), float(phase.torque[i]),
                         math.degrees(phase.theta_cc[i]), math.degrees(phase.omega_cc[i]),
                         float(fitted[i]), float(phase.torque[i] - fitted[i])))
    write_rows(out / SAMPLES_FILE, rows, columns, "--out")
    panels, start = [], 0
    for phase in fit.phases:
        n = phase.rows.size
        panels.append({"label": f"{phase.trial} ({phase.kind}"
                                + (f", {abs(math.degrees(phase.speed)):.0f}°/s)"
                                   if phase.kind != "isometric" else ")"),
                       "theta_cc": phase.theta_cc, "omega_cc": phase.omega_cc,
                       "angle": phase.theta, "torque": phase.torque,
                       "fitted": fit.fitted[start:start + n]})
        start += n
    figure = plot_strength_fit(panels, fit.parameters, title=(
        f"torquesim strength: {unit}, weighted RMS {fit.weighted_rms:.3g} N·m "
        f"({100 * fit.weighted_rms / fit.parameters.isometric_torque:.2g} % of T0)"))
    save_figure(figure, out / FIGURE_FILE, "--out")
    write_text_atomic(out / SUMMARY_FILE, json_text(summary))
    return list(STRENGTH_FILES)

