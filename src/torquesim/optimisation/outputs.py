"""What an optimisation writes: the optimised model, start-vs-optimum figure and page, the
optimum's motion, and a summary. The start and the optimum are re-simulated with the reference
solver (Radau) and the goals recomputed on those runs, so the gain reported is the model's,
not the integrator's."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..io.atomic import write_atomic, write_text_atomic
from ..io.json_text import json_text
from ..io.model_file import save_model
from ..io.provenance import provenance
from ..io.tables import write_table
from .goals import Trial
from .problem import INFEASIBLE_COST, OptimiseProblem, endstop_depths
from .search import OptimiseOutcome, OptimiseSettings

MODEL_FILE = "optimised_model.toml"
MOTION_FILE = "optimum_motion.csv"
STORAGE_FILE = "optimum_motion.sto"
FIGURE_FILE = "optimise.png"
PAGE_FILE = "optimise.html"
SUMMARY_FILE = "optimise_summary.json"
CHECKPOINT_FILE = "optimise_checkpoint.npz"
#: The files an optimisation leaves in its directory.
OPTIMISE_FILES = (MODEL_FILE, MOTION_FILE, STORAGE_FILE, FIGURE_FILE, PAGE_FILE, SUMMARY_FILE,
                  CHECKPOINT_FILE)
#: How many parameters the summary lists (those whose change carries most of the gain).
MOVED_SHOWN = 8


def _gain(goal, start: float, end: float) -> tuple[float, float]:
    """(improvement in the goal's direction, SI; the same in % of the start)."""
    change = (end - start) if goal.maximise else (start - end)
    return change, (100.0 * change / abs(start) if start != 0 else math.nan)


def summarise(problem: OptimiseProblem, outcome: OptimiseOutcome,
              settings: OptimiseSettings) -> dict:
    """Re-simulate start and optimum with the reference and collect the figures: per goal
    its value at start and optimum (the search's technique, the reference, and with copies
    the robust value), the gain, the parameters that carry it (`parameter_effects`), the
    failed runs by reason."""
    runs = {}
    for label, x in (("start", outcome.start_x), ("optimum", outcome.x)):
        runs[label] = problem.run(x, reference=True)
    reference = {}
    for label, run in runs.items():
        trial = Trial.of(run) if run.success else None
        reference[label] = [
            (float(g.function(run)) if g.function is not None
             else g.value(trial, problem.joint_names)[0]) if trial is not None else math.nan
            for g in problem.goals]
    goals, warnings = [], []
    for k, g in enumerate(problem.goals):
        gain, percent = _gain(g, outcome.start_values[k], outcome.values[k])
        ref_gain, ref_percent = _gain(g, reference["start"][k], reference["optimum"][k])
        entry = {"goal": g.label, "direction": "maximise" if g.maximise else "minimise",
                 "weight": g.weight, "unit": g.unit,
                 "start": float(outcome.start_values[k]), "optimum": float(outcome.values[k]),
                 "gain": gain, "gain_percent": percent,
                 "reference_start": reference["start"][k],
                 "reference_optimum": reference["optimum"][k],
                 "reference_gain": ref_gain, "reference_gain_percent": ref_percent}
        if problem.robust:
            entry["robust_start"] = float(outcome.start_robust_values[k])
            entry["robust_optimum"] = float(outcome.robust_values[k])
        goals.append(entry)
        if len(problem.goals) == 1 and gain > 0 and not ref_gain > 0:
            warnings.append(f"the gain in {g.label} does not hold when the optimum is "
                            "re-simulated with the reference solver: it leans on the "
                            "integrator's error; use a smaller --step")
    if outcome.start_cost >= INFEASIBLE_COST > outcome.cost:
        warnings.append("the start is infeasible (past an end stop beyond --endstop-depth, or "
                        "a --constrain outside its bounds): the optimum is the best feasible "
                        "candidate, and its goals may be worse than the start's")
    if np.array_equal(outcome.x, outcome.start_x):
        failed = sum(outcome.failures.values())
        warnings.append(f"no candidate beat the start in {outcome.generations_done} "
                        f"generations ({failed} of {outcome.simulations} runs failed): widen "
                        "the window (--window-*, --bound), free more parameters, or check that "
                        "the goal can change")
    effects = parameter_effects(problem, outcome)
    limits = limit_report(problem, outcome, runs)
    for entry in limits["endstops"]:
        if entry["past_allowed"]:
            warnings.append(f"the optimum re-simulated with the reference takes {entry['joint']} "
                            f"{entry['depth_scales']:.2g} end-stop scales past its "
                            f"{entry['stop_deg']:.1f}° stop (allowed {problem.endstop_depth:g}): "
                            "the search's technique and step miss it; use a smaller --step")
    for entry in limits["constraints"]:
        if not entry["within"]:
            warnings.append(f"the optimum re-simulated with the reference has {entry['goal']} "
                            f"outside {entry['bounds']}")
    return {
        **provenance(),
        "model": problem.start_model.name,
        "goals": goals,
        "cost": {"start": outcome.start_cost, "optimum": outcome.cost},
        "method": problem.method, "step_s": problem.step,
        "technique_choice": None if problem.choice is None else {
            "accuracy_deg": math.degrees(problem.choice.accuracy),
            "estimated_error_deg": math.degrees(problem.choice.error),
            "work_body_evaluations": problem.choice.work,
            "tried": [{"method": m, "step_s": h,
                       "estimated_error_deg": None if e is None else math.degrees(e),
                       "work_body_evaluations": w} for m, h, e, w in problem.choice.tried]},
        "robust": ({"copies": problem.robust, "timing_error_s": problem.timing_error,
                    "mode": problem.robust_mode, "seed": problem.perturbation_seed}
                   if problem.robust else None),
        "window": {"delay_s": problem.window.delay, "duration_fraction": problem.window.duration,
                   "level_fraction": problem.window.level,
                   "min_level": problem.window.min_level},
        "free_parameters": int(problem.space.free.size),
        "moved_most": effects,
        "limits": limits,
        "parameters": problem.space.table(outcome.x),
        "search": {"method": "CMA-ES (cmaes)", "seed": settings.seed,
                   "population": outcome.population, "sigma": settings.sigma,
                   "generations": outcome.generations_done,
                   "generations_asked": settings.generations, "converged": outcome.converged,
                   "interrupted": outcome.interrupted},
        "simulations": outcome.simulations,
        "failed_simulations": dict(outcome.failures),
        "wall_time_s": outcome.wall_time,
        "simulations_per_second": outcome.simulations / max(outcome.wall_time, 1e-9),
        "history": outcome.history,
        "warnings": warnings,
        "_runs": runs,
    }


def limit_report(problem: OptimiseProblem, outcome: OptimiseOutcome, runs: dict) -> dict:
    """How close the optimum (re-simulated with the reference) sits to each limit: per joint
    with end stops the stop it comes nearest, in degrees and end-stop scales (negative: inside)
    with the passive stop torque there; per constraint its value and bounds; the free
    parameters at a bound of their window."""
    run = runs["optimum"]
    model = problem.start_model
    endstops = []
    if run.success:
        angles = run.q
        depths = endstop_depths(model, angles)
        columns = run.columns()
        for k, joint in enumerate(model.joints):
            if not np.isfinite(depths[k]):
                continue
            q = angles[:, k]
            lower = joint.endstop_lower_angle - q.min() >= q.max() - joint.endstop_upper_angle
            stop = joint.endstop_lower_angle if lower else joint.endstop_upper_angle
            passive = np.abs(columns[f"torque_passive_{joint.name}"])
            endstops.append({
                "joint": joint.name, "stop_deg": round(math.degrees(stop), 6),
                "closest_deg": float(math.degrees(q.min() if lower else q.max())),
                "depth_scales": float(depths[k]),
                "peak_passive_torque_nm": float(passive.max()),
                "past_allowed": bool(depths[k] > problem.endstop_depth + 1e-9)})
    constraints = []
    trial = Trial.of(run) if run.success else None
    for constraint in problem.constraints:
        goal = constraint.goal
        value = (math.nan if trial is None else float(goal.function(run))
                 if goal.function is not None else goal.value(trial, problem.joint_names)[0])
        constraints.append({"goal": goal.label, "value": value, "shown": goal.shown(value),
                            "low": constraint.low, "high": constraint.high,
                            "bounds": constraint.shown(),
                            "within": constraint.violation(value) == 0.0})
    space = problem.space
    at_bound = [space.names[i] for i in space.free
                if min(outcome.x[i] - space.lower[i], space.upper[i] - outcome.x[i])
                <= 1e-6 * max(space.upper[i] - space.lower[i], 1e-12)]
    return {"endstop_depth_allowed_scales": problem.endstop_depth, "endstops": endstops,
            "constraints": constraints, "parameters_at_bounds": at_bound}


def parameter_effects(problem: OptimiseProblem, outcome: OptimiseOutcome) -> list[dict]:
    """The free parameters that moved, each with how far (% of its bounds) and the share of
    the plain gain lost when it alone goes back to its start value (the other parameters at
    the optimum; > 100 % when that run is worse than the start, None when it fails): the
    parameters that matter come first. One simulation per moved parameter."""
    space = problem.space
    span = np.array(space.upper) - np.array(space.lower)
    moved = [i for i in space.free if outcome.x[i] != outcome.start_x[i]]
    if not moved:
        return []
    rows = np.tile(outcome.x, (len(moved) + 2, 1))
    rows[-1] = outcome.start_x
    for k, i in enumerate(moved):
        rows[k, i] = outcome.start_x[i]
    simulations, failures = problem.simulations, problem.failures.copy()
    values, reasons, _ = problem.goal_values(rows)
    problem.simulations, problem.failures = simulations, failures  # not the search's
    cost = problem.cost_of_values(values)
    gain = cost[-1] - cost[-2]
    out = []
    for k, i in enumerate(moved):
        lost = (None if reasons[k] else
                float(100 * (cost[k] - cost[-2]) / gain) if gain != 0 else 0.0)
        out.append({"parameter": space.names[i], "start": float(outcome.start_x[i]),
                    "optimum": float(outcome.x[i]),
                    "moved_percent_of_bounds": float(100 * abs(outcome.x[i] - outcome.start_x[i])
                                                     / span[i]),
                    "gain_lost_if_reverted_percent": lost,
                    "reverted_run_fails": reasons[k] or None})
    out.sort(key=lambda e: -math.inf if e["gain_lost_if_reverted_percent"] is None
             else -e["gain_lost_if_reverted_percent"])
    return out[:MOVED_SHOWN]


def _value_text(goal, value) -> str:
    return goal.shown(value) if isinstance(value, float) else "—"


def summary_lines(summary: dict, problem: OptimiseProblem) -> list[str]:
    """The printed summary."""
    chosen = summary.get("technique_choice")
    lines = [f"model         {summary['model']}; {summary['free_parameters']} free parameters; "
             f"{summary['method']} at {summary['step_s'] * 1e3:.4g} ms" + (
                 f" (chosen: the least work within {chosen['accuracy_deg']:.3g}°, estimated "
                 f"{chosen['estimated_error_deg']:.2g}° on the start)" if chosen else "")]
    for goal, e in zip(problem.goals, summary["goals"], strict=True):
        lines.append(f"{e['direction']} {e['goal']}: start {goal.shown(e['start'])} → optimum "
                     f"{goal.shown(e['optimum'])} (gain {e['gain_percent']:+.2f} %)")
        lines.append(f"  reference   start {goal.shown(e['reference_start'])} → optimum "
                     f"{goal.shown(e['reference_optimum'])} (gain "
                     f"{e['reference_gain_percent']:+.2f} %), both re-simulated with Radau")
        if "robust_optimum" in e:
            r = summary["robust"]
            lines.append(f"  robust      {r['mode']} of the run and {r['copies']} copies with "
                         f"±{r['timing_error_s'] * 1e3:g} ms onset errors: start "
                         f"{goal.shown(e['robust_start'])} → optimum "
                         f"{goal.shown(e['robust_optimum'])}")
    lines.append("matters most  " + "; ".join(
        f"{m['parameter']} {m['start']:.4g} → {m['optimum']:.4g} (reverted alone: "
        + (f"fails, {m['reverted_run_fails']}" if m["reverted_run_fails"]
           else f"{m['gain_lost_if_reverted_percent']:.0f} % of the gain lost") + ")"
        for m in summary["moved_most"][:3]))
    limits = summary["limits"]
    nearest = sorted(limits["endstops"], key=lambda e: -e["depth_scales"])[:3]
    stops = "; ".join(
        f"{e['joint']} {abs(e['closest_deg'] - e['stop_deg']):.1f}° "
        f"{'past' if e['depth_scales'] > 0 else 'inside'} its {e['stop_deg']:.1f}° stop "
        f"({e['peak_passive_torque_nm']:.1f} N·m passive)" for e in nearest)
    if stops:
        lines.append(f"end stops     {stops} (allowed: {limits['endstop_depth_allowed_scales']:g}"
                     " stop scales past; --endstop-depth)")
    for c in limits["constraints"]:
        lines.append(f"constraint    {c['goal']} = {c['shown']} (bounds {c['bounds']}"
                     f"{'' if c['within'] else ', NOT met'})")
    free = summary["free_parameters"]
    lines.append(f"window        {len(limits['parameters_at_bounds'])} of {free} free parameters "
                 "at a bound" + (f" ({', '.join(limits['parameters_at_bounds'][:4])}"
                                 f"{', …' if len(limits['parameters_at_bounds']) > 4 else ''}): "
                                 "a wider window (--window-*, --bound) may gain more"
                                 if limits["parameters_at_bounds"] else ""))
    search = summary["search"]
    failed = sum(summary["failed_simulations"].values())
    lines.append(f"search        CMA-ES, seed {search['seed']}, {search['generations']} "
                 f"generations of {search['population']}"
                 + (" (converged)" if search["converged"] else ""))
    lines.append(f"simulations   {summary['simulations']} ({failed} failed"
                 + (": " + ", ".join(f"{n} {why}" for why, n in
                                     sorted(summary["failed_simulations"].items(),
                                            key=lambda kv: -kv[1])) if failed else "")
                 + f"), {summary['simulations_per_second']:.0f} per second")
    lines.append(f"wall time     {summary['wall_time_s']:.1f} s")
    return lines + [f"warning: {w}" for w in summary["warnings"]]


def optimise_notes(summary: dict) -> list[str]:
    """What the optimised model file says of the optimisation that made it."""
    goals = "; ".join(f"{e['direction']} {e['goal']}: {e['reference_start']:.6g} → "
                      f"{e['reference_optimum']:.6g} {e['unit']} (gain "
                      f"{e['reference_gain_percent']:+.2f} %, reference solver)"
                      for e in summary["goals"])
    robust = summary["robust"]
    extra = (f", robust ({robust['mode']} of {robust['copies']} copies with "
             f"±{robust['timing_error_s'] * 1e3:g} ms onset errors)" if robust else "")
    return [f"Activation ramps optimised by torquesim {summary['torquesim_version']} on "
            f"{summary['created']} from {summary['model']}: {goals}.",
            f"Optimise settings: {summary['method']} at {summary['step_s'] * 1e3:.4g} ms, "
            f"CMA-ES seed {summary['search']['seed']}, {summary['search']['generations']} "
            f"generations, {summary['simulations']} simulations{extra}; window ±"
            f"{summary['window']['delay_s'] * 1e3:g} ms on delays, ±"
            f"{summary['window']['duration_fraction']:.0%} on durations, ±"
            f"{summary['window']['level_fraction']:.0%} on levels; "
            + "".join(f"constraint {c['goal']} within {c['bounds']} (optimum {c['shown']}); "
                      for c in summary["limits"]["constraints"])
            + f"runs at most {summary['limits']['endstop_depth_allowed_scales']:g} end-stop "
            "scales past a stop; the notes below are the starting model's."]


def write_outputs(out_dir, problem: OptimiseProblem, outcome: OptimiseOutcome,
                  summary: dict) -> list[str]:
    """Write model TOML, the optimum's motion (CSV and OpenSim storage, reference solver),
    the comparison figure, an HTML page and the summary JSON (each atomically)."""
    from ..io import html_page
    from ..plots import figure_png, plot_comparison

    out = Path(out_dir)
    runs = summary["_runs"]
    optimum = runs["optimum"]
    save_model(optimum.model.replace(notes=(*optimise_notes(summary),
                                            *problem.start_model.notes)),
               out / MODEL_FILE, "--out")
    write_table(out / MOTION_FILE, optimum.columns())
    write_table(out / STORAGE_FILE, optimum.columns(), name="torquesim optimum")
    heads = "; ".join(f"{e['goal']} {_value_text(g, e['reference_start'])} → "
                      f"{_value_text(g, e['reference_optimum'])}"
                      for g, e in zip(problem.goals, summary["goals"], strict=True))
    title = f"torquesim optimise {summary['model']}: {heads} (reference solver)"
    png = figure_png(plot_comparison(runs["start"], optimum, title=title), dpi=120)
    write_atomic(out / FIGURE_FILE, lambda tmp: tmp.write_bytes(png), "--out")
    rows = [[e["goal"], e["direction"], _value_text(g, e["reference_start"]),
             _value_text(g, e["reference_optimum"]), f"{e['reference_gain_percent']:+.2f} %"]
            for g, e in zip(problem.goals, summary["goals"], strict=True)]
    moved = [[m["parameter"], m["start"], m["optimum"], m["moved_percent_of_bounds"],
              f"run fails: {m['reverted_run_fails']}" if m["reverted_run_fails"]
              else f"{m['gain_lost_if_reverted_percent']:.1f} %"] for m in summary["moved_most"]]
    body = [html_page.table(["goal", "direction", "start", "optimum", "gain"], rows),
            "<h2>Parameters that carry the gain</h2>",
            "<p>Each moved parameter set back alone to its start value, the others at the "
            "optimum: the share of the gain lost (search technique and step).</p>",
            html_page.table(["parameter", "start", "optimum", "moved (% of bounds)",
                             "gain lost if reverted"], moved),
            "<h2>Start (dashed) and optimum (solid)</h2>", html_page.image(png, title),
            "<h2>Settings</h2>", html_page.settings_table({
                "method": summary["method"], "step (ms)": summary["step_s"] * 1e3,
                "seed": summary["search"]["seed"],
                "generations": summary["search"]["generations"],
                "population": summary["search"]["population"],
                "simulations": summary["simulations"],
                "failed": sum(summary["failed_simulations"].values()),
                "robust copies": problem.robust})]
    write_text_atomic(out / PAGE_FILE, html_page.page(title, body))
    public = {k: v for k, v in summary.items() if not k.startswith("_")}
    write_text_atomic(out / SUMMARY_FILE, json_text(public))
    return [MODEL_FILE, MOTION_FILE, STORAGE_FILE, FIGURE_FILE, PAGE_FILE, SUMMARY_FILE]


def optimise_and_write(problem: OptimiseProblem, settings: OptimiseSettings, out: Path, *,
                       resume: dict | None = None, progress=None, tick=None,
                       should_stop=lambda: False, evaluate=None
                       ) -> tuple[OptimiseOutcome, dict, list[str]]:
    """The whole optimisation into the folder ``out`` (created if needed) under its lock:
    the search with its checkpoint, then the summary and every output file."""
    from ..io.lock import take_lock
    from .search import optimise_population

    out.mkdir(parents=True, exist_ok=True)
    lock = take_lock(out)
    try:
        outcome = optimise_population(problem, settings, checkpoint=out / CHECKPOINT_FILE,
                                      resume=resume, progress=progress, tick=tick,
                                      should_stop=should_stop, evaluate=evaluate)
        summary = summarise(problem, outcome, settings)
        files = write_outputs(out, problem, outcome, summary)
    finally:
        lock.unlink(missing_ok=True)
    return outcome, summary, files
