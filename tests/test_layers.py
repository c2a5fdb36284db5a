"""The package's layers hold: errors < model < solvers < study/fitting/batch < optimisation
< cli, the side-by-side layers borrowing nothing from each other; files through io; figures
only in the plotting modules; no import circle. Every import statement is read,
function-level ones included, and every subpackage has its entry."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "torquesim"
#: Subpackage → the torquesim subpackages it must not import.
#: ``errors`` is the bottom (every layer raises its errors); ``plots`` draws what the model,
#: solvers and io give it and nothing above; study, fitting and batch sit side by side and do
#: not borrow from each other (batch runs fits, so it may use fitting); optimisation shares
#: the fit's population kernel and ramps and runs on batch's workers.
EVERYTHING = {"model", "solvers", "study", "fitting", "io", "cli", "plots", "batch",
              "optimisation"}
FORBIDDEN = {
    "errors": EVERYTHING,
    "model": {"solvers", "study", "fitting", "io", "cli", "plots", "batch", "optimisation"},
    "solvers": {"study", "fitting", "io", "cli", "plots", "batch", "optimisation"},
    "io": {"solvers", "study", "fitting", "cli", "plots", "batch", "optimisation"},
    "plots": {"study", "fitting", "batch", "cli", "optimisation"},
    "study": {"cli", "fitting", "batch", "optimisation"},
    "fitting": {"cli", "study", "batch", "optimisation"},
    "batch": {"cli", "study", "optimisation"},
    "optimisation": {"cli", "study"},
}
PLOTTING = {"plots.py", "study/report.py", "batch/report.py"}


def _imports(path: Path):
    """(torquesim subpackage or None, top-level module name) of every import in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    part = path.relative_to(PACKAGE).parts
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                top = alias.name.split(".")[0]
                inner = alias.name.split(".")[1] if top == "torquesim" and "." in alias.name \
                    else None
                yield inner, top
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                names = (node.module or "").split(".")
                yield (names[1] if names[0] == "torquesim" and len(names) > 1 else None,
                       names[0])
            else:  # relative: resolve against the module's package
                base = list(part[:-1])[: len(part) - node.level]
                target = base + (node.module.split(".") if node.module else [])
                yield (target[0].removesuffix(".py") if target else None, "torquesim")


MODULES = sorted(p for p in PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_respect_the_layers(path):
    rel = path.relative_to(PACKAGE)
    layer = rel.parts[0] if len(rel.parts) > 1 else rel.stem
    for inner, top in _imports(path):
        assert inner not in FORBIDDEN.get(layer, set()), f"{rel} imports torquesim.{inner}"
        if top == "matplotlib":
            assert rel.as_posix() in PLOTTING, f"{rel} imports Matplotlib"


def test_every_subpackage_has_its_layer():
    """A new subpackage gets an entry (optimisation had none, so nothing was checked)."""
    subpackages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert subpackages <= FORBIDDEN.keys()
    assert subpackages | {"cli", "plots"} == EVERYTHING


def test_the_layer_check_sees_function_level_imports(tmp_path):
    """The checker itself: a relative import inside a function is found."""
    sample = PACKAGE / "cli.py"
    found = {inner for inner, _ in _imports(sample)}
    assert {"io", "solvers", "model"} <= found


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(("torquesim", *parts))


def _module_imports(path: Path) -> set[str]:
    """torquesim modules imported by ``path`` (function-level imports included), resolved to
    module files: ``from .x import y`` is module x, or x.y when y is a module."""
    known = {_module_name(p) for p in MODULES}
    package = _module_name(path) if path.name == "__init__.py" else \
        _module_name(path).rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            for alias in node.names:
                if f"{module}.{alias.name}" in known:
                    out.add(f"{module}.{alias.name}")
                elif module in known:
                    out.add(module)
        elif isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names if alias.name in known}
    out.discard(_module_name(path))
    return out


def test_no_module_imports_run_in_a_circle():
    """No two modules import each other, directly or through others (package __init__ files,
    which only re-export, are left out)."""
    graph = {_module_name(p): {m for m in _module_imports(p)
                               if not (PACKAGE.parent / m.replace(".", "/") / "__init__.py"
                                       ).exists()}
             for p in MODULES if p.name != "__init__.py"}
    state: dict[str, int] = {}
    cycles = []

    def visit(node, trail):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(trail[trail.index(nxt):] + [nxt] if nxt in trail else [node, nxt])
            elif not state.get(nxt):
                visit(nxt, trail + [nxt])
        state[node] = 2

    for start in sorted(graph):
        if not state.get(start):
            visit(start, [start])
    assert not cycles, "import circles: " + "; ".join(" -> ".join(c) for c in cycles)


#: The compiled step loops, one module a technique, and what they share.
STEP_LOOPS = ("solvers/fixed_step.py", "solvers/monolithic.py", "solvers/partitioned.py",
              "solvers/error_control.py", "solvers/step_loop.py")
#: The modules of a unit kind's equations and packed row, and a unit kind's own test.
UNIT_KIND_MODULES = {"torquesim.model.activation", "torquesim.model.torque_generator",
                     "torquesim.model.unit_row"}
UNIT_KIND_NAMES = {"has_activation_state"}


@pytest.mark.parametrize("loop", STEP_LOOPS)
def test_the_step_loops_know_no_unit_kind(loop):
    """The loops step the units through the units' terms only (`rates.unit_rates`,
    `sdirk.unit_implicit_stage`, which write all of a unit's rates): they import nothing from
    the modules of a unit's equations and packed row, nor a test of a unit's kind, so a unit
    kind with states of its own is added without editing a loop."""
    path = PACKAGE / loop
    package = _module_name(path).rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            module = ".".join(base + ([node.module] if node.module else [])) \
                if node.level else node.module
            names = {alias.name for alias in node.names}
            assert module not in UNIT_KIND_MODULES, f"{loop} imports {module}"
            assert not names & UNIT_KIND_NAMES, f"{loop} imports {names & UNIT_KIND_NAMES}"
