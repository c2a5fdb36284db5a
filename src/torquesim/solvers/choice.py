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
from .techniques import FIT_METHODS, explicit_muscles, method_technique, runs_monolithic

#: Steps tried, s, largest first (each made to divide the duration, `divisor_step`).
STEPS = (20e-3, 10e-3, 5e-3, 2.5e-3, 1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1e-5)
#: The cost of each counted piece of work in body evaluations, rounded from the unit times
#: `torquesim compare` calibrates (docs/study.md: a muscle evaluation costs about a body
#: evaluation, a Newton iteration about a seventh of one, a linearisation with its
#: factorisation and a partitioned step's exchange about three).
WORK_UNITS = {"body": 1.0, "muscle": 1.0, "newton": 0.15, "jacobian": 3.0,
              "partitioned_step": 3.0}


@dataclass(frozen=True)
class Choice:
    """The technique and step chosen for ``accuracy`` (rad, max angle error): ``method``,
    ``step`` (s), the run's estimated max angle error ``error`` (rad) and its counted
    ``work`` (body evaluations, `WORK_UNITS`); ``tried``: every run made, as (method, step,
    estimated error or None for a run that failed or broke the guard, work)."""

    method: str
    step: float
    error: float
    work: float
    accuracy: float
    tried: tuple[tuple[str, float, float | None, float], ...]

    def describe(self) -> str:
        """One line for a command's output."""
        return (f"technique chosen for {math.degrees(self.accuracy):.3g}° (max angle error on "
                f"the model's own motion, estimated): {self.method} at "
                f"{self.step * 1e3:.4g} ms, estimated {math.degrees(self.error):.2g}°, the "
                f"least work of {len(self.tried)} runs tried")


def candidates(model) -> tuple[str, ...]:
    """The techniques a choice weighs: those of `FIT_METHODS` with implicit muscles (the
    units' RK4 limit holds the others at small steps on every motion, docs/model.md §5),
    and of those, one with the contacts in its implicit part only on a body with ground
    contacts (elsewhere its linearisation buys nothing: docs/study.md's curl)."""
    return tuple(m for m in FIT_METHODS if not explicit_muscles(m)
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
        for h in steps:
            run = simulate(model, method, h, check=False, advise=False, tolerance=accuracy)
            work = work_of(run, method)
            usable = run.success and not run.stability.exceeded
            error = run.settings.get("estimated_error_rad", math.inf) if usable else None
            tried.append((method, h, error, work))
            if progress is not None:
                progress(f"{method} at {h * 1e3:.4g} ms: " + (
                    "failed or beyond the stability guard" if error is None
                    else f"estimated {math.degrees(error):.2g}°"))
            if best is not None and work >= best[3]:
                break  # finer steps of this technique only cost more
            if error is not None and error <= accuracy:
                best = (method, h, error, work)
                break
    if best is None:
        return None
    return Choice(*best, accuracy, tuple(tried))
