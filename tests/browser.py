"""A real headless Chromium (Debian's, driven by Playwright) opening a page the project wrote, for the tests."""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

#: Chromium's flags on a machine with a closed network (no background connections, no first-run work).
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@dataclass(frozen=True)
class Rendered:
    """What the browser saw: the title, the headings, the text, the images (source, loaded and their natural
    width), the console's errors and failed requests, the page's rendered height."""

    title: str
    headings: list[str]
    text: str
    images: list[tuple[str, bool, int]]
    errors: list[str]
    height: int


def render(page_path: Path, screenshot: Path | None = None) -> Rendered:
    """Open ``page_path`` in headless Chromium, wait for it to load, and report what it shows."""
    from playwright.sync_api import sync_playwright

    exe = shutil.which("chromium") or "/usr/bin/chromium"
    errors: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("requestfailed", lambda r: errors.append(f"failed: {r.url}"))
            page.goto(Path(page_path).resolve().as_uri(), wait_until="load")
            images = page.evaluate("Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, "
                                   "i.naturalWidth])")
            out = Rendered(page.title(), page.eval_on_selector_all("h1, h2", "els => els.map(e => e.textContent)"),
                           page.inner_text("body"), [tuple(v) for v in images], errors,
                           int(page.evaluate("document.body.scrollHeight")))
            if screenshot is not None:
                page.screenshot(path=str(screenshot), full_page=False)
            return out
        finally:
            browser.close()
