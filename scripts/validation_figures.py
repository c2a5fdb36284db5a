"""The figures of docs/validation.md, drawn from the same independent checks the tests run.

    python scripts/validation_figures.py    # needs the test extra (sympy): pip install -e ".[test]"

Writes into docs/figures/:

- ``validation_sympy.png``: a 3-segment chain driven by prescribed joint torques, integrated
  with torquesim's equations of motion and with an independent model built with
  ``sympy.physics.mechanics`` (Kane's method, tests/test_chain.py): the angles, and their
  difference on a log scale.
- ``validation_energy.png``: the default curl (monolithic RK4, 0.05 ms): the change of the
  total energy (kinetic, gravity, SE, end stops; tests/conftest.py, written without the
  solver's mass matrix) beside the work the contractile elements did, and their difference.
- ``validation_reference.png``: the default curl with every technique at its default step
  against the converged Radau solution (rtol 1e-11): the error over time.

Prints the largest difference of each and writes the figures with their captions and these
numbers into the ``validation-figures`` block of docs/validation.md.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # the independent implementations live in tests/
import matplotlib  # noqa: E402
from docblocks import write_blocks  # noqa: E402  (scripts/)

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from tests.conftest import ce_power, chain_energy  # noqa: E402
from tests.test_chain import chain, sympy_rhs, torquesim_rhs  # noqa: E402

import torquesim as ts  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
ALT_SYMPY = ("Joint angles of a 3-segment chain under prescribed joint torques, from torquesim "
             "and from an independent sympy model, and their difference on a log scale.")
ALT_ENERGY = ("Change of the total energy of the default curl beside the work of the "
              "contractile elements, and their difference.")
ALT_REFERENCE = ("Error of the elbow angle against the converged Radau solution over time for "
                 "monolithic RK4, partitioned RK4 and IMEX.")


def sympy_figure() -> float:
    n = 3
    model = chain(n)
    y0 = np.concatenate([[j.initial_angle for j in model.joints], 0.5 * np.ones(n)])
    grid = np.linspace(0.0, 1.0, 201)
    runs = [solve_ivp(rhs, (0.0, 1.0), y0, method="DOP853", rtol=1e-12, atol=1e-12,
                      t_eval=grid) for rhs in (torquesim_rhs(model), sympy_rhs(model))]
    ours, kane = runs[0].y[:n], runs[1].y[:n]
    difference = np.abs(ours - kane)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for j in range(n):
        line, = top.plot(grid, np.degrees(ours[j]), lw=2.5, alpha=0.5,
                         label=f"joint {j + 1}, torquesim")
        top.plot(grid, np.degrees(kane[j]), ls="--", color=line.get_color(),
                 label=f"joint {j + 1}, sympy (Kane)")
        bottom.semilogy(grid, np.maximum(difference[j], 1e-16), color=line.get_color(),
                        label=f"joint {j + 1}")
    top.set_ylabel("joint angle (deg)")
    top.set_title("3-segment chain under prescribed torques: torquesim against sympy")
    top.legend(fontsize=7, ncol=2, loc="best")
    bottom.set_ylabel("|difference| (rad)")
    bottom.set_xlabel("time (s)")
    bottom.axhline(1e-8, color="k", lw=0.8, ls=":")
    bottom.text(0.01, 1.3e-8, "test tolerance 1e-8 rad", fontsize=7)
    bottom.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(FIGURES / "validation_sympy.png", dpi=110)
    plt.close(fig)
    return float(difference.max())


def energy_figure() -> tuple[float, float]:
    result = ts.simulate(ts.default_model(), "monolithic", 5e-5)
    energy = chain_energy(result)
    power = ce_power(result)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1])
                                            * np.diff(result.time))])
    change = energy - energy[0]
    gap = change - work
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(result.time, change, lw=2.5, alpha=0.6, label="change of total energy")
    top.plot(result.time, work, ls="--", color="k", label="work of the contractile elements")
    top.set_ylabel("energy (J)")
    top.set_title("Default curl: energy balance (monolithic RK4, 0.05 ms)")
    top.legend(fontsize=8, loc="upper right")
    bottom.plot(result.time, gap * 1e9, color="C3")
    bottom.set_ylabel("difference (nJ)")
    bottom.set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(FIGURES / "validation_energy.png", dpi=110)
    plt.close(fig)
    return float(np.abs(gap).max()), float(np.ptp(energy))


def reference_figure() -> dict[str, float]:
    model = ts.default_model()
    truth = ts.simulate(model, "reference", rtol=1e-11, atol=1e-13)
    runs = {"monolithic RK4, 0.1 ms": ts.simulate(model, "monolithic", 1e-4),
            "partitioned RK4, 0.1 ms": ts.simulate(model, "partitioned", 1e-4),
            "IMEX, 1 ms": ts.simulate(model, "imex", 1e-3)}
    fig, ax = plt.subplots(figsize=(7, 3.8))
    worst = {}
    for (label, run), style in zip(runs.items(), ("-", "--", ":"), strict=True):
        error = np.abs(np.interp(truth.time, run.time, run.q[:, 0]) - truth.q[:, 0])
        worst[label] = float(error.max())
        ax.semilogy(truth.time, np.degrees(np.maximum(error, 1e-14)), ls=style, label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|elbow angle − Radau| (deg)")
    ax.set_title("Default curl against the converged Radau solution (rtol 1e-11)")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(FIGURES / "validation_reference.png", dpi=110)
    plt.close(fig)
    return worst


def main() -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    print(f"load average {os.getloadavg()[0]:.2f}")
    kane = sympy_figure()
    print(f"sympy (Kane) against torquesim, 3 segments, 1 s: max |Δq| {kane:.2g} rad")
    gap, swing = energy_figure()
    print(f"energy balance, default curl: max |ΔE − W_CE| {gap:.3g} J of a {swing:.1f} J "
          f"swing ({gap / swing:.1e})")
    worst = reference_figure()
    for label, error in worst.items():
        print(f"{label}: max |Δq| against Radau {error:.2g} rad ({np.degrees(error):.2g} deg)")
    mono, part, imex = worst.values()
    block = f"""The figures are drawn by `python scripts/validation_figures.py` from the same
independent implementations the tests use; it also writes the numbers in these captions.

![{ALT_SYMPY}](figures/validation_sympy.png)

*A 3-segment chain with point loads, driven by prescribed joint torques for 1 s and integrated
by DOP853 at rtol 1e-12 with torquesim's equations of motion and with sympy's (Kane's method):
the largest difference is {kane:.2g} rad (the test asks 1e-8 rad).*

![{ALT_ENERGY}](figures/validation_energy.png)

*The default curl, monolithic RK4 at 0.05 ms: the energy the arm and dumbbell gain and give
back ({swing:.1f} J swing) equals the work of the contractile elements to {gap:.2g} J
({gap / swing:.1e} of the swing; the test asks 1e-4).*

![{ALT_REFERENCE}](figures/validation_reference.png)

*The default curl with each technique against Radau at rtol 1e-11: monolithic RK4 at 0.1 ms
stays within {mono:.2g} rad, IMEX at 1 ms within {imex:.2g} rad; plain partitioned RK4 at
0.1 ms is off by up to {part:.2g} rad ({np.degrees(part):.1f}°), the failure the
[study](study.md) measures, and the run warns about it.*
"""
    write_blocks("docs/validation.md", {"validation-figures": block})
    print("wrote docs/figures/validation_{sympy,energy,reference}.png")


if __name__ == "__main__":
    main()
