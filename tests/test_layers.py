"""The package's layers hold: model < solvers < study/fitting/cli; files through io; figures
only in the plotting modules. Every import statement is read, function-level ones included."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "torquesim"
#: Subpackage → the torquesim subpackages it must not import.
FORBIDDEN = {
    "model": {"solvers", "study", "fitting", "io", "cli", "plots"},
    "solvers": {"study", "fitting", "io", "cli", "plots"},
    "io": {"solvers", "study", "fitting", "cli", "plots"},
    "study": {"cli", "fitting"},
    "fitting": {"cli", "study"},
    "batch": {"cli"},
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


def test_the_layer_check_sees_function_level_imports(tmp_path):
    """The checker itself: a relative import inside a function is found."""
    sample = PACKAGE / "cli.py"
    found = {inner for inner, _ in _imports(sample)}
    assert {"io", "solvers", "model"} <= found
