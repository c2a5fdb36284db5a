"""The schemes' Butcher tableaus (torquesim.solvers.tableaus): their orders from the order
conditions, their stability from their stability functions, and the compiled loops reading
the same numbers."""

import math

import numpy as np
import pytest

from torquesim.solvers import fixed_step as fs
from torquesim.solvers import partitioned as pt
from torquesim.solvers.coupling import IMEX, Coupling
from torquesim.solvers.tableaus import RK4, SDIRK2, ButcherTableau
from torquesim.solvers.techniques import coupling_order, method_technique


@pytest.mark.parametrize("tableau", [RK4, SDIRK2], ids=lambda t: t.name)
def test_the_order_conditions_hold_to_the_declared_order_and_not_beyond(tableau):
    """Every order condition (one per rooted tree) up to the declared order holds to
    rounding; one of the next order fails by far more: the declared order is the order."""
    assert max(abs(d) for d in tableau.order_defects(tableau.order)) < 1e-15
    assert max(abs(d) for d in tableau.order_defects(tableau.order + 1)) > 1e-3


def test_rk4_s_stability_function_is_its_taylor_polynomial_and_gives_the_guard_s_limit():
    """Explicit RK4 of order 4 in 4 stages: R(z) = Σ_{k≤4} z^k/k! (independent of the
    tableau's matrix algebra), and the real-axis limit where |R(−x)| = 1 is the constant
    the stability guard uses, 2.785."""
    rng = np.random.default_rng(0)
    for z in rng.normal(0, 2, 6) + 1j * rng.normal(0, 2, 6):
        taylor = sum(z**k / math.factorial(k) for k in range(5))
        assert RK4.stability_function(z) == pytest.approx(taylor, rel=1e-13)
    assert RK4.explicit and not RK4.stiffly_accurate
    assert RK4.real_stability_limit() == pytest.approx(fs.RK4_STABILITY_LIMIT, rel=1e-13)


def test_sdirk2_is_l_stable():
    """SDIRK2 (γ = 1 − 1/√2): R(z) = (1 + (1 − 2γ)z)/(1 − γz)², |R| ≤ 1 on the imaginary
    axis (A-stable: no step limit on a decaying mode), R(z) → 0 as z → −∞ (L-stable: stiff
    modes are damped, not kept oscillating); stiffly accurate."""
    g = SDIRK2.a[0][0]
    assert g == pytest.approx(1 - 1 / math.sqrt(2), rel=1e-15)
    for z in (-0.3 + 0.2j, -5.0, 2j, -40 + 3j):
        assert SDIRK2.stability_function(z) == pytest.approx(
            (1 + (1 - 2 * g) * z) / (1 - g * z) ** 2, rel=1e-13)
    assert max(abs(SDIRK2.stability_function(1j * y)) for y in np.linspace(-1e3, 1e3, 2001)) \
        <= 1.0 + 1e-12
    assert abs(SDIRK2.stability_function(-1e8)) < 1e-7
    assert SDIRK2.real_stability_limit() == math.inf
    assert SDIRK2.stiffly_accurate and not SDIRK2.explicit


def test_the_compiled_loops_use_the_tableaus_numbers():
    """The step loops' stage offsets are c·h exactly, their RK4 combination is h·Σ b·k (to
    rounding), and the muscle part's RK4 and SDIRK2 are the tableaus' (A, b, c)."""
    h = 1.7e-3
    for s in range(RK4.stages):
        assert fs.rk4_stage_offset(s, h) == RK4.c[s] * h
    rng = np.random.default_rng(1)
    for k in rng.normal(0, 100, (20, 4)):
        expected = h * float(np.dot(RK4.b, k))
        assert fs.rk4_increment(*k, h) == pytest.approx(expected, rel=1e-14,
                                                        abs=1e-14 * h * np.abs(k).max())
    # the muscle part runs its solver's tableau itself, the arrays of the tableau's numbers
    for tableau, arrays in ((RK4, (pt._RK4_A, pt._RK4_B, fs._RK4_C)),
                            (SDIRK2, (pt._SDIRK2_A, pt._SDIRK2_B, pt._SDIRK2_C))):
        assert [a.tolist() for a in arrays] == [[list(r) for r in tableau.a], list(tableau.b),
                                                list(tableau.c)]


def test_the_registry_s_orders_come_from_the_tableaus():
    assert method_technique("monolithic").order == RK4.order
    assert coupling_order(Coupling(order="every-stage")) == RK4.order
    assert coupling_order(IMEX) == SDIRK2.order


def test_a_tableau_whose_rows_do_not_sum_to_c_is_refused():
    with pytest.raises(ValueError, match="row 1"):
        ButcherTableau("bad", ((0.0, 0.0), (0.4, 0.0)), (0.5, 0.5), (0.0, 0.5), 1)
