"""The run pages (:mod:`ebb_model.io.htmlio`): text escaped, figures linked relative to the page, refused outside it,
nothing partial; opened in a real headless Chromium."""
from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest

from ebb_model.io.htmlio import Section, Table, figures_in, write_page

from browser import render

matplotlib.use("Agg")


def _figure(path):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1], [0, 1])
    fig.savefig(path)
    plt.close(fig)


def test_a_page_shows_its_tables_and_figures_and_escapes_text(tmp_path):
    (tmp_path / "sub").mkdir()
    _figure(tmp_path / "b.png")
    _figure(tmp_path / "sub" / "a.png")
    figs = figures_in(tmp_path, {"b.png": "the fit"}) + figures_in(tmp_path / "sub", {})
    assert [c for _, c in figs] == ["the fit", "a"]
    page = write_page(tmp_path / "report.html", "run <1> & co", [
        Section("Verdict", lead="verdict: <none>", paragraphs=("a < b",)),
        Section("Values", tables=(Table(("name", "value"), [("EI", "10.5 ± 0.1"), ("<script>", "x")]),),
                figures=tuple(figs))])
    raw = page.read_text()
    assert "<script>" not in raw and "&lt;script&gt;" in raw
    assert 'src="sub/a.png"' in raw and 'src="b.png"' in raw
    seen = render(page)
    assert seen.title == "run <1> & co"
    assert seen.headings == ["run <1> & co", "Verdict", "Values"]
    assert "verdict: <none>" in seen.text and "a < b" in seen.text and "<script>" in seen.text
    assert [(src, ok, w > 0) for src, ok, w, _ in seen.images] == [("b.png", True, True), ("sub/a.png", True, True)]
    assert not seen.errors


def test_a_figure_outside_the_pages_folder_is_refused_and_nothing_is_written(tmp_path):
    (tmp_path / "page").mkdir()
    _figure(tmp_path / "elsewhere.png")
    with pytest.raises(ValueError):
        write_page(tmp_path / "page" / "report.html", "t", [Section("s", figures=((tmp_path / "elsewhere.png",
                                                                                   "x"),))])
    assert list((tmp_path / "page").iterdir()) == []


def test_without_a_browser_the_page_test_is_reported_as_not_run(tmp_path):
    """On a machine with no browser (nothing on PATH, no Playwright download) the page test is skipped with the
    reason — never reported as passed — and ``tests/browser.py`` says so in one line (exit 1), which ``run.sh test``
    relays before running everything else."""
    import os
    import subprocess
    import sys

    here = Path(__file__).resolve().parent
    env = {k: v for k, v in os.environ.items() if k != "PLAYWRIGHT_BROWSERS_PATH"}
    env |= {"PATH": str(tmp_path), "PLAYWRIGHT_BROWSERS_PATH": str(tmp_path / "none")}
    probe = subprocess.run([sys.executable, str(here / "browser.py")], capture_output=True, text=True, env=env,
                           timeout=120)
    assert probe.returncode == 1 and probe.stdout.startswith("no browser found"), (probe.stdout, probe.stderr)
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "-n", "0",
                          f"{here / 'test_htmlio.py'}::test_a_page_shows_its_tables_and_figures_and_escapes_text"],
                         capture_output=True, text=True, env=env, cwd=here.parent, timeout=300)
    assert "1 skipped" in run.stdout and "passed" not in run.stdout, run.stdout[-2000:]
    assert "no headless browser on this machine" in run.stdout, run.stdout[-2000:]
