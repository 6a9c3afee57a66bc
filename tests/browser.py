"""A real headless Chromium (driven by Playwright) opening a page the project wrote, for the tests.

The browser is whichever is there (:func:`find_browser`): a Chromium or Chrome on ``PATH`` (Debian's
``chromium``, ``chromium-browser``, ``google-chrome``), else Playwright's own download.  Where there is none, a
page test is skipped — reported as not run, never as passed.  ``python tests/browser.py`` prints the browser
found, or one line saying there is none (exit 1): ``run.sh test`` asks it before the suite.
"""
from __future__ import annotations

import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

#: Browser commands looked for on ``PATH``, in order.
COMMANDS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")

#: Chromium's flags on a machine with a closed network (no background connections, no first-run work).
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@dataclass(frozen=True)
class Rendered:
    """What the browser saw: the title, the headings, the text, the images (source, loaded, natural width and the
    width shown on the page), the console's errors and failed requests, the page's rendered height."""

    title: str
    headings: list[str]
    text: str
    images: list[tuple[str, bool, int, float]]
    errors: list[str]
    height: int


def find_browser(path: str | None = None) -> str | None:
    """The executable of a Chromium-family browser: the first of :data:`COMMANDS` on ``path`` (default the
    process's ``PATH``), else Playwright's own Chromium when it was downloaded; ``None`` when there is none."""
    for cmd in COMMANDS:
        exe = shutil.which(cmd, path=path if path is not None else os.environ.get("PATH", ""))
        if exe:
            return exe
    try:
        from playwright.sync_api import sync_playwright

        with sync_playwright() as p:
            own = p.chromium.executable_path
    except Exception:       # no playwright, or no driver: no browser of its own either
        return None
    return own if own and Path(own).is_file() else None


def render(page_path: Path, screenshot: Path | None = None) -> Rendered:
    """Open ``page_path`` in headless Chromium, wait for it to load, and report what it shows (the calling test is
    skipped, reported as not run, where no browser is found)."""
    import pytest
    from playwright.sync_api import sync_playwright

    exe = find_browser()
    if exe is None:
        pytest.skip("no headless browser on this machine (chromium, chrome or Playwright's own): page not checked")
    errors: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("requestfailed", lambda r: errors.append(f"failed: {r.url}"))
            page.goto(Path(page_path).resolve().as_uri(), wait_until="load")
            images = page.evaluate("Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, "
                                   "i.naturalWidth, i.getBoundingClientRect().width])")
            out = Rendered(page.title(), page.eval_on_selector_all("h1, h2", "els => els.map(e => e.textContent)"),
                           page.inner_text("body"), [tuple(v) for v in images], errors,
                           int(page.evaluate("document.body.scrollHeight")))
            if screenshot is not None:
                page.screenshot(path=str(screenshot), full_page=False)
            return out
        finally:
            browser.close()


def smallest_text_shown(page_path: Path, seen: Rendered) -> dict[str, float]:
    """Each figure's smallest text as the browser showed it [px]: the size the figure was written with
    (:data:`ebb_model.io.figureio.TEXT_PX_KEY` in its PNG, at natural size) times the width shown over the natural
    width; NaN for an image written without it."""
    from PIL import Image

    from ebb_model.io.figureio import TEXT_PX_KEY

    out = {}
    for src, _, natural, shown in seen.images:
        with Image.open(Path(page_path).parent / src) as im:
            text = getattr(im, "text", {}).get(TEXT_PX_KEY)
        out[src] = float(text) * shown / natural if text is not None and natural else float("nan")
    return out


if __name__ == "__main__":
    found = find_browser()
    if found is None:
        print("no browser found (chromium, chromium-browser, google-chrome, chrome on PATH, or Playwright's own)")
        sys.exit(1)
    print(found)
