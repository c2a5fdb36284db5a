"""What batch work writes: tables (CSV), percentile bands, rank correlations, the batch fit
page with a small-multiples figure."""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path

import numpy as np

from ..io.atomic import write_atomic, write_text_atomic
from ..io.html_page import image, page, settings_table, table
from ..io.tables import write_rows, write_table

PERCENTILES = (5, 25, 50, 75, 95)


def rank_correlations(frame, parameters, outcomes) -> dict[str, dict[str, float]]:
    """Spearman rank correlation of every parameter with every outcome over the samples
    that finished (parameter → outcome → ρ; NaN where an outcome does not vary)."""
    from scipy.stats import spearmanr

    ok = frame["accuracy"] == "ok"
    out = {}
    for p in parameters:
        out[p] = {}
        for o in outcomes:
            x, y = frame.loc[ok, p].to_numpy(), frame.loc[ok, o].to_numpy()
            if x.size < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
                out[p][o] = math.nan
            else:
                out[p][o] = float(spearmanr(x, y).statistic)
    return out


def plot_sweep(chain, histories: np.ndarray, frame, parameters: list[str], rho: dict):
    """Per joint (a row each): the median angle and the 25–75 % and 5–95 % bands over the
    accurate samples, then each joint's peak angle against each varied parameter (one panel
    per parameter, accurate samples) with its Spearman ρ. The title says what was varied."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    n, p = chain.n_joints, len(parameters)
    t = np.linspace(0.0, chain.duration, histories.shape[2])
    ok = (frame["accuracy"] == "ok").to_numpy()
    fig, axes = plt.subplots(n, 1 + p, figsize=(5.2 + 3.6 * p, 2.9 * n + 1.0), squeeze=False,
                             layout="constrained")
    accurate = histories[ok]
    for j, joint in enumerate(chain.joints):
        ax = axes[j, 0]
        if accurate.shape[0]:
            p5, p25, p50, p75, p95 = np.percentile(accurate[:, j], PERCENTILES, axis=0)
            ax.fill_between(t, p5, p95, color="tab:blue", alpha=0.2, label="5–95 %")
            ax.fill_between(t, p25, p75, color="tab:blue", alpha=0.4, label="25–75 %")
            ax.plot(t, p50, color="tab:blue", label="median")
        else:
            ax.text(0.5, 0.5, "no accurate sample", transform=ax.transAxes, ha="center",
                    color="grey")
        ax.set_ylabel(f"{joint.coordinate} (deg)")
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
        if accurate.shape[0]:
            ax.legend(fontsize="small", loc="best")
        peak = f"peak_{joint.name}_deg"
        for k, name in enumerate(parameters):
            ax = axes[j, 1 + k]
            ax.plot(frame.loc[ok, name], frame.loc[ok, peak], ".", ms=3, alpha=0.6)
            ax.set_xlabel(name)
            ax.set_ylabel(f"peak {joint.name} (deg)")
            value = rho.get(name, {}).get(peak, float("nan"))
            ax.set_title(f"Spearman ρ = {value:.2f}", fontsize="medium")
            ax.grid(alpha=0.3)
    varied = ", ".join(parameters)
    fig.suptitle(textwrap.fill(f"{chain.name}: {int(ok.sum())} of {len(frame)} samples "
                               f"accurate; varied: {varied}", 90))
    return fig


def write_sweep(out: Path, chain, frame, histories, distributions, settings,
                outcome_columns: list[str]) -> None:
    """sweep.csv, sweep_percentiles.csv, sweep.png, rank_correlations.csv, sweep.html;
    ``outcome_columns``: the table's outcome columns (`sweep.outcome_columns`)."""
    from ..plots import save_figure

    out.mkdir(parents=True, exist_ok=True)
    write_rows(out / "sweep.csv", frame.itertuples(index=False), list(frame.columns))
    grid = np.linspace(0.0, chain.duration, histories.shape[2])
    finished = histories[(frame["accuracy"] == "ok").to_numpy()]  # as the figure: accurate
    bands = {"time": grid}
    for j, joint in enumerate(chain.joints):
        if finished.shape[0]:
            for p, row in zip(PERCENTILES, np.percentile(finished[:, j], PERCENTILES, axis=0),
                              strict=True):
                bands[f"{joint.name}_p{p}_deg"] = row
    write_table(out / "sweep_percentiles.csv", bands)
    parameters = [d.path for d in distributions]
    outcomes = [c for c in outcome_columns
                if c not in ("estimated_error_deg", "step_s", "accuracy", "error")]
    rho = rank_correlations(frame, parameters, outcomes)
    figure = plot_sweep(chain, histories, frame, parameters, rho)
    png_path = out / "sweep.png"
    save_figure(figure, png_path, "--out")
    rows = [[p, *(float(rho[p][o]) for o in outcomes)] for p in parameters]
    write_rows(out / "rank_correlations.csv", rows, ["parameter", *outcomes])
    counts = frame["accuracy"].value_counts().to_dict()
    refined = int(((frame["step_s"] < settings["step_s"] * (1 - 1e-9))
                   & (frame["accuracy"] == "ok")).sum())
    body = [f"<p>{len(frame)} samples: {counts.get('ok', 0)} accurate (estimated max angle "
            f"error within the tolerance; {refined} of them at a halved step, as the "
            f"<code>step_s</code> column gives), {counts.get('inaccurate', 0)} inaccurate, "
            f"{counts.get('unstable', 0)} beyond the RK4 stability limit, "
            f"{counts.get('failed', 0)} failed (their errors and warnings are in sweep.csv). "
            "Rank correlations use the accurate samples only.</p>",
            image(png_path.read_bytes(), "percentile bands and peak angle against each "
                  "parameter"),
            "<h2>Spearman rank correlation of each parameter with each outcome</h2>",
            table(["parameter", *outcomes], rows),
            "<h2>Distributions</h2>",
            table(["parameter", "distribution"],
                  [[d.path, f"{d.kind}({d.a:g}, {d.b:g}" + (f", {d.n})" if d.kind == "grid"
                                                           else ")")] for d in distributions]),
            "<h2>Settings</h2>", settings_table(settings)]
    write_text_atomic(out / "sweep.html", page(f"torquesim sweep: {chain.name}", body))
    write_text_atomic(out / "sweep_settings.json", json.dumps(settings, indent=2) + "\n")


#: The columns of batch.csv.
BATCH_COLUMNS = ("name", "target", "model", "status", "rms_deg", "max_deg",
                 "reference_rms_deg", "simulations", "wall_time_s", "worker", "error")


def write_batch_table(out: Path, rows: list[dict]) -> None:
    """batch.csv (one row per target, in the order given), atomically."""
    write_rows(out / "batch.csv", rows, BATCH_COLUMNS)


def plot_fits(out: Path, rows: list[dict]):
    """Small multiples: every finished fit's target and reference-simulated angles."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ..io.tables import read_table

    done = [r for r in rows if r["status"] in ("done", "done earlier")]
    cols = min(4, max(1, len(done)))
    nrows = max(1, math.ceil(len(done) / cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(3.2 * cols, 2.4 * nrows + 0.4),
                             squeeze=False, constrained_layout=True)
    for ax in axes.flat:
        ax.set_visible(False)
    for ax, row in zip(axes.flat, done, strict=False):
        ax.set_visible(True)
        motion = read_table(out / row["name"] / "fit_motion.csv")
        joints = [key.removesuffix("_target_deg") for key in motion
                  if key.endswith("_target_deg")]
        for joint in joints:
            ax.plot(motion["time"], motion[f"{joint}_reference_deg"], color="k", lw=1.2)
            # the target on top, dotted, so that it shows where the fit covers it
            ax.plot(motion["time"], motion[f"{joint}_target_deg"], ls=(0, (2, 2)),
                    color="tab:red", lw=1.4)
        ax.set_title(f"{row['name']}: {row['reference_rms_deg']:.2f}° RMS", fontsize="small")
        ax.set_xlabel("time (s)", fontsize="x-small")
        ax.set_ylabel(f"{', '.join(joints)} (deg)", fontsize="x-small")
        ax.tick_params(labelsize="x-small")
        ax.grid(alpha=0.3)
    fig.suptitle("every fit: target (red, dotted) and the fitted model re-simulated with the "
                 "reference solver (black)", fontsize="medium")
    return fig


def write_batch_page(out: Path, rows: list[dict], settings: dict) -> None:
    """batch.html: the table and the small multiples."""
    from ..plots import figure_png

    png = figure_png(plot_fits(out, rows))
    write_atomic(out / "batch.png", lambda p: p.write_bytes(png))
    body = [table(BATCH_COLUMNS, [[r.get(c) for c in BATCH_COLUMNS] for r in rows]),
            image(png, "every fit"), "<h2>Settings</h2>", settings_table(settings)]
    write_text_atomic(out / "batch.html", page("torquesim batch fit", body))
