"""The cheapest technique and step that meet an accuracy on a model's own motion: what
``torquesim optimise`` and ``torquesim batch sweep`` run when no ``--method`` and ``--step``
are given (docs/study.md answers the same question over every technique).

Each candidate technique runs its model at steps from `STEPS` down (each made to divide the
duration), with `simulate`'s own error estimate (Richardson: against the run at twice the
step, else at half the step); the first step whose run succeeds, stays within the stability
guard and whose estimate meets the accuracy is the candidate's. Of the candidates the one with
the least counted work wins (`WORK_UNITS`: work counts, not wall time, so the choice does not
depend on the machine's load).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import check_range
from .simulation import divisor_step, simulate
from .techniques import (
    CONTROLLED_TOLERANCES,
    ERROR_CONTROLLED_METHODS,
    FIT_METHODS,
    explicit_muscles,
    method_technique,
    runs_monolithic,
)

#: Steps tried, s, largest first (each made to divide the duration, `divisor_step`).
STEPS = (20e-3, 10e-3, 5e-3, 2.5e-3, 1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1e-5)
#: The output grid of a chosen error-controlled technique, s (its rows are interpolated, so
#: a fine grid costs little): that of IMEX at the contacts' usual step.
CONTROLLED_OUTPUT_STEP = 2.5e-4
#: The output grid of the choice's own runs of an error-controlled technique, s.
PILOT_OUTPUT_STEP = 1e-3
#: The cost of each counted piece of work in body evaluations, rounded from the unit times
#: `torquesim compare` calibrates (docs/study.md: a muscle evaluation costs about a body
#: evaluation, a Newton iteration about a seventh of one, a linearisation with its
#: factorisation and a partitioned step's exchange about three).
WORK_UNITS = {"body": 1.0, "muscle": 1.0, "newton": 0.15, "jacobian": 3.0,
              "partitioned_step": 3.0}


@dataclass(frozen=True)
class Choice:
    """The technique and step chosen for ``accuracy`` (rad, max angle error): ``method``,
    ``step`` (s; of an error-controlled technique its output grid), the run's estimated max
    angle error ``error`` (rad) and its counted ``work`` (body evaluations, `WORK_UNITS`);
    ``tried``: every run made, as (method, step or angle tolerance, estimated error or None
    for a run that failed or broke the guard, work); ``atol``: the angle tolerance (rad) of
    an error-controlled technique, else None."""

    method: str
    step: float
    error: float
    work: float
    accuracy: float
    tried: tuple[tuple[str, float, float | None, float], ...]
    atol: float | None = None

    def describe(self) -> str:
        """One line for a command's output."""
        at = f"{self.step * 1e3:.4g} ms" if self.atol is None else f"atol {self.atol:g} rad"
        return (f"technique chosen for {math.degrees(self.accuracy):.3g}° (max angle error on "
                f"the model's own motion, estimated): {self.method} at {at}, estimated "
                f"{math.degrees(self.error):.2g}°, the least work of {len(self.tried)} runs "
                "tried")


def candidates(model, controlled: bool = True) -> tuple[str, ...]:
    """The techniques a choice weighs: those of `FIT_METHODS` with implicit muscles (the
    units' RK4 limit holds the others at small steps on every motion, docs/model.md §5),
    and the error-controlled ones unless ``controlled`` is False; of those, one with the
    contacts in its implicit part only on a body with ground contacts (elsewhere its
    linearisation buys nothing: docs/study.md's curl)."""
    pool = (*FIT_METHODS, *ERROR_CONTROLLED_METHODS) if controlled else FIT_METHODS
    return tuple(m for m in pool
                 if not explicit_muscles(m)
                 and ("contacts" not in method_technique(m).implicit or bool(model.contacts)))


def work_of(run, method: str) -> float:
    """A run's counted work in body evaluations (`WORK_UNITS`)."""
    cost = run.cost
    work = (cost.rhs_body * WORK_UNITS["body"] + cost.rhs_muscle * WORK_UNITS["muscle"]
            + cost.newton_iterations * WORK_UNITS["newton"]
            + cost.jacobians * WORK_UNITS["jacobian"])
    if not runs_monolithic(method):
        work += cost.steps * WORK_UNITS["partitioned_step"]
    return work


def choose_technique(model, accuracy: float, methods=None, progress=None) -> Choice | None:
    """The `Choice` for ``model`` (a chain) at ``accuracy`` (rad), among ``methods`` (default
    `candidates`); None when no step of `STEPS` meets it. ``progress(text)`` hears of each
    run."""
    check_range("accuracy", accuracy, 0.0, math.pi, low_open=True, unit="rad")
    steps = sorted({divisor_step(model.duration, h) for h in STEPS if h <= model.duration},
                   reverse=True)
    best, tried = None, []
    for method in methods or candidates(model):
        controlled = method in ERROR_CONTROLLED_METHODS
        for setting in CONTROLLED_TOLERANCES if controlled else steps:
            if controlled:
                run = simulate(model, method, atol=setting, check=False, tolerance=accuracy,
                               output_step=divisor_step(model.duration, PILOT_OUTPUT_STEP))
                usable = run.success
                what = f"atol {setting:g} rad"
            else:
                run = simulate(model, method, setting, check=False, advise=False,
                               tolerance=accuracy)
                usable = run.success and not run.stability.exceeded
                what = f"{setting * 1e3:.4g} ms"
            work = work_of(run, method)
            error = run.settings.get("estimated_error_rad", math.inf) if usable else None
            tried.append((method, setting, error, work))
            if progress is not None:
                progress(f"{method} at {what}: " + (
                    "failed or beyond the stability guard" if error is None
                    else f"estimated {math.degrees(error):.2g}°"))
            if best is not None and work >= best[3]:
                break  # finer settings of this technique only cost more
            if error is not None and error <= accuracy:
                best = ((method, divisor_step(model.duration, CONTROLLED_OUTPUT_STEP), error,
                         work, setting) if controlled else (method, setting, error, work, None))
                break
    if best is None:
        return None
    method, step, error, work, atol = best
    return Choice(method, step, error, work, accuracy, tuple(tried), atol)
