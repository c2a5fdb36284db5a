"""The registry of solution techniques: one entry per technique, read by `simulate`, the
command line's ``--method`` choices, the study, the fit, the sweep, the docs and the tests.

A new coupling scheme is a `Coupling` option (or a step loop) plus one entry here: the study
then runs it, and the convergence test (tests/test_techniques.py) measures its order on the
smooth cases against the ``order`` declared here.
"""

from __future__ import annotations

from dataclasses import dataclass

from .coupling import IMEX, Coupling

#: The fixed-step methods `simulate` takes (the adaptive ones are "reference" and
#: "scipy:NAME").
FIXED_STEP_METHODS = ("monolithic", "partitioned", "imex")
#: SciPy solvers (``scipy.integrate`` classes) usable on the whole system (``scipy:NAME``);
#: ``reference`` is Radau.
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
#: Every ``method`` name `simulate` accepts besides ``scipy:NAME``.
METHODS = (*FIXED_STEP_METHODS, "reference")
#: The methods a fit or a sweep may use (fixed step: the population runs in compiled code).
FIT_METHODS = ("imex", "monolithic", "partitioned")


@dataclass(frozen=True)
class Technique:
    """One solution technique.

    Attributes
    ----------
    name : str
        The name in tables, figures and the study's results (e.g. ``partitioned[linear]``).
    method : str
        The ``method`` argument of `simulate`.
    coupling : Coupling or None
        The ``coupling`` argument of `simulate` (partitioned and IMEX), else None.
    parts : str
        How the body (q, q̇) and muscle (θ_cc) equations are integrated, in words.
    order : int or None
        Global order of accuracy on smooth problems (declared; measured by the tests); None
        for the adaptive solvers.
    implicit : str
        Which part is solved implicitly: "none", "muscles" or "all".
    in_study : bool
        Run by ``torquesim compare`` by default.
    headline : bool
        Named in the one-line summaries of ``compare --vary``.
    """

    name: str
    method: str
    coupling: Coupling | None = None
    parts: str = ""
    order: int | None = None
    implicit: str = "none"
    in_study: bool = True
    headline: bool = False

    @property
    def adaptive(self) -> bool:
        return self.method.startswith("scipy:") or self.method == "reference"


_EXPLICIT = "body RK4 and muscles RK4, each on its own, exchanging"
TECHNIQUES: tuple[Technique, ...] = (
    Technique("monolithic", "monolithic", None,
              "one state vector (q, q̇, θ_cc), classical RK4", 4, headline=True),
    Technique("partitioned", "partitioned", Coupling(),
              f"{_EXPLICIT} at step starts (Jacobi, zero-order hold)", 1, headline=True),
    Technique("partitioned[body-first]", "partitioned", Coupling(order="body-first"),
              f"{_EXPLICIT}: body first, muscles see its new angle (Gauss-Seidel)", 1),
    Technique("partitioned[muscles-first]", "partitioned", Coupling(order="muscles-first"),
              f"{_EXPLICIT}: muscles first, body sees their new torque (Gauss-Seidel)", 1,
              in_study=False),
    Technique("partitioned[linear]", "partitioned", Coupling(predictor="linear"),
              f"{_EXPLICIT}, signals extrapolated linearly over the step", 2, headline=True),
    Technique("partitioned[m=4]", "partitioned", Coupling(muscle_substeps=4),
              f"{_EXPLICIT}; muscles sub-cycled 4 times per body step", 1),
    Technique("partitioned[iter=3]", "partitioned", Coupling(iterations=3),
              f"{_EXPLICIT}, 3 sweeps per step (waveform relaxation)", 2),
    Technique("partitioned[every-stage]", "partitioned", Coupling(order="every-stage"),
              "body and muscles exchanging at every RK4 stage (monolithic RK4 by another "
              "route)", 4, in_study=False),
    Technique("partitioned[sdirk2]", "partitioned", Coupling(muscle_solver="sdirk2"),
              "body RK4, muscles implicit SDIRK2, exchanging at step starts (zero-order hold)",
              1, "muscles", in_study=False),
    Technique("imex", "imex", IMEX,
              "body explicit RK4, muscles implicit SDIRK2; body first, linear torque "
              "predictor", 2, "muscles", headline=True),
    Technique("DOP853", "scipy:DOP853", None,
              "one state vector, SciPy's adaptive explicit Runge-Kutta of order 8"),
    Technique("Radau", "scipy:Radau", None,
              "one state vector, SciPy's adaptive implicit Radau IIA of order 5",
              implicit="all"),
)


def study_techniques() -> tuple[Technique, ...]:
    """The techniques ``torquesim compare`` runs by default."""
    return tuple(t for t in TECHNIQUES if t.in_study)


def fixed_step_techniques() -> tuple[Technique, ...]:
    """Every registered fixed-step technique (those with a declared order)."""
    return tuple(t for t in TECHNIQUES if not t.adaptive)


def coupling_order(coupling: Coupling) -> int:
    """Global order of a partitioned run under ``coupling`` on smooth problems: 4 when it
    exchanges at every RK4 stage; else 1 with a zero-order hold and one sweep, 2 with linear
    extrapolation or repeated sweeps; SDIRK2 muscles at most 2."""
    if coupling.order == "every-stage":
        return 4
    order = 2 if (coupling.predictor == "linear" or coupling.iterations > 1) else 1
    return min(order, 2) if coupling.implicit_muscles else order


def nominal_order(method: str, coupling: Coupling | None) -> int:
    """The declared order of a fixed-step run (registered technique or `coupling_order`)."""
    if method == "monolithic":
        return 4
    for t in fixed_step_techniques():
        if t.method == method and t.coupling == coupling:
            return t.order
    return coupling_order(coupling or (IMEX if method == "imex" else Coupling()))
