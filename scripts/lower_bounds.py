"""Print pip requirements pinning every dependency of ``pyproject.toml`` (and the ``test``
extra) to the lowest release series it allows: ``numpy>=1.26`` becomes ``numpy==1.26.*``.

    python scripts/lower_bounds.py > lower.txt && pip install -r lower.txt

CI installs these in a second virtual environment and runs the fast tests there, so that the
lower bounds the project states are tested, not only the newest releases. ruff (a linter, run
once by CI in the first environment) is left out.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: Test tools not needed to run the tests.
SKIPPED = {"ruff"}


def lower_bounds(pyproject: Path = ROOT / "pyproject.toml") -> list[str]:
    """``name==X.Y.*`` for every ``name>=X.Y`` requirement of the project and its test extra."""
    project = tomllib.loads(pyproject.read_text())["project"]
    out = []
    for requirement in [*project["dependencies"], *project["optional-dependencies"]["test"]]:
        found = re.fullmatch(r"\s*([A-Za-z0-9_.\-]+)\s*>=\s*([0-9.]+)\s*", requirement)
        if not found:
            sys.exit(f"error: {requirement!r} has no plain lower bound (name>=X.Y)")
        name, version = found.groups()
        if name not in SKIPPED:
            out.append(f"{name}=={version}.*")
    return out


if __name__ == "__main__":
    print("\n".join(lower_bounds()))
