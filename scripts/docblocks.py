"""Generated blocks of the documentation: the text between ``<!-- generated: NAME -->`` and
``<!-- end generated -->`` in a docs page is written by a script of the repository (the
study by ``scripts/make_docs.py``, the validation figures by ``scripts/validation_figures.py``,
the fit and batch measurements by ``benchmarks/bench_fit.py --write-docs`` and
``benchmarks/bench_batch.py --write-docs``), never typed by hand."""

from __future__ import annotations

import os
import re
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BLOCK = re.compile(r"(<!-- generated: (?P<name>[a-z-]+) -->\n)(?P<body>.*?)"
                   r"(<!-- end generated -->)", re.S)
#: Every generated block, by page (checked by ``scripts/make_docs.py --check`` in CI).
PAGES = {
    "docs/study.md": {"study-verdict", "study-limits", "default-checks", "jump-verdict",
                      "jump-limits", "jump-stiffness"},
    "docs/validation.md": {"validation-figures"},
    "docs/fitting.md": {"fit-benchmark"},
    "docs/batch.md": {"batch-benchmark"},
    "docs/concepts.md": {"techniques"},
}


def techniques_block() -> str:
    """The technique registry (`torquesim.solvers.techniques.TECHNIQUES`) as a table: cheap,
    so ``make_docs.py --check`` also checks that the page shows the registry as it is."""
    from torquesim.solvers.techniques import TECHNIQUES

    lines = ["| technique | `--method` | how the parts are integrated | order | implicit | "
             "in the study |", "|---|---|---|---|---|---|"]
    for t in TECHNIQUES:
        order = "adaptive" if t.order is None else str(t.order)
        # plain text, not code spans: code spans break inside words in narrow table cells
        lines.append(f"| {t.name} | {t.method} | {t.parts} | {order} | {t.implicit} | "
                     f"{'yes' if t.in_study else 'no'} |")
    return ("Every technique torquesim knows, from its registry "
            "(`torquesim.solvers.techniques`; the order is the declared one, which the tests "
            "measure on two smooth cases):\n\n" + "\n".join(lines) + "\n")


def current_block(page: str, name: str) -> str:
    """The body of generated block ``name`` of ``page`` as it stands."""
    text = (ROOT / page).read_text(encoding="utf-8")
    for m in BLOCK.finditer(text):
        if m.group("name") == name:
            return m.group("body")
    raise KeyError(name)


def blocks_in(page: str) -> set[str]:
    """Names of the generated blocks in ``page`` (a path relative to the repository)."""
    text = (ROOT / page).read_text(encoding="utf-8")
    return {m.group("name") for m in BLOCK.finditer(text)}


def missing_blocks() -> list[str]:
    """Pages whose generated blocks differ from `PAGES`, one message each."""
    problems = []
    for page, wanted in PAGES.items():
        found = blocks_in(page)
        if found != wanted:
            problems.append(f"{page}: generated blocks {sorted(found)}; expected "
                            f"{sorted(wanted)}")
    return problems


def write_blocks(page: str, blocks: dict[str, str]) -> None:
    """Replace the bodies of the named generated blocks of ``page``."""
    path = ROOT / page
    text = path.read_text(encoding="utf-8")
    missing = set(blocks) - blocks_in(page)
    if missing:
        raise SystemExit(f"{page}: no generated block {sorted(missing)}")
    text = BLOCK.sub(lambda m: m.group(1) + blocks.get(m.group("name"), m.group("body"))
                     + m.group(4), text)
    path.write_text(text, encoding="utf-8")
    print(f"rewrote {page} ({', '.join(sorted(blocks))})")


def measured_on(load_start: float) -> str:
    """'2026-12-01, 2 cores, load 0.8 → 1.1': when and under what load a block was measured."""
    return (f"{datetime.now(UTC).date()}, {os.cpu_count()} cores, load average "
            f"{load_start:.2f} → {os.getloadavg()[0]:.2f}")
