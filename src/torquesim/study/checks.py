"""How well `torquesim.simulate`'s default checks catch wrong runs.

Every fixed-step technique — monolithic RK4, IMEX, IMEX with the body on ROS2, and every
coupling variant of the partitioned technique (order × predictor × iterations × muscle
solver) — at a range of steps, simulated with `simulate`'s default arguments and compared
with a Radau reference. A run more than `WRONG_RAD` off must carry a warning (or be
refused); a warning on a run within `RIGHT_RAD` is a false alarm.
"""

from __future__ import annotations

import itertools
import math

from ..model.chain import as_chain
from ..solvers import Coupling, simulate
from ..solvers.simulation import SimulationError
from .compare import GRID, _errors, reference_solution

CHECK_STEPS = (20e-3, 10e-3, 5e-3, 2e-3, 1e-3, 0.5e-3, 0.25e-3)
#: A run this far off (max angle error, rad) is wrong: it must not be silent.
WRONG_RAD = 0.1
#: A warning on a run within this (rad) is a false alarm.
RIGHT_RAD = 0.01


def check_techniques() -> list[tuple[str, str, Coupling | None]]:
    """(name, method, coupling) of monolithic, IMEX, imex-ros2 and every coupling variant."""
    out = [("monolithic", "monolithic", None), ("imex", "imex", None),
           ("imex-ros2", "imex-ros2", None)]
    for order, predictor, sweeps, solver in itertools.product(
            ("jacobi", "body-first", "muscles-first"), ("hold", "linear"), (1, 3),
            ("rk4", "sdirk2")):
        coupling = Coupling(order=order, predictor=predictor, iterations=sweeps,
                            muscle_solver=solver)
        out.append((f"partitioned[{order},{predictor},iter={sweeps},{solver}]", "partitioned",
                    coupling))
    return out


def check_study(model, steps=CHECK_STEPS, progress=None, advise: bool = True,
                techniques=None, reference=None) -> list[dict]:
    """One row per (technique, step): the true max angle error (rad), whether the run
    warned or was refused, the estimate, and the verdict (``caught``, ``missed``,
    ``false alarm``, ``quiet`` or ``warned`` for runs between the two thresholds).
    ``techniques``: (name, method, coupling) triples, default `check_techniques`;
    ``reference``: the run to measure against (on a 1 ms grid), default the study's.

    ``advise=False`` skips `simulate`'s search for a step to recommend. That search runs
    only on a run that already failed or broke the stability limit, which warns (or is
    refused) either way, so no verdict changes; it only saves time (a few seconds per
    unstable run)."""
    model = as_chain(model)
    reference = reference_solution(model) if reference is None else reference
    if not math.isclose(reference.time[1], GRID):
        raise ValueError(f"the reference's grid is {reference.time[1]} s; allowed: {GRID} s")
    rows = []
    jobs = [(t, h) for t in (techniques or check_techniques()) for h in steps]
    for i, ((name, method, coupling), h) in enumerate(jobs):
        try:
            run = simulate(model, method, h, coupling=coupling, advise=advise)
            error = _errors(run, reference)["max_error_rad"]
            warned, message = bool(run.message), run.message
            estimate = run.settings.get("estimated_error_rad")
        except SimulationError as exc:
            error, warned, message, estimate = math.inf, True, f"refused: {exc}", None
        if error > WRONG_RAD:
            outcome = "caught" if warned else "missed"
        elif error <= RIGHT_RAD:
            outcome = "false alarm" if warned else "quiet"
        else:
            outcome = "warned" if warned else "quiet"
        rows.append({"technique": name, "h_s": h, "max_error_rad": error,
                     "estimated_error_rad": estimate, "warned": warned, "outcome": outcome,
                     "message": message})
        if progress:
            progress(i + 1, len(jobs), f"{name} h {h * 1e3:g} ms")
    return rows
