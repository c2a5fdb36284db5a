"""How the partitioned technique exchanges data between the body and the muscle parts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, check_range
from . import coupling_layout as fs

ORDERS = {"jacobi": fs.JACOBI, "body-first": fs.BODY_FIRST, "muscles-first": fs.MUSCLES_FIRST,
          "every-stage": fs.EVERY_STAGE}
PREDICTORS = {"hold": fs.HOLD, "linear": fs.LINEAR}
MUSCLE_SOLVERS = {"rk4": fs.EXPLICIT_RK4, "sdirk2": fs.SDIRK2}
BODY_SOLVERS = {"rk4": fs.EXPLICIT_RK4, "ros2": fs.ROS2}


@dataclass(frozen=True)
class Coupling:
    """The exchange between the two parts of the partitioned technique (docs/model.md §4).

    Attributes
    ----------
    order : str
        ``"jacobi"`` (default): both parts start from the step-start values;
        ``"body-first"`` / ``"muscles-first"``: sequential (Gauss-Seidel), the second part sees
        the first part's new values (linearly interpolated over the step);
        ``"every-stage"``: exchange at every RK4 stage, which is monolithic RK4 written through
        the two parts (not a partitioned scheme: it runs the monolithic loop, and the other
        options do not apply to it).
    predictor : str
        What a part sees of a signal not yet advanced in this step: ``"hold"`` (default,
        zero-order hold of the step-start value) or ``"linear"`` (extrapolated from the last
        step's change).
    muscle_substeps : int
        m RK4 sub-steps of the muscle part per body step (sub-cycling). Default 1. Bounds [1, 1000].
    iterations : int
        Maximum sweeps of the exchange within a step (waveform relaxation). Default 1.
        Bounds [1, 100].
    tolerance : float
        Stop sweeping when the end-of-step state changes by less than this (rad); 0 means
        always make ``iterations`` sweeps. Default 0. Bounds [0, inf).
    muscle_solver : str
        How the muscle part is integrated over a step: ``"rk4"`` (default, explicit classical
        RK4, stable only for step/τ ≤ 2.785) or ``"sdirk2"`` (the L-stable two-stage SDIRK
        method of order 2, one scalar implicit equation per unit and stage solved by
        safeguarded Newton: no stability limit from the muscles). ``"sdirk2"`` with the body
        on explicit RK4 is the IMEX technique.
    body_solver : str
        How the body part is integrated over a step: ``"rk4"`` (default, explicit classical
        RK4, stable only for step/τ ≤ 2.785 of the ground contacts and end stops) or
        ``"ros2"`` (the two-stage Rosenbrock W-method ROS2, order 2, linearly implicit in the
        forces of the end stops and the ground contacts, whose Jacobian it factorises once per
        step: no stability limit from them; docs/model.md §4). The IMEX technique with the
        body on ROS2 is ``imex-ros2``.
    """

    order: str = "jacobi"
    predictor: str = "hold"
    muscle_substeps: int = 1
    iterations: int = 1
    tolerance: float = 0.0
    muscle_solver: str = "rk4"
    body_solver: str = "rk4"

    def __post_init__(self) -> None:
        if self.order not in ORDERS:
            raise ModelError("order", f"{self.order!r} is not one of {', '.join(ORDERS)}")
        if self.muscle_solver not in MUSCLE_SOLVERS:
            raise ModelError("muscle_solver", f"{self.muscle_solver!r} is not one of "
                             f"{', '.join(MUSCLE_SOLVERS)}")
        if self.body_solver not in BODY_SOLVERS:
            raise ModelError("body_solver", f"{self.body_solver!r} is not one of "
                             f"{', '.join(BODY_SOLVERS)}")
        for name in ("muscle_solver", "body_solver"):
            if self.order == "every-stage" and getattr(self, name) != "rk4":
                raise ModelError(name, f"order 'every-stage' is monolithic RK4; allowed {name} "
                                 "there: rk4")
        if self.predictor not in PREDICTORS:
            raise ModelError("predictor",
                             f"{self.predictor!r} is not one of {', '.join(PREDICTORS)}")
        for name, high in (("muscle_substeps", 1000), ("iterations", 100)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ModelError(name, f"must be a whole number in [1, {high}], got {value!r}")
            check_range(name, value, 1, high)
        check_range("tolerance", self.tolerance, 0.0, unit="rad")

    def to_array(self) -> np.ndarray:
        a = np.zeros(fs.COUPLING_SIZE)
        a[fs.ORDER] = ORDERS[self.order]
        a[fs.PREDICTOR] = PREDICTORS[self.predictor]
        a[fs.MUSCLE_SUBSTEPS] = self.muscle_substeps
        a[fs.ITERATIONS] = self.iterations
        a[fs.TOLERANCE] = self.tolerance
        a[fs.MUSCLE_SOLVER] = MUSCLE_SOLVERS[self.muscle_solver]
        a[fs.BODY_SOLVER] = BODY_SOLVERS[self.body_solver]
        return a

    @property
    def implicit_muscles(self) -> bool:
        return self.muscle_solver != "rk4"

    @property
    def implicit_body(self) -> bool:
        """The body part linearly implicit in its stiff forces (end stops, contacts)."""
        return self.body_solver != "rk4"

    def label(self) -> str:
        """Short name, e.g. ``partitioned`` or ``partitioned[body-first,linear,m=4]``."""
        parts = []
        if self.order != "jacobi":
            parts.append(self.order)
        if self.predictor != "hold":
            parts.append(self.predictor)
        if self.muscle_substeps != 1:
            parts.append(f"m={self.muscle_substeps}")
        if self.iterations != 1:
            parts.append(f"iter={self.iterations}" + (f",tol={self.tolerance:g}"
                                                       if self.tolerance else ""))
        if self == IMEX:
            return "imex"
        if self == IMEX_ROS2:
            return "imex-ros2"
        if self.implicit_muscles:
            parts.append(self.muscle_solver)
        if self.implicit_body:
            parts.append(f"body={self.body_solver}")
        return "partitioned" + (f"[{','.join(parts)}]" if parts else "")


#: The IMEX technique (``method="imex"``): body on explicit RK4, muscles on implicit SDIRK2.
IMEX = Coupling(order="body-first", predictor="linear", muscle_solver="sdirk2")
#: IMEX with the body part on ROS2 (``method="imex-ros2"``): the units and the body's stiff
#: forces (end stops, ground contacts) implicit, the rest of the body explicit.
IMEX_ROS2 = Coupling(order="body-first", predictor="linear", muscle_solver="sdirk2",
                     body_solver="ros2")
