"""The registry of solution techniques: one entry per technique, read by `simulate`, the
command line's ``--method`` choices, the study, the fit, the sweep, the docs and the tests.

A new coupling scheme is a `Coupling` option (or a step loop) plus one entry here: the study
then runs it, and the convergence test (tests/test_techniques.py) measures its order on the
smooth cases against the ``order`` declared here.
"""

from __future__ import annotations

from dataclasses import dataclass

from .coupling import IMEX, IMEX_ROS2, Coupling
from .tableaus import RK4, ROS2_ORDER, SDIRK2

#: SciPy solvers (``scipy.integrate`` classes) usable on the whole system (``scipy:NAME``);
#: ``reference`` is Radau.
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
#: Those of them fit for stiff problems (implicit, or LSODA switching to BDF).
STIFF_SCIPY_METHODS = ("Radau", "BDF", "LSODA")


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
        for SciPy's solvers; the error-controlled technique's is its step's.
    implicit : str
        Which part is solved implicitly: "none", "muscles", "muscles, end stops, contacts"
        (the body part linearly implicit in those forces) or "all".
    in_study : bool
        Run by ``torquesim compare`` by default.
    headline : bool
        Named in the one-line summaries of ``compare --vary``.
    error_controlled : bool
        A compiled technique whose steps an error estimate chooses (`error_control`): run at
        an angle tolerance (``atol``), not a step.
    """

    name: str
    method: str
    coupling: Coupling | None = None
    parts: str = ""
    order: int | None = None
    implicit: str = "none"
    in_study: bool = True
    headline: bool = False
    error_controlled: bool = False

    @property
    def adaptive(self) -> bool:
        """Its steps chosen by an error estimate (SciPy's solvers and ``imex-ros2-adaptive``):
        run at a tolerance, not a step."""
        return self.error_controlled or scipy_solver(self.method) is not None


#: The ``method`` of the reference solution: SciPy's Radau at tight tolerances.
REFERENCE = "reference"
#: The name of technique 1 with its default coupling (Jacobi, zero-order hold).
PARTITIONED = "partitioned"


def scipy_solver(method: str) -> str | None:
    """The SciPy solver an adaptive ``method`` runs (``reference``: Radau; ``scipy:NAME``:
    NAME, valid or not); None for a fixed-step method."""
    if method == REFERENCE:
        return "Radau"
    return method.split(":", 1)[1] if method.startswith("scipy:") else None


_EXPLICIT = "body RK4 and muscles RK4, each on its own, exchanging"
TECHNIQUES: tuple[Technique, ...] = (
    Technique("monolithic", "monolithic", None,
              "one state vector (q, q̇, θ_cc), classical RK4", RK4.order, headline=True),
    Technique(PARTITIONED, PARTITIONED, Coupling(),
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
              "route)", RK4.order, in_study=False),
    Technique("partitioned[sdirk2]", "partitioned", Coupling(muscle_solver="sdirk2"),
              "body RK4, muscles implicit SDIRK2, exchanging at step starts (zero-order hold)",
              1, "muscles", in_study=False),
    Technique("imex", "imex", IMEX,
              "body explicit RK4, muscles implicit SDIRK2; body first, linear torque "
              "predictor", 2, "muscles", headline=True),
    Technique("imex-ros2", "imex-ros2", IMEX_ROS2,
              "body ROS2 (linearly implicit in the end stops and ground contacts), muscles "
              "implicit SDIRK2; body first, linear torque predictor", 2,
              "muscles, end stops, contacts"),
    Technique("imex-ros2-adaptive", "imex-ros2-adaptive", IMEX_ROS2,
              "imex-ros2's parts at steps chosen by an embedded error estimate (PI "
              "controller), take-off and touchdown located as events", 2,
              "muscles, end stops, contacts", error_controlled=True),
    Technique("DOP853", "scipy:DOP853", None,
              "one state vector, SciPy's adaptive explicit Runge-Kutta of order 8"),
    Technique("Radau", "scipy:Radau", None,
              "one state vector, SciPy's adaptive implicit Radau IIA of order 5",
              implicit="all"),
)


#: The error-controlled technique's angle tolerance, rad: its default, and its smallest (at
#: 1e-10 the squat jump takes 1.2 million steps; below it the round-off of millions of
#: steps, 1e-16 each, approaches the tolerance, and the accuracy check's run at a 4x tighter
#: tolerance takes tens of millions). The default is the loosest of the study's tolerances
#: at which every built-in model passes `simulate`'s default accuracy check (0.5°;
#: tests/test_error_control.py): at 1e-4 the arm raise, a double pendulum swinging freely
#: after its ramps, ended 1.1° off.
ERROR_CONTROL_ATOL = 1.0e-5
MIN_CONTROL_ATOL = 1.0e-10
#: Its default on a body with ground contacts, rad (m for the base's position). The ground
#: force is the contacts' law at the state (k·δ^1.5 of a deflection of millimetres), known only
#: as well as the base's height, so its impulse balances the body's momentum only to about 10-15x
#: atol: 1.5e-3 of the take-off momentum at 1e-4, 5e-7 here on the squat jump, the
#: countermovement jump and the two-joint jump (docs/validation.md, tests/test_error_control.py),
#: the books of IMEX at the jump's default 0.1 ms (2.2e-7). Warm, the jump with its accuracy
#: check takes 0.5 s here, 0.06 s at 1e-4 (an angle error of 0.005°); the study's runs choose
#: their own (`CONTROLLED_TOLERANCES`).
GROUND_CONTROL_ATOL = 5.0e-8
#: Speeds are held to this many times the angle tolerance per second (rad/s per rad): a speed
#: error carried over 3.3 ms moves the angle by the angle tolerance. Chosen on the squat jump
#: and the drop landing (benchmarks/bench_error_control.py): 100, 200, 300, 500, 1000 and 3000
#: tried, 300 the least work at 0.1° and 0.01° on both; 10 cost the jump 3-4x more steps.
VELOCITY_SCALE = 300.0

#: The fixed-step methods `simulate` takes, each the name of its registered default
#: technique (the adaptive ones are "reference" and "scipy:NAME").
FIXED_STEP_METHODS = tuple(t.method for t in TECHNIQUES if not t.adaptive and t.name == t.method)
#: The error-controlled methods (compiled; run at a tolerance, `error_control`).
ERROR_CONTROLLED_METHODS = tuple(t.method for t in TECHNIQUES if t.error_controlled)
#: The angle tolerances (atol, rad) an error-controlled technique is tried at (the study's
#: ladder and `choice`'s), spaced as the steps (1, 2, 5 per decade): its global error follows
#: atol, and a decade of it costs √10 in steps (order 2).
CONTROLLED_TOLERANCES = (2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6)
#: Every ``method`` name `simulate` accepts besides ``scipy:NAME``.
METHODS = (*FIXED_STEP_METHODS, *ERROR_CONTROLLED_METHODS, REFERENCE)
#: The methods a fit, an optimisation or a sweep may use (fixed step: the population runs in
#: compiled code), the IMEX technique, their default, first.
FIT_METHODS = tuple(sorted(FIXED_STEP_METHODS, key=lambda m: m != "imex"))


def method_technique(method: str) -> Technique:
    """The registered technique a compiled ``method`` (fixed-step or error-controlled) runs
    as when no coupling is given (``partitioned``: Jacobi, zero-order hold; ``imex``:
    `IMEX`)."""
    for t in TECHNIQUES:
        if t.name == method and t.method == method and scipy_solver(method) is None:
            return t
    raise ValueError(f"{method!r} is not a compiled method "
                     f"({', '.join(FIXED_STEP_METHODS + ERROR_CONTROLLED_METHODS)})")


def runs_monolithic(method: str) -> bool:
    """True when ``method`` is a fixed-step method whose loop is the monolithic one (one
    state vector, one RK4), not the partitioned loop with its coupling; False for any other
    name."""
    return method in FIXED_STEP_METHODS and method_technique(method).coupling is None


def explicit_muscles(method: str) -> bool:
    """True when ``method`` (with its default coupling) integrates the muscles explicitly:
    its runs are then bound by explicit RK4's stability limit in the units."""
    return method_technique(method).implicit == "none"


def default_coupling(method: str) -> Coupling:
    """The coupling a fixed-step ``method`` runs with unless told otherwise: its registered
    technique's (`IMEX` for ``imex``, the default `Coupling` for ``partitioned``), and the
    default `Coupling` for ``monolithic``, which ignores it."""
    return method_technique(method).coupling or Coupling()


def study_techniques() -> tuple[Technique, ...]:
    """The techniques ``torquesim compare`` runs by default."""
    return tuple(t for t in TECHNIQUES if t.in_study)


def fixed_step_techniques() -> tuple[Technique, ...]:
    """Every registered fixed-step technique (those with a declared order)."""
    return tuple(t for t in TECHNIQUES if not t.adaptive)


def coupling_order(coupling: Coupling) -> int:
    """Global order of a partitioned run under ``coupling`` on smooth problems: RK4's (4) when
    it exchanges at every RK4 stage; else 1 with a zero-order hold and one sweep, 2 with linear
    extrapolation or repeated sweeps; with SDIRK2 muscles at most SDIRK2's (2)."""
    if coupling.order == "every-stage":
        return RK4.order
    order = 2 if (coupling.predictor == "linear" or coupling.iterations > 1) else 1
    order = min(order, SDIRK2.order) if coupling.implicit_muscles else order
    return min(order, ROS2_ORDER) if coupling.implicit_body else order


def nominal_order(method: str, coupling: Coupling | None) -> int:
    """The declared order of a fixed-step run (registered technique or `coupling_order`)."""
    if runs_monolithic(method):
        return method_technique(method).order
    for t in fixed_step_techniques():
        if t.method == method and t.coupling == coupling:
            return t.order
    return coupling_order(coupling or default_coupling(method))
