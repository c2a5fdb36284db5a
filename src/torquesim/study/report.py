"""Figures and the self-contained HTML report of a comparison study."""

from __future__ import annotations

import html
import math
import textwrap

import numpy as np

from ..io.html_page import image, page, settings_table, table
from ..plots import figure_png
from ..solvers.fixed_step import RK4_STABILITY_LIMIT
from ..solvers.techniques import PARTITIONED
from .compare import (
    ACCURACY_TARGETS_DEG,
    STABLE_ERROR_DEG,
    TIE_RATIO,
    observed_order,
    stability_limit,
    verdict,
    verdict_sentences,
)

#: Figure titles are wrapped at this many characters.
TITLE_WIDTH = 70


def wrapped(title: str, width: int = TITLE_WIDTH) -> str:
    """``title`` broken into lines of at most ``width`` characters."""
    return textwrap.fill(title, width)


def _techniques(rows):
    return list(dict.fromkeys(r["technique"] for r in rows))


#: Each technique's marker and dash pattern, in the order the techniques appear: lines that lie
#: on top of each other stay distinguishable without colour.
MARKERS = "osD^v<>ph*XP"
DASHES = ("-", "--", "-.", ":")


def _style(i: int) -> dict:
    return {"marker": MARKERS[i % len(MARKERS)], "ls": DASHES[i % len(DASHES)],
            "ms": 8 - (i % 3) * 1.5, "alpha": 0.85}


def _loglog_by_technique(rows, x_key, y_key, *, label, xlabel, ylabel, title, lines):
    """One log-log line per technique of ``rows[y_key]`` against ``rows[x_key]`` (× 1e3:
    s → ms); ``label(name)`` names each line and ``lines`` are (y, text) reference levels.
    Runs the stability guard flags are drawn with hollow markers."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(8, 5.8), constrained_layout=True)
    flagged_any = False
    for i, name in enumerate(_techniques(rows)):
        pts = sorted((r[x_key], r[y_key], bool(r["guard_exceeded"])) for r in rows
                     if r["technique"] == name and r[x_key] and math.isfinite(r[y_key]))
        style = _style(i)
        if not pts:
            ax.plot([], [], color=f"C{i % 10}", label=label(name), **style)
            continue
        x, y, flagged = (np.array(v) for v in zip(*pts, strict=True))
        (line,) = ax.loglog(x * 1e3, y, label=label(name), color=f"C{i % 10}",
                            zorder=3 + (name == PARTITIONED), **style)
        if flagged.any():
            flagged_any = True
            ax.loglog(x[flagged] * 1e3, y[flagged], ls="none", marker=style["marker"],
                      ms=style["ms"], mfc="white", mec=line.get_color(), zorder=5)
    for level, text in lines:
        ax.axhline(level, color="grey", ls=":", lw=0.8)
        ax.text(ax.get_xlim()[0], level * 1.15, f" {text}", color="grey", fontsize="small")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(wrapped(title))
    ax.grid(alpha=0.3, which="both")
    handles, labels = ax.get_legend_handles_labels()
    if flagged_any:
        handles.append(Line2D([], [], ls="none", marker="o", mfc="white", mec="black"))
        labels.append("hollow: stability guard flagged the run")
    fig.legend(handles, labels, fontsize="small", loc="outside lower center", ncols=2)
    return fig


def _limit_text(rows, name) -> str:
    """The stability limit in words, censored where the steps tried do not bound it."""
    steps = [r["h_s"] for r in rows if r["technique"] == name and r["h_s"]]
    if not steps:
        return ""
    limit = stability_limit(rows, name)
    if limit is None:
        return f"never within {STABLE_ERROR_DEG:g}°"
    if limit >= max(steps):
        return f"within {STABLE_ERROR_DEG:g}° up to ≥ {limit * 1e3:g} ms"
    return f"within {STABLE_ERROR_DEG:g}° up to {limit * 1e3:g} ms"


def order_label(rows, name) -> str:
    """``name (slope p; within 1° up to h ms)`` where the runs show an asymptotic range, else
    says there is none; the stability limit is censored (≥, never) where the steps tried do
    not bound it."""
    order = observed_order(rows, name)
    parts = ["no asymptotic range" if order is None else f"slope {order:.2f}"]
    limit = _limit_text(rows, name)
    if limit:
        parts.append(limit)
    return f"{name} ({'; '.join(parts)})"


def plot_convergence(rows):
    """Max angle error (degrees) against step (log-log), one line per fixed-step technique,
    labelled with its fitted slope where `observed_order` finds a power law and with its
    stability limit (censored where the steps tried do not bound it)."""
    fixed = [r for r in rows if r["h_s"]]
    return _loglog_by_technique(
        fixed, "h_s", "max_error_deg", label=lambda name: order_label(fixed, name),
        xlabel="step h (ms)", ylabel="max |q − q_ref| over the motion and the joints (deg)",
        title="Convergence against the Radau reference",
        lines=[(STABLE_ERROR_DEG, f"accuracy threshold ({STABLE_ERROR_DEG:g}°)")])


def plot_work_precision(rows):
    """Max angle error against modelled cost (work counts × calibrated unit times), one line
    per technique; hollow markers for runs the stability guard flags."""
    return _loglog_by_technique(
        rows, "modelled_cost_s", "max_error_deg", label=str,
        xlabel="modelled cost (ms): work counts × time per unit of work, calibrated in this run",
        ylabel="max angle error (deg)", title="Work-precision",
        lines=[(t, f"{t:g}°") for t in ACCURACY_TARGETS_DEG])


def plot_time_constants(reference):
    """Each unit's CE time constant over the motion, with the RK4 limit it sets; the y axis
    has labelled ticks at 1, 2 and 5 per decade and the smallest τ and its limit are marked
    with their values."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

    taus = reference.time_constants()
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(8, 7), sharex=True, layout="constrained")
    for joint in reference.model.joints:
        ax0.plot(reference.time, np.degrees(reference.angle(joint.name)),
                 label=joint.coordinate)
    ax0.set_ylabel("joint angle (deg)")
    ax0.legend(fontsize="small")
    for i, (name, tau) in enumerate(taus.items()):
        ax1.semilogy(reference.time, tau * 1e3, label=f"{name} τ", ls=DASHES[i % 4])
    smallest = np.min(np.array(list(taus.values())), axis=0)
    ax1.semilogy(reference.time, RK4_STABILITY_LIMIT * smallest * 1e3, "k:",
                 label="largest stable RK4 step 2.785·min τ")
    finite = smallest[np.isfinite(smallest)]
    if finite.size:
        tau_min = float(np.min(finite))
        for value, text, where in ((tau_min, f"min τ = {tau_min * 1e3:.3g} ms", "top"),
                                   (RK4_STABILITY_LIMIT * tau_min,
                                    f"2.785·min τ = {RK4_STABILITY_LIMIT * tau_min * 1e3:.3g} ms",
                                    "bottom")):
            ax1.axhline(value * 1e3, color="grey", lw=0.6)
            ax1.text(1.0, value * 1e3, f" {text} ", transform=ax1.get_yaxis_transform(),
                     ha="right", va=where, fontsize="small",
                     bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.0})
    ax1.set_ylabel("CE time constant τ (ms)")
    ax1.set_xlabel("time (s)")
    ax1.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax1.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax1.yaxis.set_minor_locator(NullLocator())
    ax1.grid(alpha=0.3, which="both")
    fig.legend(*ax1.get_legend_handles_labels(), fontsize="small", loc="outside lower center",
               ncols=2)
    return fig


EXPLANATION = """
<h2>Why each technique shows the order it shows</h2>
<ul>
<li><b>Monolithic RK4</b> is fourth order where the right-hand side is smooth: on the smooth
case (constant activations, no unit crossing ω<sub>cc</sub> = 0, no clamp, no end stop) the
measured slope is close to 4. On the default curl it is <em>unstable</em> for steps above the
stability limit 2.785·τ (τ, a unit's CE time constant, falls to ≈0.15 ms for the extensor at
activation 0.1 while it is stretched): the ±ω<sub>max</sub> clamps keep it bounded, so the
motion is plausible and wrong. Below the limit its error drops at once to a floor of
~1e-9 rad that is not monotone in h: the slope jump of T<sub>ω</sub> at ω<sub>cc</sub> = 0
(factor 4.3), the SE going slack and the clamps are crossed inside a step at a place that
differs for every h, and a step containing such a kink has a local error of low order. The
errors there do not fall as a power of h, so no order is reported for it on this case (“no
asymptotic range”): a slope fitted through them would measure the kinks, not RK4.</li>
<li><b>Partitioned (zero-order hold)</b> freezes the other part's output over a step: the
coupling error is O(h) per unit time whatever the order of each part's integrator, so the
method is first order, with a large constant on this stiff model (≈0.14 rad at 0.1 ms).
Sub-cycling the muscle part does not help: the error is in the exchange, not in the muscle
integration. Gauss-Seidel (body first) removes the lag of one signal but is still first
order.</li>
<li><b>Linear extrapolation</b> of the held values, and <b>iterating the exchange</b> with a
linear interpolant, make the coupling error O(h²): second order.</li>
<li><b>IMEX</b> keeps the body on explicit RK4 but integrates each unit's CE equation with
an L-stable two-stage SDIRK method (order 2; one scalar implicit equation per unit and stage,
solved by Newton's method safeguarded by bisection and stopped at the T<sub>ω</sub> kink), with
the body's new angle fed to the muscles (Gauss-Seidel) and the muscle torque linearly
extrapolated for the body. The muscle part then has no stability limit, so the stiff
low-activation eccentric regime that breaks explicit RK4 costs nothing; the order is 2 (SDIRK2
and the linear exchange), measured on the smooth case, and on the default curl the slope stays
near 2 because the kinks sit below its error. This is the variant partitioning makes
possible and the abstract does not consider; the verdict above says where it pays.</li>
<li><b>Adaptive solvers</b> (DOP853, Radau) place their steps by an error estimate; near the
non-smooth points they shrink the step, which is what an event-aware method does by locating
the kink and restarting there. Their cost does not fall with tolerance as theory says because
the kinks and the stiffness, not the requested accuracy, set the steps.</li>
</ul>
"""


#: The report's table of all runs: (row key, header with units, scale).
RUN_TABLE = (("technique", "technique", None), ("h_s", "step h (ms)", 1e3),
             ("tolerance", "rtol (atol, rad: imex-ros2-adaptive)", None),
             ("max_error_deg", "max error (deg)", None),
             ("rms_error_deg", "RMS error (deg)", None),
             ("final_torque_error_nm", "final torque error (N·m)", None),
             ("stable", "within 1°", None), ("guard_exceeded", "guard exceeded", None),
             ("max_step_over_tau", "max h/τ", None), ("steps", "steps", None),
             ("rhs_body", "body evaluations", None), ("rhs_muscle", "muscle evaluations", None),
             ("newton_iterations", "Newton iterations", None),
             ("modelled_cost_s", "modelled cost (ms)", 1e3),
             ("wall_time_s", "wall time, min (ms)", 1e3),
             ("wall_time_max_s", "wall time, max (ms)", 1e3), ("status", "status", None))


def _scaled(value, scale):
    return value * scale if scale is not None and isinstance(value, float) else value


def render_report(rows, reference, *, smooth_orders=None, title="torquesim comparison",
                  settings=None) -> str:
    """A self-contained HTML page: verdict, orders, stability limits, figures, the table of
    runs (the per-joint errors are in results.csv), the settings."""
    names = _techniques(rows)
    sentences = verdict_sentences(verdict(rows), names)
    body = ["<p>Every technique against a Radau reference (rtol 1e-11). Error = max |q − "
            "q<sub>ref</sub>| over the motion and over the joints (results.csv also gives it "
            "per joint). Cost = modelled cost: the run's work (right-hand-side evaluations of "
            "each part, Newton iterations) times the time of one unit of each, calibrated in "
            "this run on every run's minimum wall time over interleaved repeats; so the "
            "ranking does not move with machine load. Techniques whose modelled costs are "
            f"within {TIE_RATIO:g}× are a tie. verdict.csv holds the verdict.</p>",
            "<h2>Verdict</h2><ul>", *(f"<li>{html.escape(s)}</li>" for s in sentences), "</ul>",
            "<h2>Measured orders and stability limits</h2>"]
    order_rows = []
    for name in names:
        order = observed_order(rows, name)
        smooth = (smooth_orders or {}).get(name)
        order_rows.append((name, "none" if order is None else f"{order:.2f}",
                           "" if smooth is None else f"{smooth:.2f}",
                           _limit_text(rows, name) or "adaptive"))
    body.append(table(("technique", "observed order (this model)", "order on the smooth case",
                       "stability limit (every step up to it within 1°)"), order_rows))
    body.append("<p>“none”: the errors do not fall as a power of h over the steps tried (no "
                "asymptotic range; for monolithic RK4 on the curl the error below the "
                "stability limit is a floor set by the model's kinks), or too few runs were "
                "stable to measure a slope.</p>")
    for heading, fig in (("Convergence", plot_convergence(rows)),
                         ("Work-precision", plot_work_precision(rows)),
                         ("Stiffness over the motion", plot_time_constants(reference))):
        body.append(f"<h2>{heading}</h2>{image(figure_png(fig), heading)}")
    body.append(EXPLANATION)
    body.append("<h2>All runs</h2>")
    body.append(table([h for _, h, _ in RUN_TABLE],
                      [[_scaled(r.get(k), scale) for k, _, scale in RUN_TABLE] for r in rows]))
    if settings:
        body.append("<h2>Settings</h2>" + settings_table(settings))
    return page(title, body)


def plot_sensitivity(summary: list[dict], name: str, unit: str):
    """Smallest unit τ and each fixed-step technique's stability limit against the varied
    value (``name`` in ``unit``), ticks at the values studied. The x axis is logarithmic when
    every value is positive and they span more than a factor of 10."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, FuncFormatter, LogLocator, NullLocator

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4.6), constrained_layout=True)
    values = sorted({r["value"] for r in summary})
    first = {v: next(r for r in summary if r["value"] == v) for v in values}
    ax0.plot(values, [first[v]["min_tau_s"] * 1e3 for v in values], "o-",
             label="smallest unit τ over the motion")
    ax0.plot(values, [RK4_STABILITY_LIMIT * first[v]["min_tau_s"] * 1e3 for v in values],
             "k:", label="RK4 limit 2.785·min τ")
    ax0.set_ylabel("time constant, step (ms)")
    ax0.set_title(wrapped("Stiffest unit's CE time constant", 45))
    ax0.legend(fontsize="small")
    markers = "osD^v<>ph*"
    for i, tech in enumerate(dict.fromkeys(r["technique"] for r in summary)):
        limits = [next((r["stability_limit_s"] for r in summary
                        if r["value"] == v and r["technique"] == tech), None) for v in values]
        if any(lim is not None for lim in limits):
            # distinct markers and dashes, drawn half transparent, so lines lying on top of
            # each other (several techniques often share a limit) stay visible
            ax1.plot(values, [np.nan if lim is None else lim * 1e3 for lim in limits],
                     marker=markers[i % len(markers)], ls=("-", "--", "-.", ":")[i % 4],
                     ms=9 - i % 4 * 1.5, alpha=0.75, label=tech)
    ax1.set_yscale("log")
    ax1.set_ylabel("largest step within 1° (ms)")
    ax1.set_title(wrapped("Stability limit of each fixed-step technique "
                          "(every smaller step tried also within 1°)", 45))
    ax1.legend(fontsize="x-small")
    log_x = min(values) > 0 and max(values) > 10 * min(values)
    for ax in (ax0, ax1):
        if ax is ax0:
            ax.set_yscale("log")
        if log_x:
            ax.set_xscale("log")
        ax.xaxis.set_major_locator(FixedLocator(values))
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xticks(values, [f"{v:g}" for v in values])
        ax.set_xlabel(f"{name} ({unit})")
        ax.grid(alpha=0.3, which="both")
        # labelled ticks at 1, 2 and 5 per decade: the values are read off the axis
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_locator(NullLocator())
    return fig
