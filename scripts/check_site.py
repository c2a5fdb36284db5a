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
  wider than the window or than its cell.
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
