"""Butcher tableaus of the fixed-step schemes, as data (Hairer, Nørsett & Wanner, Solving
Ordinary Differential Equations I, §II.1–II.2; Hairer & Wanner II, §IV.6).

A Runge-Kutta method of s stages is its tableau (A, b, c): stage i evaluates f at
t + c_i·h and y + h·Σ_j a_ij·k_j, the step adds h·Σ_i b_i·k_i. Its order p is the largest
for which the order conditions up to p hold (`ButcherTableau.order_defects`); its stability
function R(z) = 1 + z·bᵀ(I − zA)⁻¹·1 gives the linear stability limits the solvers' guards
use (`ButcherTableau.real_stability_limit`).

The compiled step loops (`torquesim.solvers.monolithic`, `torquesim.solvers.partitioned`)
read their coefficients here: classical RK4 for the body, the monolithic state and explicit
muscles; the two-stage L-stable SDIRK2 for the implicit muscles (IMEX); the Rosenbrock method
ROS2 of the implicit body part (its γ; `ros2_amplification`). The registry of techniques
(`torquesim.solvers.techniques`) takes its declared orders from them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ButcherTableau:
    """A Runge-Kutta method (A, b, c) of ``order`` (declared; `order_defects` checks it).

    Attributes
    ----------
    name : str
        How tables and docs name it.
    a : tuple of tuple of float
        The s × s matrix A (row i: the weights of stages j in stage i).
    b : tuple of float
        The s weights of the step.
    c : tuple of float
        The s stage times as fractions of the step (c_i = Σ_j a_ij).
    order : int
        Its global order p.
    """

    name: str
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    order: int

    def __post_init__(self) -> None:
        s = len(self.b)
        if len(self.c) != s or len(self.a) != s or any(len(row) != s for row in self.a):
            raise ValueError(f"{self.name}: A must be {s} × {s} with b and c of {s}")
        for i, row in enumerate(self.a):
            if not math.isclose(sum(row), self.c[i], rel_tol=0.0, abs_tol=1e-15):
                raise ValueError(f"{self.name}: row {i} of A sums to {sum(row)!r}, c = "
                                 f"{self.c[i]!r}")

    @property
    def stages(self) -> int:
        return len(self.b)

    @property
    def explicit(self) -> bool:
        """A strictly lower triangular: every stage from earlier stages only."""
        return all(self.a[i][j] == 0.0 for i in range(self.stages)
                   for j in range(i, self.stages))

    @property
    def stiffly_accurate(self) -> bool:
        """b equals the last row of A: the step's result is the last stage (R(∞) = 0 when A
        is invertible, so L-stable if A-stable)."""
        return tuple(self.a[-1]) == tuple(self.b)

    def order_defects(self, up_to: int) -> list[float]:
        """The defects of the order conditions of orders 1 … ``up_to`` (at most 5), one per
        rooted tree: Σ b_i·Φ_i(tree) − 1/γ(tree). All zero to rounding up to the method's
        order; some not zero at order + 1."""
        a, b, c = np.array(self.a), np.array(self.b), np.array(self.c)
        conditions = [  # (order, Σ b·Φ, 1/γ), the 17 trees of order ≤ 5
            (1, b.sum(), 1.0),
            (2, b @ c, 1 / 2),
            (3, b @ c**2, 1 / 3), (3, b @ a @ c, 1 / 6),
            (4, b @ c**3, 1 / 4), (4, b @ (c * (a @ c)), 1 / 8), (4, b @ a @ c**2, 1 / 12),
            (4, b @ a @ a @ c, 1 / 24),
            (5, b @ c**4, 1 / 5), (5, b @ (c**2 * (a @ c)), 1 / 10),
            (5, b @ (c * (a @ c**2)), 1 / 15), (5, b @ (c * (a @ a @ c)), 1 / 30),
            (5, b @ (a @ c) ** 2, 1 / 20), (5, b @ a @ c**3, 1 / 20),
            (5, b @ a @ (c * (a @ c)), 1 / 40), (5, b @ a @ a @ c**2, 1 / 60),
            (5, b @ a @ a @ a @ c, 1 / 120),
        ]
        return [float(value - exact) for order, value, exact in conditions if order <= up_to]

    def stability_function(self, z: complex) -> complex:
        """R(z) = 1 + z·bᵀ(I − zA)⁻¹·1: one step of y' = λy multiplies y by R(λh), z = λh."""
        s = self.stages
        solve = np.linalg.solve(np.eye(s) - z * np.array(self.a), np.ones(s))
        return complex(1.0 + z * (np.array(self.b) @ solve))

    def real_stability_limit(self) -> float:
        """The largest x with |R(−x')| ≤ 1 for every 0 ≤ x' ≤ x: the step h ≤ x·τ at which a
        decaying mode of time constant τ stays stable (inf for an A-stable method, whose
        |R| ≤ 1 on the whole negative axis)."""
        from scipy.optimize import brentq

        grid = np.linspace(1e-6, 50.0, 20001)
        outside = [x for x in grid if abs(self.stability_function(-x)) > 1.0 + 1e-12]
        if not outside:
            return math.inf
        first = outside[0]
        return float(brentq(lambda x: abs(self.stability_function(-x)) - 1.0,
                            first - grid[1] + grid[0], first, xtol=1e-15, rtol=1e-15))


#: Classical RK4 (Kutta 1901): c = (0, ½, ½, 1), a_{i,i−1} = c_i, b = (⅙, ⅓, ⅓, ⅙).
RK4 = ButcherTableau("classical RK4",
                     ((0.0, 0.0, 0.0, 0.0), (0.5, 0.0, 0.0, 0.0), (0.0, 0.5, 0.0, 0.0),
                      (0.0, 0.0, 1.0, 0.0)),
                     (1 / 6, 1 / 3, 1 / 3, 1 / 6), (0.0, 0.5, 0.5, 1.0), 4)

_GAMMA = 1.0 - 1.0 / math.sqrt(2.0)
#: The two-stage SDIRK method of order 2 with γ = 1 − 1/√2 (Alexander 1977, SIAM J Numer Anal
#: 14:1006; Hairer & Wanner II §IV.6): A = ((γ, 0), (1 − γ, γ)), stiffly accurate, hence
#: L-stable.
SDIRK2 = ButcherTableau("L-stable SDIRK2", ((_GAMMA, 0.0), (1.0 - _GAMMA, _GAMMA)),
                        (1.0 - _GAMMA, _GAMMA), (_GAMMA, 1.0), 2)

#: γ of ROS2, the two-stage Rosenbrock W-method of order 2 of Verwer, Spee, Blom and
#: Hundsdorfer (1999, SIAM J Sci Comput 20:1456) that the implicit body part runs
#: (`torquesim.solvers.partitioned._body_ros2`): (I − γhJ)·k1 = f(y),
#: (I − γhJ)·k2 = f(y + h·k1) − 2·k1, y_new = y + h·(3/2·k1 + 1/2·k2). γ = 1 + 1/√2 makes it
#: L-stable when J is the exact Jacobian.
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: Its order, with any J (tests/test_tableaus.py checks both from `ros2_amplification`).
ROS2_ORDER = 2


def ros2_amplification(z: complex, w: complex) -> complex:
    """One ROS2 step of y' = λy with J taken as μ multiplies y by this (z = λh, w = μh):
    1 + 2z/d + (z²/2 − z)/d², d = 1 − γw. With w = z its stability function."""
    d = 1.0 - ROS2_GAMMA * w
    return 1.0 + 2.0 * z / d + (0.5 * z * z - z) / (d * d)
