"""Open torquesim's HTML pages in headless Chromium: screenshots, and a check that nothing
overflows the window (page width, tables, figures) and that every figure decodes.

    python scripts/check_pages.py compare-out/report.html vary/sensitivity.html \
        --screenshots shots/

Exit code 0 when every page passes at every window width, 1 otherwise, 2 when no Chromium is
found (install Debian's ``chromium`` or set ``CHROMIUM=/path/to/chrome``). The check runs in
the page itself after it has loaded: the document's scroll width against the window's, the
right edge of every image and table box, and each image's decoded size.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

WIDTHS = (1280, 800)  # px: a laptop window and a half-screen one

CHECK = """<script>
window.addEventListener('load', () => {
  const W = document.documentElement.clientWidth, bad = [];
  if (document.documentElement.scrollWidth > W + 1)
    bad.push('page ' + document.documentElement.scrollWidth + ' px wide in a ' + W + ' px window');
  document.querySelectorAll('img').forEach((im, i) => {
    const n = 'figure ' + (i + 1);
    if (!im.complete || im.naturalWidth === 0) bad.push(n + ' does not decode');
    if (im.getBoundingClientRect().right > W + 1) bad.push(n + ' beyond the edge');
  });
  document.querySelectorAll('div.table').forEach((d, i) => {
    if (d.getBoundingClientRect().right > W + 1) bad.push('table ' + (i + 1) + ' beyond the edge');
  });
  document.body.setAttribute('data-page-check', bad.length ? bad.join('; ') : 'OK');
});
</script>"""


def chromium() -> str | None:
    """The Chromium executable: $CHROMIUM, else the first of the usual names on PATH."""
    if os.environ.get("CHROMIUM"):
        return os.environ["CHROMIUM"]
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if found := shutil.which(name):
            return found
    return None


def found_chromium() -> str | None:
    """`chromium`, or None after saying on stderr how to get one."""
    browser = chromium()
    if browser is None:
        print("no Chromium found: install chromium or set CHROMIUM", file=sys.stderr)
    return browser


def headless(browser: str, *args: str, budget_ms: int = 10000) -> str:
    """Run headless Chromium with ``args`` (no network of its own, no first-run work) and
    return what it prints."""
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           "--disable-background-networking", "--disable-component-update", "--no-first-run",
           "--disable-sync", f"--virtual-time-budget={budget_ms}", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True).stdout


def check_page(page: Path, browser: str, width: int, screenshot: Path | None = None) -> str:
    """'OK' or what is wrong with ``page`` in a ``width``-pixel window."""
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / page.name
        # the probe lives elsewhere: a <base> keeps the page's relative links (figures) working
        text = page.read_text(encoding="utf-8").replace("</body>", CHECK + "</body>")
        base = f"<base href='{page.resolve().parent.as_uri()}/'>"
        probe.write_text(re.sub(r"(<head[^>]*>)", lambda m: m.group(1) + base, text, count=1),
                         encoding="utf-8")
        dom = headless(browser, f"--window-size={width},900", "--dump-dom", probe.as_uri())
        if screenshot is not None:
            headless(browser, f"--window-size={width},3000", f"--screenshot={screenshot}",
                     page.resolve().as_uri())
    found = re.search(r'data-page-check="([^"]*)"', dom)
    return found.group(1) if found else "the page did not finish loading"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pages", nargs="+", type=Path)
    parser.add_argument("--screenshots", type=Path, help="folder for PNG screenshots")
    args = parser.parse_args(argv)
    browser = found_chromium()
    if browser is None:
        return 2
    if args.screenshots:
        args.screenshots.mkdir(parents=True, exist_ok=True)
    failed = 0
    for page in args.pages:
        for width in WIDTHS:
            shot = (args.screenshots / f"{page.parent.name}-{page.stem}-{width}.png"
                    if args.screenshots else None)
            verdict = check_page(page, browser, width, shot)
            failed += verdict != "OK"
            print(f"{page} at {width} px: {verdict}" + (f" (screenshot {shot})" if shot else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
