"""Sensitivity of the study to one model parameter (``torquesim compare --vary NAME=v1,v2``).

The whole study is repeated per value; the summary shows how each technique's stability
limit, the units' smallest CE time constants and the verdict move. The stiff regime (low
activation, fast lengthening, stiff SE) is where explicit schemes suffer.
"""

from __future__ import annotations

import html
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..io.atomic import write_atomic, write_text_atomic
from ..io.html_page import image, page, table
from ..io.tables import write_rows
from ..model.activation import ActivationProfile
from ..model.chain import ChainModel, as_chain
from ..model.paths import parse_assignment, set_parameter
from ..plots import figure_png
from .compare import (
    ACCURACY_TARGETS_DEG,
    DEFAULT_REPEATS,
    DEFAULT_TOLERANCES,
    stability_limit,
    verdict,
)
from .outputs import smooth_case_orders, write_study
from .report import plot_sensitivity

#: Parameter name → (what it changes, unit, allowed range).
VARIABLES = {
    "se_stiffness": ("SE stiffness k of every unit (flexors and extensors alike)", "N·m/rad",
                     (1.0, 1e5)),
    "extensor_level": ("constant activation of every extensor unit (its co-activation): "
                       "initial level and every ramp", "activation, 0–1", (0.0, 1.0)),
    "dumbbell_mass": ("mass of every point load (the dumbbell of the elbow curl)", "kg",
                      (0.0, 100.0)),
    "ce_damping": ("CE parallel damping β of every unit (Millard et al. 2013)", "N·m·s/rad",
                   (0.0, 1e4)),
}
SUMMARY_COLUMNS = ("variable", "value", "technique", "stability_limit_s", "min_tau_unit",
                   "min_tau_s", *(f"cheapest_{t:g}deg" for t in ACCURACY_TARGETS_DEG),
                   *(f"cost_{t:g}deg_s" for t in ACCURACY_TARGETS_DEG))


def parse_vary(text: str) -> tuple[str, tuple[float, ...]]:
    """``NAME=v1,v2,...`` → (name, values). NAME is one of `VARIABLES` (a field of every unit
    or every load at once, values checked against its range) or a parameter path of the model
    (`torquesim.model.paths`, checked when the model is changed)."""
    name, rest = parse_assignment(text, "--vary", "se_stiffness=200,600,3000")
    try:
        values = tuple(float(v) for v in rest.split(",") if v.strip())
    except ValueError:
        values = ()
    low, high = VARIABLES[name][2] if name in VARIABLES else (-math.inf, math.inf)
    if not values or not all(math.isfinite(v) and low <= v <= high for v in values):
        allowed = f" in [{low:g}, {high:g}]" if name in VARIABLES else " finite"
        raise ModelError("--vary", f"{text!r}: allowed {name}=v1,v2,... with every "
                         f"value{allowed}")
    return name, values


def describe(name: str) -> tuple[str, str]:
    """(what ``name`` changes, its unit) for the page and the figure."""
    if name in VARIABLES:
        return VARIABLES[name][0], VARIABLES[name][1]
    return f"the model's {name}", "SI units of the model file"


def vary_model(model, name: str, value: float) -> ChainModel:
    """``model`` (any chain) with parameter ``name`` set to ``value`` (one of `VARIABLES`
    or a parameter path, `torquesim.model.paths`)."""
    model = as_chain(model)
    if name not in VARIABLES:
        return set_parameter(model, name, value, "--vary")
    try:
        if name in ("se_stiffness", "ce_damping"):
            units = tuple(replace(u, parameters=replace(u.parameters, **{name: value}))
                          for u in model.units)
            return model.replace(units=units)
        if name == "extensor_level":
            units = tuple(replace(u, activation=ActivationProfile(
                value, tuple(replace(r, level=value) for r in u.activation.ramps)))
                if u.direction == -1 else u for u in model.units)
            return model.replace(units=units)
        if name == "dumbbell_mass":
            segments = tuple(replace(s, loads=tuple(replace(ld, mass=value) for ld in s.loads))
                             for s in model.segments)
            return model.replace(segments=segments)
    except ModelError as exc:
        raise ModelError("--vary", f"{name}={value:g} gives an invalid model: {exc}") from None
    raise ModelError("--vary", f"{name!r}; allowed: {', '.join(VARIABLES)}")


def summary_rows(name: str, value: float, rows: list[dict], reference) -> list[dict]:
    """One row per technique: its stability limit, the smallest τ of each unit over the
    reference motion, and the verdict's winner per accuracy target."""
    taus = {unit: float(np.min(tau)) for unit, tau in reference.time_constants().items()}
    stiffest = min(taus, key=taus.get)
    verdicts = verdict(rows)
    out = []
    for tech in dict.fromkeys(r["technique"] for r in rows):
        row = {"variable": name, "value": value, "technique": tech,
               "stability_limit_s": stability_limit(rows, tech),
               "min_tau_unit": stiffest, "min_tau_s": taus[stiffest]}
        for v in verdicts:
            winner = v["winner"]
            row[f"cheapest_{v['target_deg']:g}deg"] = winner["technique"] if winner else ""
            mine = next((r for r in v["ranking"] if r["technique"] == tech), None)
            row[f"cost_{v['target_deg']:g}deg_s"] = mine["modelled_cost_s"] if mine else None
        out.append(row)
    return out


def render_sensitivity(summary, name, figures: dict[float, bytes], overview: bytes) -> str:
    """A self-contained HTML page of the sensitivity study."""
    what, unit = describe(name)
    headers = {"variable": "variable", "value": f"value ({unit})", "technique": "technique",
               "stability_limit_s": "stability limit (ms)", "min_tau_unit": "stiffest unit",
               "min_tau_s": "its smallest τ (ms)",
               **{f"cheapest_{t:g}deg": f"cheapest for {t:g}°" for t in ACCURACY_TARGETS_DEG},
               **{f"cost_{t:g}deg_s": f"its modelled cost for {t:g}° (ms)"
                  for t in ACCURACY_TARGETS_DEG}}
    in_ms = {"stability_limit_s", "min_tau_s", *(f"cost_{t:g}deg_s"
                                                 for t in ACCURACY_TARGETS_DEG)}
    rows = [[r[c] * 1e3 if c in in_ms and r[c] is not None else r[c] for c in SUMMARY_COLUMNS]
            for r in summary]
    body = [f"<p>{html.escape(what)} ({html.escape(unit)}). The full study was repeated per "
            "value (each in its own folder, with its report). Stability limit: the largest "
            "step whose run, and every smaller one, stays within 1° of the reference.</p>",
            image(overview, "stability limits against the value"),
            "<h2>How the limits and the verdict move</h2>",
            table([headers[c] for c in SUMMARY_COLUMNS], rows, name_columns=1),
            "<h2>Each unit's time constant over the motion</h2>"]
    for value, png in figures.items():
        body.append(f"<h3>{html.escape(name)} = {value:g} {html.escape(unit)}</h3>"
                    + image(png, f"time constants at {name} = {value:g}"))
    return page(f"Sensitivity to {name}", body)


def write_sensitivity(directory, model, name: str, values, *, steps, repeats=DEFAULT_REPEATS,
                      progress=None, model_source="builtin",
                      tolerances=DEFAULT_TOLERANCES) -> list[dict]:
    """Run the study per value into ``directory/NAME=VALUE/`` and write
    ``sensitivity.csv``, ``sensitivity.png`` and ``sensitivity.html`` into ``directory``
    (``tolerances``: the adaptive solvers' rtol values, `run_study`)."""
    from .report import plot_time_constants

    directory = Path(directory)
    models = [(v, vary_model(model, name, v)) for v in values]  # all checked before any run
    directory.mkdir(parents=True, exist_ok=True)
    if progress:
        progress(0, 0, "smooth case orders")
    smooth = smooth_case_orders(chain=as_chain(model).n_joints > 1)
    summary, figures = [], {}
    for value, varied in models:
        if progress:
            progress(0, 0, f"{name} = {value:g}")
        rows, reference, _ = write_study(directory / f"{name}={value:g}", varied, steps=steps,
                                         tolerances=tolerances, repeats=repeats,
                                         progress=progress, smooth=smooth,
                                         model_source=f"{model_source}, {name}={value:g}")
        summary += summary_rows(name, value, rows, reference)
        figures[value] = figure_png(plot_time_constants(reference))
    write_rows(directory / "sensitivity.csv", summary, SUMMARY_COLUMNS)
    overview = figure_png(plot_sensitivity(summary, name, describe(name)[1]))
    write_atomic(directory / "sensitivity.png", lambda p: p.write_bytes(overview))
    write_text_atomic(directory / "sensitivity.html",
                      render_sensitivity(summary, name, figures, overview))
    return summary
