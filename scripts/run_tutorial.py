"""Run every command of docs/tutorial.md as written, in a fresh folder, and check the files
each one says it writes.

    python scripts/run_tutorial.py [--keep DIR]

Every ``torquesim ...`` line of the page's ```bash blocks (continuation lines joined, comments
dropped) is run in a new empty folder holding a copy of ``examples/``, in page order; the
install lines (``git clone``, ``python -m venv``, ``pip install``) are what CI itself does and
are skipped. A command must exit 0 and every ``--out``/``--plot``/``--animate``/``--grf``
path it names must exist afterwards. Exit code 0 when all pass. ``.ci/run`` runs it.
"""

from __future__ import annotations

import argparse
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "tutorial.md"
SKIP = ("git clone", "python -m venv", "pip install", "cd ")


def commands(text: str) -> list[str]:
    """The tutorial's torquesim commands, in page order."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.split(" #")[0].strip()
            if line.startswith("torquesim ") and not line.startswith(SKIP):
                out.append(line)
    return out


def written(command: str) -> list[str]:
    """The paths a command says it writes (--out, --plot, --animate, --grf)."""
    args = shlex.split(command)
    written = ("--out", "--plot", "--animate", "--grf")
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a in written]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, help="run in this folder and keep it")
    args = parser.parse_args(argv)
    todo = commands(PAGE.read_text(encoding="utf-8"))
    if not todo:
        print("no commands found in docs/tutorial.md", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copytree(ROOT / "examples", folder / "examples", dirs_exist_ok=True)
        failed = 0
        for command in todo:
            start = time.perf_counter()
            run = subprocess.run(shlex.split(command), cwd=folder, capture_output=True,
                                 text=True)
            missing = [p for p in written(command) if not (folder / p).exists()]
            ok = run.returncode == 0 and not missing
            failed += not ok
            print(f"{'ok  ' if ok else 'FAIL'} {time.perf_counter() - start:6.1f} s  {command}")
            if not ok:
                print(f"     exit {run.returncode}; missing {missing}; "
                      f"{(run.stderr or run.stdout).strip()[-300:]}")
    print(f"{len(todo)} commands, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
