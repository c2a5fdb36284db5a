"""Accuracy against cost of every solution technique (the abstract's question).

Each technique runs over a range of fixed steps (or tolerances, for adaptive solvers) and is
compared with a high-accuracy reference (Radau, rtol 1e-11). The table has one row per
(technique, step or tolerance); `verdict` turns it into the answer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction

import numpy as np
from scipy.stats import linregress

from ..errors import ModelError
from ..model.chain import ChainModel, as_chain
from ..solvers import simulate
from ..solvers.simulation import step_count
from ..solvers.techniques import (
    CONTROLLED_TOLERANCES,
    Technique,
    runs_monolithic,
    scipy_solver,
    study_techniques,
)

DEFAULT_STEPS = (20e-3, 10e-3, 5e-3, 2e-3, 1e-3, 0.5e-3, 0.2e-3, 0.1e-3, 0.05e-3)
#: A default step list keeps at least this many steps (`default_steps`).
MIN_DEFAULT_STEPS = 6
DEFAULT_TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
ACCURACY_TARGETS_DEG = (1.0, 0.1, 0.01, 0.001)
#: A run whose max angle error exceeds this is counted unstable: RK4 past its stability limit
#: stays bounded (the clamps), so "bounded" is not enough.
STABLE_ERROR_DEG = 1.0
REFERENCE_RTOL, REFERENCE_ATOL = 1e-11, 1e-13
GRID = 1e-3  # s, the reference output grid

#: Each run is repeated this many times, round-robin over all runs (so that a change of machine
#: load hits every technique alike); its wall time is the minimum.
DEFAULT_REPEATS = 5
#: The runs that calibrate the unit times of the fixed-step work (each fixed-step technique's
#: run with the most work among those within 1° of the reference) are repeated this many times
#: in all, interleaved: their minimum is then steady to a few per cent whatever the load.
CALIBRATION_REPEATS = 15
#: Runs whose modelled costs are within this factor of the cheapest are a tie: the verdict then
#: names the technique listed first (the modelled cost's calibration is not finer than this).
TIE_RATIO = 1.2

COLUMNS = ("technique", "method", "h_s", "tolerance", "max_error_rad", "max_error_deg",
           "rms_error_rad", "rms_error_deg", "peak_error_deg", "final_torque_error_nm", "stable",
           "guard_exceeded", "max_step_over_tau", "steps", "rhs_body", "rhs_muscle",
           "newton_iterations", "jacobians", "lu_decompositions", "calibration_run",
           "modelled_cost_s",
           "wall_time_s", "wall_time_median_s", "wall_time_max_s", "wall_times_s", "status")

#: The work whose unit times are calibrated: (name, what it counts). Fixed-step runs count
#: steps per kernel (the monolithic loop and the partitioned loop have their own per-step
#: overhead), body and muscle evaluations, Newton iterations and the implicit body part's
#: linearisations with their factorisations (imex-ros2); SciPy runs count steps,
#: right-hand-side calls and LU factorisations.
FIXED_STEP_WORK = (("step.monolithic", lambda r: r["steps"] * runs_monolithic(r["method"])),
                   ("step.partitioned",
                    lambda r: r["steps"] * (not runs_monolithic(r["method"]))),
                   ("body", lambda r: r["rhs_body"]), ("muscle", lambda r: r["rhs_muscle"]),
                   ("newton", lambda r: r["newton_iterations"]),
                   ("jacobian", lambda r: r["jacobians"]))
ADAPTIVE_WORK = (("step", lambda r: r["steps"]), ("call", lambda r: r["rhs_body"]),
                 ("lu", lambda r: r["lu_decompositions"]))


def default_steps(model: ChainModel) -> tuple[float, ...]:
    """The study's steps on ``model``, s: those of `DEFAULT_STEPS` that divide its duration;
    where fewer than `MIN_DEFAULT_STEPS` do, each other one is replaced by the largest step
    below it that divides the duration (`divisor_step`; 20 ms → 19.64 ms on a 0.55 s jump)."""
    from ..solvers.simulation import divisor_step

    duration = model.duration

    def divides(h: float) -> bool:
        try:
            step_count(duration, h)
        except ModelError:
            return False
        return True

    dividing = [h for h in DEFAULT_STEPS if divides(h)]
    if len(dividing) >= MIN_DEFAULT_STEPS:
        return tuple(dividing)
    return tuple(sorted({divisor_step(duration, h) for h in DEFAULT_STEPS if h <= duration},
                        reverse=True))


def joint_error_columns(model: ChainModel) -> tuple[str, ...]:
    """Per-joint error columns of the study table, ``max_error_deg_<joint>``."""
    return tuple(f"max_error_deg_{j.name}" for j in model.joints)


def reference_solution(model: ChainModel, initial_state=None):
    return simulate(model, "reference", rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL,
                    output_step=GRID, initial_state=initial_state)


def _errors(result, reference) -> dict:
    """Errors on the times both grids share (multiples of the least common multiple of h and
    the 1 ms reference grid): max and RMS over all joints, the max per joint, the peak-angle
    error (largest over joints) and the final net-torque error (largest over joints)."""
    h = Fraction(result.step or GRID).limit_denominator(10**9)
    grid = Fraction(GRID).limit_denominator(10**9)
    spacing = Fraction(math.lcm(h.numerator * grid.denominator, grid.numerator * h.denominator),
                       h.denominator * grid.denominator)
    k_res = int(spacing / h)
    k_ref = int(spacing / grid)
    n = min((result.time.size - 1) // k_res, (reference.time.size - 1) // k_ref) + 1
    err = result.q[::k_res][:n] - reference.q[::k_ref][:n]
    joints = result.model.joints
    res_cols, ref_cols = result.columns(), reference.columns()
    torque = max(abs(res_cols[f"torque_net_{j.name}"][-1] - ref_cols[f"torque_net_{j.name}"][-1])
                 for j in joints)
    max_err = float(np.max(np.abs(err)))
    rms = float(np.sqrt(np.mean(err**2)))
    peaks = np.max(result.q, axis=0) - np.max(reference.q, axis=0)
    peak = math.degrees(float(peaks[np.argmax(np.abs(peaks))]))
    out = {"max_error_rad": max_err, "max_error_deg": math.degrees(max_err),
           "rms_error_rad": rms, "rms_error_deg": math.degrees(rms), "peak_error_deg": peak,
           "final_torque_error_nm": float(torque)}
    for k, j in enumerate(joints):
        out[f"max_error_deg_{j.name}"] = math.degrees(float(np.max(np.abs(err[:, k]))))
    return out


def _wall_time(result) -> float:
    """The kernel's own wall-time reading of a run, s (the study's default timer)."""
    return result.cost.wall_time


def run_study(model, *, steps=DEFAULT_STEPS, tolerances=DEFAULT_TOLERANCES,
              techniques=None, repeats: int = DEFAULT_REPEATS, initial_state=None,
              progress: Callable[[int, int, str], None] | None = None,
              timer: Callable[[object], float] = _wall_time) -> tuple[list[dict], object]:
    """Run every technique at every step/tolerance on ``model`` (any chain); return (rows,
    reference). Rows have `COLUMNS` and the per-joint `joint_error_columns`.

    Every run is made ``repeats`` times, round-robin over all runs (the first round gives the
    errors and the work counts, which do not change between repeats); its wall time is the
    minimum over the repeats, with the median, the maximum and every reading. ``timer(result)``
    reads a run's wall time (default: the kernel's own reading; tests inject noise here).
    ``modelled_cost_s`` is filled by `calibrate`. ``progress(done, total, label)`` is
    called after each run."""
    model = as_chain(model)
    columns = COLUMNS + joint_error_columns(model)
    techniques = study_techniques() if techniques is None else techniques
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ModelError("repeats", f"must be a whole number ≥ 1, got {repeats!r}")
    for h in steps:
        step_count(model.duration, h)
    reference = reference_solution(model, initial_state)
    jobs = [(t, s) for t in techniques for s in (
        CONTROLLED_TOLERANCES if t.error_controlled else tolerances if t.adaptive else steps)]
    rows: list[dict] = []
    times: list[list[float]] = [[] for _ in jobs]
    total = repeats * len(jobs)
    for round_ in range(repeats):
        for i, (tech, setting) in enumerate(jobs):
            result = _run(model, tech, setting, initial_state)
            times[i].append(float(timer(result)))
            if round_ == 0:
                rows.append(_row(tech, setting, result, reference, model))
            if progress:
                what = f"tol {setting:g}" if tech.adaptive else f"h {setting * 1e3:g} ms"
                progress(round_ * len(jobs) + i + 1, total, f"{tech.name} {what}")
    calibration = _calibration_jobs(rows, jobs)
    rounds = max(0, CALIBRATION_REPEATS - repeats)
    for round_ in range(rounds):
        for k, i in enumerate(calibration):
            tech, setting = jobs[i]
            times[i].append(float(timer(_run(model, tech, setting, initial_state))))
            if progress:
                progress(round_ * len(calibration) + k + 1, rounds * len(calibration),
                         f"calibration {tech.name}")
    for i, (row, readings) in enumerate(zip(rows, times, strict=True)):
        row["calibration_run"] = i in calibration
        row.update(wall_time_s=min(readings), wall_time_median_s=float(np.median(readings)),
                   wall_time_max_s=max(readings), wall_times_s=tuple(readings))
    calibrate(rows)
    return [{c: row.get(c) for c in columns} for row in rows], reference


def _run(model, tech: Technique, setting: float, initial_state):
    """One run of the study: ``tech`` at step (rtol; atol of an error-controlled technique)
    ``setting``, no advice and no accuracy check (the study measures the error against its
    reference itself)."""
    kwargs = dict(initial_state=initial_state, check=False, advise=False, tolerance=None)
    if tech.error_controlled:
        kwargs.update(atol=setting, output_step=GRID)
    elif tech.adaptive:
        kwargs.update(rtol=setting, atol=setting * 1e-3, output_step=GRID)
    else:
        kwargs.update(step=setting, coupling=tech.coupling)
    return simulate(model, tech.method, **kwargs)


def _calibration_jobs(rows: list[dict], jobs) -> list[int]:
    """Indices of the runs that calibrate the fixed-step unit times: per fixed-step technique
    its run with the most steps among those within 1° of the reference (or, if none is, its
    run with the most steps)."""
    picks = []
    for tech in dict.fromkeys(t for t, _ in jobs):
        if tech.adaptive:
            continue
        mine = [i for i, (t, _) in enumerate(jobs) if t is tech]
        good = [i for i in mine if rows[i]["stable"] and not rows[i]["guard_exceeded"]]
        picks.append(max(good or mine, key=lambda i: rows[i]["steps"]))
    return picks


def _row(tech: Technique, setting: float, result, reference, model) -> dict:
    """A study row of one run: its settings, work counts, guard and errors."""
    row = {"technique": tech.name, "method": tech.method,
           "h_s": None if tech.adaptive else setting,
           "tolerance": setting if tech.adaptive else None,
           "steps": result.cost.steps, "rhs_body": result.cost.rhs_body,
           "rhs_muscle": result.cost.rhs_muscle,
           "newton_iterations": result.cost.newton_iterations,
           "jacobians": result.cost.jacobians,
           "lu_decompositions": result.cost.lu_decompositions,
           "status": result.status,
           "guard_exceeded": bool(result.stability and result.stability.exceeded),
           "max_step_over_tau": (result.stability.max_step_ratio
                                 if result.stability else None)}
    if result.success:
        row.update(_errors(result, reference))
        row["stable"] = row["max_error_deg"] <= STABLE_ERROR_DEG
    else:
        row.update({k: math.inf for k in ("max_error_rad", "max_error_deg",
                                          "rms_error_rad", "rms_error_deg",
                                          *joint_error_columns(model))})
        row.update(peak_error_deg=math.nan, final_torque_error_nm=math.nan, stable=False)
    return row


def calibrate(rows: list[dict]) -> dict[str, float]:
    """Time of one unit of each kind of work, s, fitted in the same run to every run's minimum
    wall time, and each row's ``modelled_cost_s`` = Σ count × time per unit.

    Fixed-step runs: wall ≈ c_step,kernel·steps + c_body·(body evaluations) +
    c_muscle·(muscle evaluations) + c_newton·(Newton iterations) + c_jacobian·(the body's
    linearisations and their factorisations, imex-ros2), the per-step overhead
    separate for the monolithic and the partitioned loop (`FIXED_STEP_WORK`); SciPy runs:
    wall ≈ c_step·steps + c_call·calls + c_lu·(LU factorisations). Non-negative least squares
    on the relative errors (every run weighs alike), over the rows marked ``calibration_run``
    (`CALIBRATION_REPEATS` readings each) where there are any. Returns the coefficients
    by name (``fixed.body`` …)."""
    from scipy.optimize import nnls

    coefficients: dict[str, float] = {}
    for kind, work, adaptive in (("fixed", FIXED_STEP_WORK, False),
                                 ("scipy", ADAPTIVE_WORK, True)):
        mine = [r for r in rows if (r["h_s"] is None and scipy_solver(r.get("method") or
                                                                    "scipy:") is not None)
                == adaptive and r.get("wall_time_s")]
        if not mine:
            continue
        fit = [r for r in mine if r.get("calibration_run")] or mine
        a = np.array([[float(count(r) or 0) for _, count in work] for r in fit])
        wall = np.array([r["wall_time_s"] for r in fit])
        used = np.any(a > 0.0, axis=0)
        c = np.zeros(len(work))
        scale = a[:, used].max(axis=0)
        solution, _ = nnls(a[:, used] / scale / wall[:, None], np.ones(wall.size))
        c[used] = solution / scale
        coefficients.update({f"{kind}.{name}": float(v)
                             for (name, _), v in zip(work, c, strict=True)})
        for r in mine:
            r["modelled_cost_s"] = float(np.array([float(count(r) or 0) for _, count in work])
                                         @ c)
    return coefficients


def observed_order(rows: list[dict], technique: str, floor: float = 1e-11,
                   min_r_squared: float = 0.98) -> float | None:
    """Slope of log(max error) against log(h) over the asymptotic range, or None when the runs
    show none.

    The range starts from the smallest step and takes the runs that finished within the RK4
    stability guard, stopping at the first jump of the error by more than (h ratio)^4.5 (the
    onset of instability, which no consistent scheme here shows). Errors below ``floor`` are
    round-off and skipped. A slope is reported only for a power law: at least 2 points, the
    error growing with every step increase and, from 3 points, a log-log fit with
    R² ≥ ``min_r_squared``.
    Monolithic RK4 on the default curl fails this: below its stability limit the error sits
    at a floor set by the model's kinks, not by h (docs/model.md §5)."""
    runs = sorted((r["h_s"], r["max_error_rad"], r["status"] == "success"
                   and not r["guard_exceeded"]) for r in rows
                  if r["technique"] == technique and r["h_s"])
    pts: list[tuple[float, float]] = []
    for h, err, ok in runs:
        if not ok or not math.isfinite(err):
            break
        if err <= floor:
            continue
        if pts and err / pts[-1][1] > (h / pts[-1][0]) ** 4.5:
            break
        pts.append((h, err))
    if len(pts) < 2:
        return None
    h, e = np.array(pts).T
    if not np.all(np.diff(e) > 0.0):
        return None
    fit = linregress(np.log(h), np.log(e))
    return float(fit.slope) if fit.rvalue ** 2 >= min_r_squared else None


def stability_limit(rows: list[dict], technique: str) -> float | None:
    """Largest h whose run, and every run at a smaller h, stays within 1° of the reference."""
    runs = sorted((r["h_s"], r["stable"]) for r in rows
                  if r["technique"] == technique and r["h_s"])
    limit = None
    for h, stable in runs:
        if not stable:
            break
        limit = h
    return limit


def _setting(row) -> str:
    if row["h_s"]:
        return f"h = {row['h_s'] * 1e3:g} ms"
    if row.get("method") and scipy_solver(row["method"]) is None:  # error-controlled: atol
        return f"atol = {row['tolerance']:g} rad"
    return f"rtol = {row['tolerance']:g}"


def verdict(rows: list[dict], targets=ACCURACY_TARGETS_DEG, cost: str = "modelled_cost_s",
            tie: float = TIE_RATIO) -> list[dict]:
    """For each accuracy target (max angle error, degrees): the cheapest run of every technique
    that meets it (within the stability guard), ranked by ``cost`` (default the modelled cost,
    which does not move with machine load).

    Runs within the factor ``tie`` of the cheapest are a tie, resolved by the order in which
    the techniques appear in ``rows`` (the abstract's first), so that the verdict does not
    depend on timing noise. Each entry: ``target_deg``, ``winner``, ``runner_up``, ``ranking``,
    ``ratios`` (cost of each technique's best run over the winner's), ``tie`` (the runner-up is
    within ``tie``), ``wall_ratio`` (ratio of minimum wall times, runner-up over winner) and
    ``wall_ratio_range`` (its lowest and highest over the interleaved repeats)."""
    order = {name: i for i, name in enumerate(dict.fromkeys(r["technique"] for r in rows))}
    out = []
    for target in targets:
        best: dict[str, dict] = {}
        for r in rows:
            if r["status"] != "success" or r["max_error_deg"] > target or r["guard_exceeded"]:
                continue
            mine = best.get(r["technique"])
            if mine is None or (r[cost], -(r["h_s"] or r["tolerance"])) < \
                    (mine[cost], -(mine["h_s"] or mine["tolerance"])):
                best[r["technique"]] = r
        ranking = sorted(best.values(), key=lambda r: (r[cost], order[r["technique"]]))
        if ranking:
            cheapest = ranking[0][cost]
            tied = [r for r in ranking if r[cost] <= tie * cheapest]
            first = min(tied, key=lambda r: order[r["technique"]])
            ranking = [first, *(r for r in ranking if r is not first)]
        entry = {"target_deg": target, "ranking": ranking, "winner": None, "runner_up": None,
                 "ratios": {}, "tie": False, "wall_ratio": None, "wall_ratio_range": None}
        if ranking:
            win = entry["winner"] = ranking[0]
            entry["ratios"] = {r["technique"]: r[cost] / win[cost] for r in ranking[1:]}
        if len(ranking) > 1:
            second = entry["runner_up"] = ranking[1]
            entry["tie"] = max(win[cost], second[cost]) <= tie * min(win[cost], second[cost])
            entry["wall_ratio"] = second["wall_time_s"] / win["wall_time_s"]
            paired = [a / b for a, b in zip(second.get("wall_times_s") or (),
                                             win.get("wall_times_s") or (), strict=False)]
            if paired:
                entry["wall_ratio_range"] = (min(paired), max(paired))
        out.append(entry)
    return out


VERDICT_COLUMNS = ("target_deg", "cheapest", "cheapest_setting", "modelled_cost_ms",
                   "max_error_deg", "wall_time_ms", "runner_up", "runner_up_setting",
                   "cost_ratio", "tie", "wall_time_ratio", "wall_time_ratio_low",
                   "wall_time_ratio_high")


def verdict_table(verdicts: list[dict]) -> list[dict]:
    """The verdict as rows of `VERDICT_COLUMNS` (``verdict.csv``): per accuracy target
    the cheapest technique and its setting, its modelled cost, the runner-up and the cost
    ratio, and the measured wall-time ratio with its range over the interleaved repeats."""
    out = []
    for v in verdicts:
        w, r = v["winner"], v["runner_up"]
        low, high = v["wall_ratio_range"] or (None, None)
        out.append({
            "target_deg": v["target_deg"],
            "cheapest": w["technique"] if w else "none reached it",
            "cheapest_setting": _setting(w) if w else None,
            "modelled_cost_ms": w["modelled_cost_s"] * 1e3 if w else None,
            "max_error_deg": w["max_error_deg"] if w else None,
            "wall_time_ms": w["wall_time_s"] * 1e3 if w else None,
            "runner_up": r["technique"] if r else None,
            "runner_up_setting": _setting(r) if r else None,
            "cost_ratio": v["ratios"][r["technique"]] if r else None,
            "tie": v["tie"], "wall_time_ratio": v["wall_ratio"],
            "wall_time_ratio_low": low, "wall_time_ratio_high": high})
    return out


def verdict_sentences(verdicts: list[dict], techniques: list[str]) -> list[str]:
    """The verdict in words, one sentence per accuracy target."""
    lines = []
    for v in verdicts:
        target = v["target_deg"]
        if v["winner"] is None:
            lines.append(f"{target:g}°: no technique reached it in the steps tried.")
            continue
        w = v["winner"]
        work = f"{w['rhs_body']} body + {w['rhs_muscle']} muscle evaluations"
        if w.get("newton_iterations"):
            work += f" + {w['newton_iterations']} Newton iterations"
        text = (f"{target:g}°: cheapest is {w['technique']} ({_setting(w)}, modelled cost "
                f"{w['modelled_cost_s'] * 1e3:.3g} ms: {work})")
        if v["tie"]:
            r = v["runner_up"]
            text += (f"; a tie with {r['technique']} ({_setting(r)}), whose modelled cost is "
                     f"within {TIE_RATIO:g}× (ratio {v['ratios'][r['technique']]:.2f})")
        parts = [f"{name} {ratio:.1f}× dearer" for name, ratio in v["ratios"].items()
                 if not (v["tie"] and name == v["runner_up"]["technique"])]
        if parts:
            text += "; " + ", ".join(parts)
        if v["wall_ratio_range"]:
            low, high = v["wall_ratio_range"]
            text += (f" (measured wall time of the runner-up {v['wall_ratio']:.2g}× the "
                     f"cheapest's, {low:.2g}–{high:.2g}× over the repeats)")
        missing = [t for t in techniques if t != w["technique"] and t not in v["ratios"]]
        if missing:
            text += "; never reached by " + ", ".join(missing)
        lines.append(text + ".")
    return lines
