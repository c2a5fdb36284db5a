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
- ``validation_jump.png``: the squat jump (monolithic RK4, 12.5 µs, as tests/test_ground.py):
  the impulse of the ground force beyond body weight against the change of momentum, and in
  flight the centre of mass's acceleration against −g.
- ``validation_drop.png``: a rigid bar dropped onto two contacts (tests/test_ground.py): its
  energy (kinetic, gravity, contact springs) plus what the contacts' damping and friction
  dissipated, against its energy at the start.

And a table of the squat jump's momentum books kept by each technique (`jump_books`): the
impulse against the change of momentum, the angle error against the reference and the
counted work.

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
from tests.test_ground import dropped_bar, dropped_bar_energy  # noqa: E402

import torquesim as ts  # noqa: E402
from torquesim.solvers.techniques import GROUND_CONTROL_ATOL  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
ALT_SYMPY = ("Joint angles of a 3-segment chain under prescribed joint torques, from torquesim "
             "and from an independent sympy model, and their difference on a log scale.")
ALT_ENERGY = ("Change of the total energy of the default curl beside the work of the "
              "contractile elements, and their difference.")
ALT_JUMP = ("Impulse of the ground force beyond body weight against the change of momentum "
            "over the squat jump, and the centre of mass's acceleration in flight against -g.")
ALT_DROP = ("Energy of a rigid bar dropped onto two contacts plus what the contacts "
            "dissipated, against its energy at the start.")
G = 9.81
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


def momentum_series(run) -> tuple[np.ndarray, np.ndarray]:
    """A run's impulse ∫(F_y − m·g) dt from its start (the trapezoid on its output grid, as
    tests/test_ground.py) and its change of momentum m·(v_y − v_y,0), N·s, at every row."""
    c = run.columns()
    mass = sum(s.total_mass for s in run.model.segments)
    net = c["grf_y"] - mass * G
    impulse = np.concatenate([[0.0], np.cumsum(0.5 * (net[1:] + net[:-1]) * np.diff(run.time))])
    return impulse, mass * (c["com_speed_y"] - c["com_speed_y"][0])


def momentum_books(run) -> tuple[float, float]:
    """The largest |∫(F_y − m·g) dt − m·Δv_y| over a run and the largest change of momentum,
    N·s (`momentum_series`)."""
    impulse, change = momentum_series(run)
    return float(np.max(np.abs(impulse - change))), float(np.abs(change).max())


def jump_figure() -> tuple[float, float, float]:
    """The squat jump's momentum books and flight: the largest |impulse − m·Δv_y| (N·s), the
    largest change of momentum (N·s) and the largest |a_com + g| in flight (m/s²)."""
    run = ts.simulate(ts.load_model("builtin:squat-jump"), "monolithic", 1.25e-5)
    c = run.columns()
    impulse, change = momentum_series(run)
    air = np.flatnonzero(c["grf_y"] == 0.0)
    flight = slice(air[0] + 1, air[-1])
    accel = np.diff(c["com_speed_y"])[flight] / run.step
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    a.plot(run.time, impulse, color="k", lw=2.5, label="∫(F_y − m·g) dt")
    a.plot(run.time, change, color="tab:orange", ls="--", label="m·(v_y − v_y,0)")
    a.axvline(run.time[air[0]], color="tab:red", ls=":", label="take-off")
    a.set(xlabel="time (s)", ylabel="N·s", title="impulse = change of momentum")
    a.legend(fontsize=8)
    twin = a.twinx()
    twin.semilogy(run.time, np.abs(impulse - change) + 1e-16, color="tab:grey", lw=0.8)
    twin.set_ylabel("|difference| (N·s)", color="tab:grey")
    b.plot(run.time[1:][flight], accel + G, color="k")
    b.set(xlabel="time (s)", ylabel="a_com,y + g (m/s²)")
    b.set_title("flight: the centre of mass falls at g", pad=16)
    b.ticklabel_format(axis="y", style="sci", scilimits=(0, 0))
    for ax in (a, b):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(FIGURES / "validation_jump.png", dpi=110)
    plt.close(fig)
    return (float(np.max(np.abs(impulse - change))), float(np.abs(change).max()),
            float(np.max(np.abs(accel + G))))


#: The runs of the momentum books' table: (method, step s or None, atol rad or None).
BOOK_RUNS = (("monolithic", 1.25e-5, None), ("imex", 2.5e-4, None), ("imex", 1e-4, None),
             ("imex-ros2", 2.5e-4, None), ("imex-ros2", 1e-4, None),
             ("imex-ros2-adaptive", None, 1e-4), ("imex-ros2-adaptive", None, 1e-5),
             ("imex-ros2-adaptive", None, 1e-6), ("imex-ros2-adaptive", None, 1e-7),
             ("imex-ros2-adaptive", None, GROUND_CONTROL_ATOL))
#: The reference's output grid for the table (divides every fixed step of `BOOK_RUNS`), and
#: the error-controlled runs' output grid (the tests' 0.1 ms).
BOOK_REFERENCE_GRID, BOOK_OUTPUT_GRID = 1.25e-5, 1e-4


def jump_books() -> list[tuple[str, str, float, float, float]]:
    """Each run of `BOOK_RUNS` on the squat jump: (technique, its step or atol, the books'
    largest gap relative to the largest change of momentum, the max angle error against the
    reference in degrees, the counted work in body evaluations, `choice.work_of`)."""
    from torquesim.solvers.choice import work_of

    jump = ts.load_model("builtin:squat-jump")
    reference = ts.simulate(jump, "reference", output_step=BOOK_REFERENCE_GRID)
    rows = []
    for method, step, atol in BOOK_RUNS:
        run = ts.simulate(jump, method, step, atol=atol, tolerance=None,
                          output_step=BOOK_OUTPUT_GRID if step is None else None)
        stride = round((run.time[1] - run.time[0]) / BOOK_REFERENCE_GRID)
        error = float(np.degrees(np.max(np.abs(run.q - reference.q[::stride]))))
        gap, momentum = momentum_books(run)
        setting = f"{step * 1e3:g} ms" if step is not None else \
            f"atol {atol:.0e} rad".replace("e-0", "e-")
        rows.append((method, setting, gap / momentum, error, work_of(run, method)))
    return rows


def drop_figure() -> tuple[float, float, float]:
    """The dropped bar's energy books: the largest |E + dissipated − E0| (J), E0 (J) and the
    energy dissipated (J)."""
    run, contacts = dropped_bar()
    energy, dissipated = dropped_bar_energy(run, contacts)
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    a.plot(run.time, energy, color="tab:blue", label="E: kinetic + gravity + contact springs")
    a.plot(run.time, dissipated, color="tab:orange", label="dissipated by damping, friction")
    a.plot(run.time, energy + dissipated, color="k", lw=2, label="E + dissipated")
    a.set(xlabel="time (s)", ylabel="J", title="a rigid bar dropped onto two contacts")
    a.legend(fontsize=8)
    b.semilogy(run.time, np.abs(energy + dissipated - energy[0]) + 1e-16, color="k")
    b.set(xlabel="time (s)", ylabel="|E + dissipated − E(0)| (J)", title="the books balance")
    for ax in (a, b):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(FIGURES / "validation_drop.png", dpi=110)
    plt.close(fig)
    return (float(np.max(np.abs(energy + dissipated - energy[0]))), float(energy[0]),
            float(dissipated[-1]))


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
    books, momentum, fall = jump_figure()
    print(f"squat jump: max |impulse - m dv| {books:.2g} N s of {momentum:.1f} N s; "
          f"flight max |a + g| {fall:.2g} m/s^2")
    books_rows = jump_books()
    for method, setting, gap, error, work in books_rows:
        print(f"  books {method} {setting}: gap {gap:.2g}, error {error:.2g} deg, "
              f"work {work:.0f}")
    drop, start, lost = drop_figure()
    print(f"dropped bar: max |E + dissipated - E0| {drop:.2g} J of {start:.2f} J "
          f"({lost:.2f} J dissipated)")
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
    table = "\n".join(f"| {m} | {setting} | {gap:.1e} | {error:.2g} | {work:,.0f} |"
                       for m, setting, gap, error, work in books_rows)
    adaptive = {atol: row for (method, step, atol), row in zip(BOOK_RUNS, books_rows, strict=True)
                if method == "imex-ros2-adaptive"}
    loose, default = adaptive[max(adaptive)], adaptive[GROUND_CONTROL_ATOL]
    ground = f"""The figures are drawn by `python scripts/validation_figures.py` (the same runs
the tests make).

![{ALT_JUMP}](figures/validation_jump.png)

*The squat jump, monolithic RK4 at 12.5 µs: the impulse of the ground force beyond body weight
equals the change of the body's momentum to {books:.2g} N·s ({books / momentum:.1e} of the
{momentum:.0f} N·s it gains; the test asks 1e-6); in flight the centre of mass accelerates at
−g to {fall:.1g} m/s² (the test asks 1e-7).*

The same books kept by each technique (the squat jump; the gap relative to the largest
change of momentum, on each run's output grid: its step, or {BOOK_OUTPUT_GRID * 1e3:g} ms for
the error-controlled runs; angle error against Radau; work in body evaluations as
[`optimise` counts it](study.md)):

| technique | step or tolerance | impulse − m·Δv_y | max angle error (°) | work |
|---|---|---|---|---|
{table}

The ground force is the contacts' spring and damper law at the written state, so its impulse
balances the motion's momentum only as closely as the contacts' deflection is known, and their
stiffness multiplies the deflection's error (the position's) into the force's. IMEX's
explicit body (RK4, order 4) keeps the books to {books_rows[1][2]:.1e} at 0.25 ms, within the
contacts' own limit; imex-ros2's implicit body (ROS2, order 2) to {books_rows[3][2]:.1e} at the
same step; and `imex-ros2-adaptive` to {loose[2]:.1e} at {loose[1]} ({loose[2] * 100:.2g} % of
the take-off momentum, at an angle error of {loose[3]:.2g}° and {loose[4] / books_rows[1][4]:.2g}x
the work of IMEX at 0.25 ms). Its
books follow its tolerance, and its default on a body with ground contacts is the tolerance
that keeps them within the 1e-6 the test asks of monolithic RK4 at 12.5 µs: {default[1]},
{default[2]:.1e}, at {default[4] / books_rows[1][4]:.0f}x the work of IMEX at 0.25 ms. A run
after speed, whose ground force need not balance the motion to that precision, gives a
larger `--atol` (the [study](study.md) chooses its own).

![{ALT_DROP}](figures/validation_drop.png)


*A 5 kg bar dropped from 20 cm, tilted and moving sideways, onto Hunt-Crossley contacts with
friction (monolithic RK4 at 10 µs): of its {start:.2f} J, {lost:.2f} J are dissipated by the
contacts' damping and friction, and energy plus dissipation stay within {drop:.2g} J of the
start ({drop / start:.1e}; the test asks 1e-4).*
"""
    write_blocks("docs/validation.md", {"validation-figures": block,
                                        "validation-ground": ground})
    print("wrote docs/figures/validation_{sympy,energy,reference,jump,drop}.png")


if __name__ == "__main__":
    main()
