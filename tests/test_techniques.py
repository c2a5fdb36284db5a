"""The technique registry: every registered fixed-step technique is tested by being
registered. Its order of accuracy is measured on the smooth cases (the elbow, the
shoulder–elbow chain and the elbow with activation dynamics) against the order it declares,
and the registry agrees with the command line, `simulate` and the coupling rule."""

import pytest

import torquesim as ts
from torquesim.solvers.techniques import (
    FIT_METHODS,
    METHODS,
    TECHNIQUES,
    coupling_order,
    fixed_step_techniques,
    nominal_order,
    study_techniques,
)
from torquesim.study import smooth_case, smooth_chain_case

from .conftest import activation_dynamics_case, measured_order

#: Steps of the measurement, coarse for 4th order (finer ones reach the reference's
#: round-off), finer for the low orders (to be in the asymptotic range).
STEPS = {("elbow", True): [2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4],
         ("elbow", False): [1.25e-3, 6.25e-4, 3.125e-4, 1.5625e-4],
         ("activation dynamics", True): [2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4],
         ("activation dynamics", False): [1.25e-3, 6.25e-4, 3.125e-4, 1.5625e-4],
         ("chain", True): [1e-3, 5e-4, 2.5e-4, 1.25e-4],
         ("chain", False): [5e-4, 2.5e-4, 1.25e-4, 6.25e-5]}
#: The elbow, the shoulder–elbow chain, and the elbow whose units have activation dynamics
#: (a unit kind with a state of its own, run by the same loops).
CASES = {"elbow": smooth_case, "chain": smooth_chain_case,
         "activation dynamics": activation_dynamics_case}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("technique", fixed_step_techniques(), ids=lambda t: t.name)
def test_measured_order_is_the_declared_order(technique, case):
    high_order = technique.order >= 4
    slope = measured_order(CASES[case](), technique.method, technique.coupling,
                           STEPS[case, high_order])
    band = 0.5 if high_order else 0.2
    assert technique.order - band < slope < technique.order + band, slope


def test_the_registry_is_consistent():
    names = [t.name for t in TECHNIQUES]
    assert len(set(names)) == len(names)
    for t in fixed_step_techniques():
        assert t.method in METHODS
        if t.method == "partitioned":
            assert t.coupling.label() == t.name  # the name a run reports is the registry's
            assert coupling_order(t.coupling) == t.order
        assert nominal_order(t.method, t.coupling) == t.order
        assert t.implicit.startswith("muscles") == bool(t.coupling and t.coupling.implicit_muscles)
        assert ("contacts" in t.implicit) == bool(t.coupling and t.coupling.implicit_body)
    assert set(FIT_METHODS) <= set(METHODS)
    assert {"monolithic", "partitioned", "imex"} <= {t.name for t in study_techniques()}


def test_the_command_line_offers_the_registered_methods():
    from torquesim.cli import cli

    def choices(command, option="--method"):
        params = cli.commands[command].params if " " not in command else \
            cli.commands[command.split()[0]].commands[command.split()[1]].params
        return tuple(next(p for p in params if option in p.opts).type.choices)

    assert choices("simulate") == METHODS
    assert choices("fit") == FIT_METHODS
    assert choices("batch sweep") == FIT_METHODS


def test_every_registered_technique_runs_under_its_name():
    model = ts.default_model().replace(duration=0.05)
    for t in fixed_step_techniques():
        run = ts.simulate(model, t.method, 5e-4, coupling=t.coupling, tolerance=None,
                          check=False)
        assert run.method == t.name


def test_public_names_are_the_functions_whatever_was_imported_first():
    """The solvers' names are imported on first use (so the CLI reads the registry without
    Numba); no submodule may shadow one (a module ``solvers/simulate.py`` did: ``ts.simulate``
    became the module once the fit had imported it)."""
    import subprocess
    import sys

    code = ("import torquesim.fitting.fit, torquesim.batch.sweep, torquesim.study.compare\n"
            "import torquesim as ts, torquesim.solvers as s\n"
            "assert callable(ts.simulate) and s.simulate is ts.simulate, ts.simulate\n"
            "assert callable(s.step_count) and isinstance(s.TECHNIQUES, tuple)\n"
            "import sys; assert 'numba' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
    light = "import torquesim.cli, sys; assert 'numba' not in sys.modules, 'numba loaded'"
    subprocess.run([sys.executable, "-c", light], check=True)


def test_no_technique_is_named_in_a_comparison_outside_the_registry():
    """Technique identity lives in the registry (`solvers/techniques.py`): no other module
    compares a method or a technique with a registered name written out (``method ==
    "imex"``, ``name in ("Radau", ...)``); they read the registry's lists and constants."""
    import ast
    from pathlib import Path

    from torquesim.solvers.techniques import SCIPY_METHODS

    names = {t.name for t in TECHNIQUES} | {t.method for t in TECHNIQUES} | set(METHODS) \
        | set(SCIPY_METHODS)
    package = Path(ts.__file__).parent
    found = []
    for path in sorted(package.rglob("*.py")):
        if path.name == "techniques.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Compare):
                continue
            for side in (node.left, *node.comparators):
                values = side.elts if isinstance(side, (ast.Tuple, ast.List, ast.Set)) \
                    else [side]
                if any(isinstance(v, ast.Constant) and v.value in names for v in values):
                    found.append(f"{path.relative_to(package)}:{node.lineno}")
    assert not found, found
