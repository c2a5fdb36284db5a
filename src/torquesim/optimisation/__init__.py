"""Optimise a performance: the activation ramps that maximise or minimise goals of the run
(jump height, time to a position, speed, effort) within a window around a starting model.

>>> import torquesim as ts
>>> best = ts.optimise("builtin:elbow-curl", minimise="time_to:elbow=90deg")  # doctest: +SKIP
>>> best.model, best.summary["goals"][0]["reference_gain_percent"]              # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import ModelError
from .goals import GOALS, Constraint, Goal, Trial, parse_constraint, parse_goal
from .problem import ACCURACY, OptimiseProblem, Window
from .search import OptimiseOutcome, OptimiseSettings

__all__ = ["GOALS", "Constraint", "Goal", "OptimiseProblem", "OptimiseSettings", "Optimum",
           "Trial", "Window", "constraints_of", "goals_of", "optimise", "parse_constraint",
           "parse_goal"]


@dataclass
class Optimum:
    """What `optimise` returns: the optimised ``model`` (a `ChainModel`), the search's
    ``outcome`` and the ``summary`` (goals at start and optimum with the reference solver,
    gains, the parameters that carry them, failures; as ``optimise_summary.json``), and the
    files written (when ``out`` was given)."""

    model: object
    outcome: OptimiseOutcome
    summary: dict
    files: list


def goals_of(model, maximise=(), minimise=()) -> tuple[Goal, ...]:
    """Goals from their written forms (`parse_goal`), `Goal` objects or functions of a
    `SimulationResult` (custom goals), to maximise and to minimise."""
    out = []
    for sense, items in ((True, maximise), (False, minimise)):
        if isinstance(items, str | Goal) or callable(items):
            items = (items,)
        for item in items:
            if isinstance(item, Goal):
                out.append(item)
            elif isinstance(item, str):
                out.append(parse_goal(item, model, maximise=sense,
                                      field="maximise" if sense else "minimise"))
            elif callable(item):
                out.append(Goal.custom(item, maximise=sense,
                                       label=getattr(item, "__name__", "custom")))
            else:
                raise ModelError("maximise" if sense else "minimise",
                                 f"{item!r}; allowed: a goal name, a Goal or a function "
                                 "of a SimulationResult")
    senses = {}
    for goal in out:
        if goal.name == "custom":
            continue
        key = (goal.name, goal.joint, goal.angle)
        if senses.setdefault(key, goal.maximise) != goal.maximise:
            raise ModelError("minimise", f"{goal.label!r} is maximised too; "
                             "allowed: each goal in one sense, maximised or minimised")
    return tuple(out)


def constraints_of(model, constrain=()) -> tuple[Constraint, ...]:
    """Constraints from their written forms (``GOAL=LOW..HIGH``, `parse_constraint`) or
    `Constraint` objects."""
    if isinstance(constrain, str | Constraint):
        constrain = (constrain,)
    return tuple(c if isinstance(c, Constraint) else parse_constraint(c, model)
                 for c in constrain)


def optimise(model="builtin:elbow-curl", *, maximise=(), minimise=(),
             method: str | None = None, step: float | None = None,
             accuracy: float = ACCURACY, window: Window | None = None, free=(),
             frozen: dict | None = None, bounds: dict | None = None, robust: int = 0,
             timing_error: float = 0.01, robust_mode: str = "worst", constrain=(),
             endstop_depth: float = 0.0, settings: OptimiseSettings | None = None,
             out: str | Path | None = None, client=None,
             progress: Callable[[str], None] | None = None) -> Optimum:
    """Optimise ``model``'s activation ramps for the goals (see `torquesim.optimisation`).

    ``model``: a `ChainModel`, a model file or ``builtin:NAME``. ``maximise`` / ``minimise``:
    a goal or a list (written forms such as ``"time_to:elbow=90deg"``, `Goal` objects, or
    functions of a `SimulationResult`). ``free``, ``frozen`` (path → value or None for the
    start's), ``bounds`` (path → (low, high); a model field's path is searched too, from
    the static equilibrium of each candidate's own model) and ``window`` say what may move;
    ``robust``
    perturbed copies with onset errors in ±``timing_error`` s make the optimum robust.
    ``constrain``: goals held within bounds (``"com_speed_x_at_takeoff=-0.1..0.1"`` or
    `Constraint` objects); ``endstop_depth``: how many end-stop scales a run may go past an
    end stop (default 0: an optimum does not lean on the passive stop torque). ``method``
    and ``step`` default to the cheapest technique and step whose run of the start is
    within ``accuracy`` (rad, default 0.05°; `OptimiseProblem`). With
    ``out`` the outputs of ``torquesim optimise`` are written there. With a Dask ``client``
    each generation is scored on its workers (the same optimum as here).
    """
    from ..io.model_file import load_model
    from .outputs import optimise_and_write, summarise
    from .search import optimise_population

    window = window or Window()
    settings = settings or OptimiseSettings()
    if isinstance(model, str | Path):
        model = load_model(str(model))
    problem = OptimiseProblem(model, goals_of(model, maximise, minimise), method, step,
                              window, tuple(free), frozen, bounds, robust, timing_error,
                              robust_mode, constraints=constraints_of(model, constrain),
                              endstop_depth=endstop_depth, accuracy=accuracy)
    evaluate = None
    if client is not None:
        from .distributed import DaskScorer

        evaluate = DaskScorer(client, problem)
    if out is not None:
        outcome, summary, files = optimise_and_write(problem, settings, Path(out),
                                                     progress=progress, evaluate=evaluate)
    else:
        outcome = optimise_population(problem, settings, progress=progress,
                                      evaluate=evaluate)
        summary, files = summarise(problem, outcome, settings), []
    return Optimum(summary["_runs"]["optimum"].model, outcome, summary, files)
