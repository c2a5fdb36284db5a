"""Accuracy against cost of every solution technique (the abstract's question).

Each technique runs over a range of fixed steps (or tolerances, for adaptive solvers) and is
compared with a high-accuracy reference (Radau, rtol 1e-11). The table has one row per
(technique, step or tolerance); :func:`verdict` turns it into the answer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from scipy.stats import linregress

from ..model.chain import ChainModel, as_chain
from ..solvers import Coupling, simulate
from ..solvers.coupling import IMEX
from ..solvers.simulate import step_count

DEFAULT_STEPS = (20e-3, 10e-3, 5e-3, 2e-3, 1e-3, 0.5e-3, 0.2e-3, 0.1e-3, 0.05e-3)
DEFAULT_TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
ACCURACY_TARGETS_DEG = (1.0, 0.1, 0.01, 0.001)
#: A run whose max angle error exceeds this is counted unstable: RK4 past its stability limit
#: stays bounded (the clamps), so "bounded" is not enough.
STABLE_ERROR_DEG = 1.0
REFERENCE_RTOL, REFERENCE_ATOL = 1e-11, 1e-13
GRID = 1e-3  # s, the reference output grid

COLUMNS = ("technique", "h_s", "tolerance", "max_error_rad", "max_error_deg", "rms_error_rad",
           "rms_error_deg", "peak_error_deg", "final_torque_error_nm", "stable",
           "guard_exceeded", "max_step_over_tau", "rhs_body", "rhs_muscle", "steps",
           "wall_time_s", "status")


@dataclass(frozen=True)
class Technique:
    """One solution technique of the study: a method and, for partitioned, its coupling."""

    name: str
    method: str
    coupling: Coupling | None = None

    @property
    def adaptive(self) -> bool:
        return self.method.startswith("scipy:")


def default_techniques() -> tuple[Technique, ...]:
    """The abstract's two techniques, the partitioned variants, IMEX (body explicit RK4,
    muscles implicit SDIRK2) and two adaptive solvers."""
    return (
        Technique("monolithic", "monolithic"),
        Technique("partitioned", "partitioned", Coupling()),
        Technique("partitioned[body-first]", "partitioned", Coupling(order="body-first")),
        Technique("partitioned[linear]", "partitioned", Coupling(predictor="linear")),
        Technique("partitioned[m=4]", "partitioned", Coupling(muscle_substeps=4)),
        Technique("partitioned[iter=3]", "partitioned", Coupling(iterations=3)),
        Technique("imex", "imex", IMEX),
        Technique("DOP853", "scipy:DOP853"),
        Technique("Radau", "scipy:Radau"),
    )


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


def run_study(model, *, steps=DEFAULT_STEPS, tolerances=DEFAULT_TOLERANCES,
              techniques=None, repeats: int = 3, initial_state=None,
              progress: Callable[[int, int, str], None] | None = None
              ) -> tuple[list[dict], object]:
    """Run every technique at every step/tolerance on ``model`` (any chain); return (rows,
    reference). Rows have :data:`COLUMNS` and the per-joint :func:`joint_error_columns`.
    ``progress(done, total, label)`` is called after each run."""
    model = as_chain(model)
    columns = COLUMNS + joint_error_columns(model)
    techniques = default_techniques() if techniques is None else techniques
    for h in steps:
        step_count(model.duration, h)
    reference = reference_solution(model, initial_state)
    rows = []
    jobs = [(t, s) for t in techniques for s in (tolerances if t.adaptive else steps)]
    for i, (tech, setting) in enumerate(jobs):
        kwargs = dict(initial_state=initial_state, check=False, advise=False)
        if tech.adaptive:
            kwargs.update(rtol=setting, atol=setting * 1e-3, output_step=GRID)
        else:
            kwargs.update(step=setting, coupling=tech.coupling)
        runs = [simulate(model, tech.method, **kwargs) for _ in range(repeats)]
        result = runs[0]
        row = {"technique": tech.name, "h_s": None if tech.adaptive else setting,
               "tolerance": setting if tech.adaptive else None,
               "rhs_body": result.cost.rhs_body, "rhs_muscle": result.cost.rhs_muscle,
               "steps": result.cost.steps,
               "wall_time_s": float(np.median([r.cost.wall_time for r in runs])),
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
        rows.append({c: row.get(c) for c in columns})
        if progress:
            what = f"tol {setting:g}" if tech.adaptive else f"h {setting * 1e3:g} ms"
            progress(i + 1, len(jobs), f"{tech.name} {what}")
    return rows, reference


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


def verdict(rows: list[dict], targets=ACCURACY_TARGETS_DEG,
            cost: str = "wall_time_s") -> list[dict]:
    """For each accuracy target (max angle error, degrees): the cheapest run of every technique
    that meets it, the winner and how many times cheaper it is than each other technique."""
    out = []
    for target in targets:
        best: dict[str, dict] = {}
        for r in rows:
            if r["status"] != "success" or r["max_error_deg"] > target or r["guard_exceeded"]:
                continue
            if r["technique"] not in best or r[cost] < best[r["technique"]][cost]:
                best[r["technique"]] = r
        ranking = sorted(best.values(), key=lambda r: r[cost])
        entry = {"target_deg": target, "ranking": ranking, "winner": None, "ratios": {}}
        if ranking:
            win = ranking[0]
            entry["winner"] = win
            entry["ratios"] = {r["technique"]: r[cost] / win[cost] for r in ranking[1:]}
        out.append(entry)
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
        setting = (f"h = {w['h_s'] * 1e3:g} ms" if w["h_s"] else f"tol = {w['tolerance']:g}")
        parts = [f"{name} {ratio:.1f}× dearer" for name, ratio in v["ratios"].items()]
        missing = [t for t in techniques if t != w["technique"] and t not in v["ratios"]]
        text = (f"{target:g}°: cheapest is {w['technique']} ({setting}, "
                f"{w['wall_time_s'] * 1e3:.2f} ms, {w['rhs_body']} body + {w['rhs_muscle']} "
                f"muscle evaluations)")
        if parts:
            text += "; " + ", ".join(parts)
        if missing:
            text += "; never reached by " + ", ".join(missing)
        lines.append(text + ".")
    return lines
