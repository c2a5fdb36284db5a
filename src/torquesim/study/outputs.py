"""Write a comparison study to a directory: table, figures, report, manifest."""

from __future__ import annotations

import json
from pathlib import Path

from ..io.atomic import write_atomic, write_text_atomic
from ..io.provenance import load_average, provenance
from ..io.tables import write_rows
from ..plots import figure_png
from ..solvers.techniques import CONTROLLED_TOLERANCES
from .cases import smooth_case, smooth_chain_case
from .compare import (
    COLUMNS,
    DEFAULT_REPEATS,
    DEFAULT_TOLERANCES,
    VERDICT_COLUMNS,
    calibrate,
    observed_order,
    run_study,
    verdict,
    verdict_table,
)
from .report import (
    plot_convergence,
    plot_time_constants,
    plot_work_precision,
    render_report,
)

SMOOTH_STEPS = (2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4)


def smooth_case_orders(progress=None, chain: bool = False) -> dict[str, float]:
    """Observed orders of the fixed-step techniques on `smooth_case` (the elbow) or,
    with ``chain``, `smooth_chain_case` (shoulder and elbow)."""
    from ..solvers.techniques import study_techniques

    model, y0 = smooth_chain_case() if chain else smooth_case()
    techniques = tuple(t for t in study_techniques() if not t.adaptive)
    rows, _ = run_study(model, steps=SMOOTH_STEPS, tolerances=(), techniques=techniques,
                        repeats=1, initial_state=y0, progress=progress)
    return {t.name: observed_order(rows, t.name) for t in techniques}


def calibration_text(coefficients: dict[str, float]) -> dict[str, str]:
    """The calibrated time of one unit of work, for people: ``{"one body evaluation": "85
    ns", ...}``."""
    names = {"fixed.step.monolithic": "monolithic loop: per-step overhead",
             "fixed.step.partitioned": "partitioned loop: per-step overhead (exchange)",
             "fixed.body": "one body evaluation (joint accelerations)",
             "fixed.muscle": "one muscle evaluation (every unit's CE velocity)",
             "fixed.newton": "one Newton iteration of an implicit unit equation",
             "fixed.jacobian": "one linearisation of the body's stiff forces with its "
             "factorisation (imex-ros2)",
             "scipy.step": "SciPy: per-step overhead", "scipy.call": "SciPy: one right-hand side "
             "call (from Python)", "scipy.lu": "SciPy: one LU factorisation"}
    return {names[k]: f"{v * 1e9:.4g} ns" if v > 0 else "not resolved (absorbed by the others)"
            for k, v in coefficients.items() if k in names}


def write_study(directory, model, *, steps, repeats=DEFAULT_REPEATS, progress=None,
                model_source="builtin", smooth=None, timer=None,
                tolerances=DEFAULT_TOLERANCES):
    """Run the study on ``model`` and write results.csv, verdict.csv, convergence.png,
    work_precision.png, time_constants.png, report.html and manifest.json into ``directory``.
    ``smooth`` (orders on the smooth case) is measured unless given. ``timer`` and
    ``tolerances`` (the adaptive solvers' rtol values): see `run_study`."""
    from ..io.model_file import model_to_toml
    from ..model.chain import as_chain

    model = as_chain(model)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    extra = {} if timer is None else {"timer": timer}
    rows, reference = run_study(model, steps=steps, tolerances=tolerances, repeats=repeats,
                                progress=progress, **extra)
    coefficients = calibrate(rows)
    if smooth is None:
        if progress:
            progress(0, 0, "smooth case orders")
        smooth = smooth_case_orders(chain=model.n_joints > 1)
    write_rows(directory / "results.csv", rows, list(rows[0] if rows else COLUMNS))
    verdicts = verdict_table(verdict(rows))
    write_rows(directory / "verdict.csv", verdicts, VERDICT_COLUMNS)
    for name, plot in (("convergence", plot_convergence), ("work_precision", plot_work_precision)):
        png = figure_png(plot(rows))
        write_atomic(directory / f"{name}.png", lambda p, png=png: p.write_bytes(png))
    png = figure_png(plot_time_constants(reference))
    write_atomic(directory / "time_constants.png", lambda p: p.write_bytes(png))
    settings = {"steps_s": list(steps), "repeats": repeats, "model": model_source}
    load = load_average()
    shown = {"model": model_source, "fixed steps (ms)": [h * 1e3 for h in steps],
             "adaptive tolerances (rtol)": list(DEFAULT_TOLERANCES),
             "error-controlled tolerances (atol, rad)": list(CONTROLLED_TOLERANCES),
             "reference": "SciPy Radau, rtol 1e-11, atol 1e-13",
             "cost": "modelled: work counts × the time of one unit of each kind of work, "
                     "calibrated in this run",
             "wall time": f"minimum of {repeats} runs, interleaved round-robin over all runs, "
                          "after compilation",
             "load average at the end (1 min)": "unknown" if load is None else f"{load:.2f}",
             **calibration_text(coefficients)}
    write_text_atomic(directory / "report.html",
                      render_report(rows, reference, smooth_orders=smooth, settings=shown))
    manifest = {**provenance(), "command": "compare", "settings": settings,
                "reference": {"method": "Radau", "rtol": 1e-11, "atol": 1e-13},
                "smooth_case_orders": smooth,
                "calibration_s": coefficients, "load_average_1min": load,
                "model_toml": model_to_toml(model)}
    write_text_atomic(directory / "manifest.json", json.dumps(manifest, indent=2) + "\n")
    return rows, reference, smooth


