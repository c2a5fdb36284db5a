"""Read the built documentation site as a reader would: every page in headless Chromium, served
over HTTP, at 1280 and 800 px.

    mkdocs build --strict --site-dir site && python scripts/check_site.py site

A page fails when, after it has loaded and its equations have been typeset:
- text outside code shows raw math (``$$``, ``\\(``, ``\\[``), a KaTeX error, a click sentinel
  (``Sentinel.UNSET``) or a raw Sphinx role (``:func:``, ``:class:``, ``:meth:``, ...);
- markup was garbled (an element with an attribute no HTML element has: Markdown's
  ``attr_list`` read text such as ``x_{k-1}`` as attributes and ate letters around it);
- a figure does not decode;
- the page, a figure, an equation, or the text of a table cell (header cells included) is
  wider than the window or than its cell;
- a line of a code block is wider than its box (the reader would have to scroll it), or an
  identifier in a table cell (``code``) breaks across lines.

Read from the HTML against the code itself:
- the command-line reference (``cli/``): each option row's description is the option's whole
  help (a help cut at a ``|`` fails) and its Default cell the option's real default;
- the API reference (``api/``): every ``torquesim.…`` name in code resolves, and every
  ``--option`` it mentions is an option of some command.
Exit code 0 when every page passes, 1 otherwise, 2 when no Chromium is found (install Debian's
``chromium`` or set ``CHROMIUM``). ``.ci/run`` runs it after the strict build.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import re
import shutil
import sys
import tempfile
import threading
from html.parser import HTMLParser
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from check_pages import WIDTHS, found_chromium, headless  # noqa: E402

CHECK = r"""<script>
function torquesimCheck() {
  const W = document.documentElement.clientWidth, bad = [];
  if (document.documentElement.scrollWidth > W + 1)
    bad.push('page ' + document.documentElement.scrollWidth + ' px wide in a ' + W + ' px window');
  document.querySelectorAll('article img').forEach((im, i) => {
    const n = 'figure ' + (i + 1) + ' (' + im.getAttribute('src') + ')';
    if (!im.complete || im.naturalWidth === 0) bad.push(n + ' does not decode');
    if (im.getBoundingClientRect().right > W + 1) bad.push(n + ' beyond the edge');
  });
  document.querySelectorAll('article th, article td').forEach((c) => {
    if (c.scrollWidth > c.clientWidth + 1)
      bad.push('table cell "' + c.textContent.trim().slice(0, 30) + '" overflows its cell');
  });
  // Markdown's attr_list turns text such as x_{k-1} into attributes of a made-up element
  // (<em k_1>) and eats the letters around it: an attribute no HTML element has gives it away.
  const known = new RegExp('^(class|id|href|src|alt|title|style|width|height|colspan|rowspan'
    + '|align|role|type|name|value|target|rel|lang|dir|tabindex|loading|decoding|srcset|sizes'
    + '|start|for|hidden|open|checked|disabled|download|viewbox|xmlns|d|fill|stroke'
    + '|aria-.*|data-.*)$', 'i');
  document.querySelectorAll('article *').forEach((e) => {
    if (e.closest('.katex, svg, math')) return;
    for (const a of e.attributes)
      if (!known.test(a.name))
        bad.push('garbled markup <' + e.tagName.toLowerCase() + ' ' + a.name + '> near "'
                 + e.textContent.trim().slice(0, 30) + '"');
  });
  document.querySelectorAll('article pre > code').forEach((e) => {
    if (e.scrollWidth > e.clientWidth + 1)
      bad.push('code line wider than its box in "' + e.textContent.trim().slice(0, 40) + '"');
  });
  document.querySelectorAll('article td code, article th code').forEach((e) => {
    if (!/\s/.test(e.textContent.trim()) && e.getClientRects().length > 1)
      bad.push('identifier "' + e.textContent.trim().slice(0, 40) + '" broken across lines');
  });
  document.querySelectorAll('article .katex-display, article .arithmatex').forEach((e) => {
    if (e.scrollWidth > e.clientWidth + 1)
      bad.push('equation "' + e.textContent.trim().slice(0, 30) + '" wider than the page');
  });
  if (document.querySelectorAll('.katex-error').length)
    bad.push(document.querySelectorAll('.katex-error').length + ' equations do not typeset');
  const article = document.querySelector('article');
  if (article) {
    const copy = article.cloneNode(true);
    copy.querySelectorAll('code, pre, .katex, script, style').forEach((e) => e.remove());
    const text = copy.textContent;
    const checks = [['raw math', /\$\$|\\\(|\\\[/], ['click sentinel', /Sentinel\./],
                    ['raw Sphinx role', /:(func|class|meth|mod|attr|data|obj|exc|ref):/]];
    for (const [what, re] of checks) {
      const m = text.match(re);
      if (m) bad.push(what + ' near "' + text.slice(Math.max(0, m.index - 30), m.index + 30)
                      .replace(/\s+/g, ' ') + '"');
    }
  }
  document.body.setAttribute('data-page-check', bad.length ? bad.join('; ') : 'OK');
}
window.addEventListener('load', () => setTimeout(torquesimCheck, 1500));
</script>"""


class _Cells(HTMLParser):
    """Table rows of a page, each with the id of the heading above it: (heading id, [cell
    text]); and the text of every ``code`` element."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[tuple[str | None, list[str]]] = []
        self.codes: list[str] = []
        self._heading = None
        self._row: list[str] | None = None
        self._cell: list[str] | None = None
        self._code: list[str] | None = None

    def handle_starttag(self, tag, attrs) -> None:
        if tag in ("h1", "h2", "h3", "h4") and dict(attrs).get("id"):
            self._heading = dict(attrs)["id"]
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []
        elif tag == "code":
            self._code = []

    def handle_endtag(self, tag) -> None:
        if tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.rows.append((self._heading, self._row))
            self._row = None
        elif tag == "code" and self._code is not None:
            self.codes.append("".join(self._code).strip())
            self._code = None

    def handle_data(self, data) -> None:
        for part in (self._cell, self._code):
            if part is not None:
                part.append(data)


def _commands():
    """Every command of the CLI by its heading id on the reference page (``torquesim-fit``,
    ``torquesim-batch-sweep``), with its options."""
    import click

    from torquesim.cli import cli

    out = {}

    def walk(command, path):
        out["-".join(path)] = [p for p in command.get_params(click.Context(command))
                               if isinstance(p, click.Option)]
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, (*path, name))

    walk(cli, ("torquesim",))
    return out


def _shown_default(option) -> str:
    """The option's default as the reference prints it (a repeatable option with none given:
    "()", its empty tuple)."""
    value = option.default
    if option.multiple and not value:
        return "()"
    if value is None or type(value).__name__ in ("Sentinel", "_Sentinel"):
        return "None"
    return str(value)


def cli_reference_problems(html: str) -> list[str]:
    """Rows of the CLI reference whose description is not the option's whole help or whose
    Default cell is not its real default; options the page lacks or does not know."""
    commands = _commands()
    page = _Cells()
    page.feed(html)
    bad, seen = [], set()
    shown = {heading for heading, _ in page.rows}
    for heading, row in page.rows:
        if heading not in commands or not row or row[0] == "Name":
            continue
        if len(row) != 4:
            bad.append(f"{heading}: a row of {len(row)} cells, not 4: {row[0][:40]!r}")
            continue
        names = {n.strip() for n in row[0].split(",")}
        option = next((o for o in commands[heading] if names & set(o.opts)), None)
        if option is None:
            bad.append(f"{heading}: {row[0]!r} is not an option of the command")
            continue
        seen.add((heading, option.name))
        whole = " ".join((option.help or "").replace("`", "").split())
        if row[2] != whole:
            bad.append(f"{heading} {row[0]}: description {row[2][-40:]!r} is not the whole "
                       f"help (…{whole[-40:]!r})")
        if row[3] != _shown_default(option):
            bad.append(f"{heading} {row[0]}: Default {row[3]!r}, the real default "
                       f"{_shown_default(option)!r}")
    for heading, options in commands.items():
        for option in options if heading in shown else ():
            if (heading, option.name) not in seen and not option.hidden:
                bad.append(f"{heading}: option {option.opts[0]} has no row")
    return bad


def html_text(html: str) -> str:
    """The text of an HTML fragment: tags dropped, entities decoded, spaces collapsed."""
    import html as entities

    return re.sub(r"\s+", " ", entities.unescape(re.sub(r"<[^>]+>", " ", html)))


def api_reference_problems(html: str) -> list[str]:
    """Names in the API reference that do not exist (a ``torquesim.…`` path in code that does
    not resolve, an ``--option`` in code or text that no command has) and raw reST left in
    its text (double backticks: a docstring section the renderer did not parse)."""
    import importlib

    page = _Cells()
    page.feed(html)
    options = {o for opts in _commands().values() for p in opts for o in p.opts}
    bad = []
    prose = html_text(re.sub(r"<(pre|script|style)\b.*?</\1>", " ", html, flags=re.DOTALL))
    for raw in dict.fromkeys(re.findall(r"``[^`]{0,60}``", prose)):
        bad.append(f"api: raw reST {raw} in the text (a docstring section numpydoc did not "
                   "parse, e.g. an attribute without its type line)")
    for option in dict.fromkeys(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", prose)):
        if option not in options:
            bad.append(f"api: {option} is not an option of any command")
    for text in dict.fromkeys(page.codes):
        if re.fullmatch(r"--[a-z][a-z0-9-]*", text) and text not in options:
            bad.append(f"api: {text} is not an option of any command")
        elif re.fullmatch(r"torquesim(\.\w+)+", text):
            parts = text.split(".")
            for cut in range(len(parts), 0, -1):
                try:
                    found = importlib.import_module(".".join(parts[:cut]))
                except ImportError:
                    continue
                try:
                    for attr in parts[cut:]:
                        found = getattr(found, attr)
                except AttributeError:
                    bad.append(f"api: {text} does not exist")
                break
    return list(dict.fromkeys(bad))


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # no line per request
        pass


def _serve(folder: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    handler = functools.partial(_Quiet, directory=str(folder))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("site", type=Path, help="the folder mkdocs built")
    args = parser.parse_args(argv)
    browser = found_chromium()
    if browser is None:
        return 2
    pages = sorted(p.relative_to(args.site) for p in args.site.rglob("index.html"))
    if not pages:
        print(f"no pages under {args.site}", file=sys.stderr)
        return 1
    failed = 0
    for name, check in (("cli", cli_reference_problems), ("api", api_reference_problems)):
        page = args.site / name / "index.html"
        problems = check(page.read_text(encoding="utf-8")) if page.exists() else [
            f"{name}/index.html is missing"]
        failed += bool(problems)
        print(f"{name}/ against the code: " + ("; ".join(problems) if problems else "OK"))
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "site"
        shutil.copytree(args.site, copy)
        for page in pages:
            path = copy / page
            path.write_text(path.read_text(encoding="utf-8").replace("</body>",
                                                                     CHECK + "</body>"),
                            encoding="utf-8")
        server, root = _serve(copy)
        try:
            for page in pages:
                url = f"{root}/{page.parent.as_posix()}/".replace("/./", "/")
                for width in WIDTHS:
                    dom = headless(browser, f"--window-size={width},900", "--dump-dom", url,
                                   budget_ms=15000)
                    found = re.search(r'data-page-check="([^"]*)"', dom)
                    verdict = found.group(1) if found else "the page did not finish loading"
                    failed += verdict != "OK"
                    print(f"{page.parent.as_posix() or '/'} at {width} px: "
                          f"{verdict.replace('&quot;', chr(34))}")
        finally:
            server.shutdown()
    print(f"{len(pages)} pages, {failed} failures")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
