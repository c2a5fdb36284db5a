"""The documentation as a reader meets it: the site checker finds what the strict build cannot
see, and the study page's generated blocks are in place."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

needs_chromium = pytest.mark.skipif(
    not any(shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")),
    reason="no Chromium on this machine (scripts/check_site.py needs one)")


@needs_chromium
def test_the_site_checker_finds_raw_math_sentinels_roles_garbling_and_overflowing_cells(
        tmp_path):
    good = tmp_path / "site" / "good"
    bad = tmp_path / "site" / "bad"
    good.mkdir(parents=True)
    bad.mkdir(parents=True)
    (good / "index.html").write_text(
        "<html><body><article><p>T = k·s</p><code>$$x$$ :func: Sentinel.UNSET</code>"
        "</article></body></html>")
    (bad / "index.html").write_text(
        "<html><body><article><p>$$T = k s$$ see :func:`simulate` default Sentinel.UNSET"
        " then q̈ = φ̈<em k_1>k − φ̈</em></p><div class='arithmatex' style='width:60px;"
        "overflow-x:auto'><span style='display:inline-block;width:600px'>T = k s</span></div>"
        "<table style='width:100px;table-layout:fixed'><tr><th style='width:50px;"
        "white-space:nowrap;overflow:hidden'>a_header_far_too_long_for_its_cell</th></tr>"
        "</table><pre style='width:200px'><code style='display:block;overflow-x:auto'>"
        "torquesim simulate --model builtin:squat-jump --method imex --step 0.25ms --animate "
        "jump.gif</code></pre><table style='width:60px;table-layout:fixed'><tr><td>"
        "<code>--weight-effort-of-the-fit</code></td></tr></table>"
        "</article></body></html>")
    run = subprocess.run([sys.executable, str(ROOT / "scripts" / "check_site.py"),
                          str(tmp_path / "site")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    assert all(line.endswith(": OK") for line in lines if line.startswith("good"))
    bad_lines = [line for line in lines if line.startswith("bad")]
    assert len(bad_lines) == 2
    for line in bad_lines:
        assert "raw math" in line and "click sentinel" in line and "raw Sphinx role" in line
        assert "overflows its cell" in line and "garbled markup" in line
        assert "wider than the page" in line
        assert "code line wider than its box" in line and "broken across lines" in line


def test_the_site_checker_reads_the_reference_pages_against_the_code():
    """A Default cell that is not the option's default, a help cut short (at a ``|``, which
    ends a Markdown table cell), an option the page lacks, an API name or option that does
    not exist: each is named."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from check_site import api_reference_problems, cli_reference_problems

    def page(rows):
        cells = "".join(f"<tr><td><code>{n}</code></td><td>t</td><td>{h}</td><td>{d}</td></tr>"
                        for n, h, d in rows)
        return (f"<h3 id='torquesim-compare'>torquesim compare</h3><table><tr><th>Name</th>"
                f"<th>Type</th><th>Description</th><th>Default</th></tr>{cells}</table>")

    import click

    from torquesim.cli import cli

    compare = cli.commands["compare"]
    rows = [(", ".join(o.opts + o.secondary_opts),
             " ".join((o.help or "").replace("`", "").split()),
             "()" if o.multiple else ("None" if o.default is None else str(o.default)))
            for o in compare.get_params(click.Context(compare)) if isinstance(o, click.Option)]
    assert cli_reference_problems(page(rows)) == []
    model = next(i for i, r in enumerate(rows) if r[0] == "--model")
    wrong = list(rows)
    wrong[model] = (rows[model][0], rows[model][1], "knee-extension")
    assert cli_reference_problems(page(wrong)) == [
        "torquesim-compare --model: Default 'knee-extension', the real default "
        "'builtin:elbow-curl'"]
    wrong[model] = (rows[model][0], rows[model][1][:30], rows[model][2])
    assert "is not the whole help" in cli_reference_problems(page(wrong))[0]
    assert cli_reference_problems(page(rows[1:]))[-1].endswith(f"option {rows[0][0]} has no "
                                                              "row")
    assert api_reference_problems(
        "<code>--techniques</code><code>--method</code><code>torquesim.simulate</code>"
        "<code>torquesim.solvers.nothing</code><code>torquesim.model.presets.preset</code>"
    ) == ["api: --techniques is not an option of any command",
          "api: torquesim.solvers.nothing does not exist"]
    # in the text too, and raw reST a renderer left (an attribute section without types put
    # its descriptions in the Type column as ``code``); not in code blocks or styles
    assert api_reference_problems(
        "<table><tr><td>name</td><td>the name in ``--techniques``; see compare --vary</td>"
        "</tr></table><pre>x = ``kept``</pre><style>:root{--md-text-font:x}</style>"
    ) == ["api: raw reST ``--techniques`` in the text (a docstring section numpydoc did not "
          "parse, e.g. an attribute without its type line)",
          "api: --techniques is not an option of any command"]


def test_the_study_page_holds_its_generated_blocks():
    """Every generated block is there and the techniques table is the registry's. The blocks
    regenerated from simulations (the presets' motions, the contacts, the optima) are checked
    by ``make_docs.py --check``, which CI runs beside the suite (.ci/run): here they cost 19 s
    of every run of the suite."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from docblocks import current_block, fields_block, missing_blocks, techniques_block

    assert missing_blocks() == []
    assert current_block("docs/concepts.md", "techniques") == techniques_block()
    assert current_block("docs/model-files.md", "model-fields") == fields_block()
    assert "python scripts/make_docs.py --check" in (ROOT / ".ci" / "run").read_text()


def test_the_study_page_states_the_ladders_the_study_runs():
    """docs/study.md's list of what the study tries: the fixed steps and the error-controlled
    technique's tolerances as `study.compare` and the registry have them (it said 5e-6 after
    the ladder went to 1e-6)."""
    from torquesim.solvers.techniques import CONTROLLED_TOLERANCES
    from torquesim.study.compare import DEFAULT_STEPS

    page = (ROOT / "docs" / "study.md").read_text()
    tolerances = f"atol {CONTROLLED_TOLERANCES[0]:.0e} … {CONTROLLED_TOLERANCES[-1]:.0e} rad"
    assert tolerances.replace("e-0", "e-") in page
    steps = ", ".join(f"{h * 1e3:g}" for h in DEFAULT_STEPS[:-1])
    assert f"Fixed steps: {steps} and {DEFAULT_STEPS[-1] * 1e3:g} ms." in page


def test_the_stated_spread_of_the_optima_holds_what_it_says():
    """docs/data/optimise_spread.json: each case's range holds every kernel set's optimum and
    this machine's, and docs/optimise.md quotes it."""
    import json

    spread = json.loads((ROOT / "docs" / "data" / "optimise_spread.json").read_text())
    page = (ROOT / "docs" / "optimise.md").read_text()
    for case, scale, unit in (("curl", 1e3, "ms"), ("jump", 1e2, "cm")):
        found = spread[case]
        values = [*found["by_kernel_set"].values(), found["this_machine"]]
        assert len(found["by_kernel_set"]) >= 2
        assert found["low"] == min(values) and found["high"] == max(values)
        digits = 1 if unit == "ms" else 2
        assert (f"{found['low'] * scale:.{digits}f}–{found['high'] * scale:.{digits}f} {unit} "
                "across BLAS kernels") in page


def test_the_readme_names_every_dependency_and_the_docs_only_versions_that_exist():
    """Every package pyproject.toml installs (and the test extra) is named in the README's
    list (cmaes was missing); the package's version is the CHANGELOG's newest release and the
    citation's; a "torquesim ≥ X" in the docs names a release no newer than it (model.md
    said ≥ 0.3 of a 0.2.0 package)."""
    import re
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    readme = (ROOT / "README.md").read_text()
    listed = readme[readme.index("Dependencies (all installed"):][:1200].lower()
    for requirement in project["dependencies"] + project["optional-dependencies"]["test"]:
        name = re.split(r"[<>=\[ ]", requirement)[0].lower()
        assert name in listed, f"README's dependency list does not name {name}"
    version = project["version"]
    changelog = (ROOT / "CHANGELOG.md").read_text()
    newest = re.search(r"^## (\S+) \(", changelog, re.MULTILINE).group(1)
    assert newest == version
    assert f"version: {version}" in (ROOT / "CITATION.cff").read_text()
    assert f"version {version}," in (ROOT / "docs" / "references.md").read_text()

    def parts(text):
        return tuple(int(x) for x in text.split("."))

    for page in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]:
        for found in re.findall(r"torquesim ≥ ([0-9.]+)", page.read_text()):
            assert parts(found) <= parts(version)[:len(parts(found))], (page.name, found)


def test_the_extending_page_names_files_and_functions_that_exist():
    """docs/extending.md names the files and functions a new element goes into: each
    ``path.py`` (below src/torquesim, or tests/) exists, and each ``path.py: name`` (and the
    names listed after it) is defined there, so the page cannot go stale silently."""
    import ast
    import re

    page = (ROOT / "docs" / "extending.md").read_text()
    package = ROOT / "src" / "torquesim"
    cited = re.findall(r"`((?:tests|[a-z_]+)/[a-z_/]+\.py|plots\.py)(?:: (\w+))?`"
                       r"((?:, `\w+`)*)", page)
    assert len(cited) > 20
    for path, name, more in cited:
        file = ROOT / path if path.startswith("tests/") else package / path
        assert file.exists(), path
        names = ([name] if name else []) + re.findall(r"`(\w+)`", more)
        if names:
            tree = ast.parse(file.read_text())
            defined = {n.name for n in ast.walk(tree)
                       if isinstance(n, ast.FunctionDef | ast.ClassDef)}
            defined |= {t.id for n in ast.walk(tree) if isinstance(n, ast.Assign)
                        for t in n.targets if isinstance(t, ast.Name)}
            assert set(names) <= defined, (path, set(names) - defined)


def test_the_model_file_page_s_examples_state_the_checked_bounds():
    """The example files on docs/model-files.md write a field's bounds in its comment as the
    model file does: each interval written after a key is that key's, from the tables the
    range checks read (a key of several tables, such as ``distance``, may match any)."""
    import re

    from torquesim.io.model_file import FIELD_TABLES

    allowed: dict[str, set[str]] = {}
    for table in FIELD_TABLES.values():
        for name, values in table.items():
            allowed.setdefault(name, set()).add(values.interval(plain=True))
    page = (ROOT / "docs" / "model-files.md").read_text()
    stated = [(key, interval) for block in re.findall(r"```toml\n(.*?)```", page, re.S)
              for key, comment in re.findall(r"^(\w+) = [^#\n]*#([^\n]*)", block, re.M)
              for interval in re.findall(r"[\[(]-?(?:[\d.]+(?:e\d+)?|2?pi|inf), "
                                         r"-?(?:[\d.]+(?:e\d+)?|2?pi|inf)[\])]", comment)]
    assert len(stated) >= 8
    for key, interval in stated:
        assert interval in allowed.get(key, ()), (key, interval, allowed.get(key))
