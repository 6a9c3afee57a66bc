"""The documentation's measured figures come from ``python -m benchmarks.report``, never typed by hand.

The pages (``README.md``, ``docs/*.md``) are rendered from ``docs/src`` with ``docs/figures.json``, the file the
report writes from the benchmarks' own output.  Checked here: every page is exactly its rendered source (so no
figure was typed into a page, and every placeholder names a measured figure); no source types a time or a
speed-up outside a placeholder (targets and limits, written with ≤, ≥, "target", "limit", … are not
measurements); the renderer's own behaviour on a small page.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.report import (BENCHMARKS, FIGURES, PlaceholderError, load_figures, main, pages, render,  # noqa: E402
                               stale_pages)

#: A time or a ratio: a number followed by a unit of time or by ×.
_MEASURED = re.compile(r"(?<![\w.{|:/-])(\d+(?:[.,]\d+)*)\s?(ms|µs|s|min|×)(?![\w/²])")
#: Words that mark a number as a target, a limit or a setting, not a measurement (looked for just before it) …
_NOT_MEASURED = re.compile(r"(≤|≥|<|>|target|limit|at most|at least|every|each|per|timeout|interval|up to|"
                           r"budget|within)\s*$", re.IGNORECASE)
#: … or just after it (the length of a record or a window is a setting).
_SETTING_AFTER = re.compile(r"\s*(record|long|window|of data|of the record|at \d)")


_BLANK = {c: " " for c in range(33, 0x110000) if chr(c) != "\n"}


def _prose(text: str) -> str:
    """``text`` without code (but with its comments), inline code and placeholders (each replaced by blanks of
    its length)."""
    def code(m: re.Match[str]) -> str:   # a code block's comments are prose: they quote figures too
        return "".join(line[:line.index("#")].translate(_BLANK) + line[line.index("#"):] if "#" in line
                       else line.translate(_BLANK) for line in m.group(0).splitlines(keepends=True))

    text = re.sub(r"```.*?```", code, text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", lambda m: " " * len(m.group(0)), text)
    return re.sub(r"\{\{.*?\}\}", lambda m: " " * len(m.group(0)), text)


def typed_figures(text: str) -> list[tuple[str, str]]:
    """Times and speed-ups typed in ``text``'s prose (what a placeholder should quote instead): each as
    (the figure, the text just before it)."""
    prose = _prose(text)
    found = []
    for m in _MEASURED.finditer(prose):
        before = prose[max(0, m.start() - 16):m.start()]
        if not _NOT_MEASURED.search(before) and not _SETTING_AFTER.match(prose, m.end()):
            found.append((m.group(0), " ".join(prose[max(0, m.start() - 40):m.start()].split())))
    return found


def test_every_page_is_its_rendered_source() -> None:
    figures = load_figures()
    assert FIGURES.exists(), "docs/figures.json: run python -m benchmarks.report"
    assert [p.target.name for p in pages()] == sorted(["README.md", "architecture.md", "benchmarks.md", "cli.md",
                                                       "diagnosis.md", "fmu.md", "identification.md", "model.md"])
    assert stale_pages(figures) == [], "a page differs from its source: edit docs/src and run --render"


def test_no_source_types_a_measured_time_or_speed_up() -> None:
    typed = {p.source.name: typed_figures(p.source.read_text(encoding="utf-8")) for p in pages()}
    assert {k: v for k, v in typed.items() if v} == {}


def test_every_quoted_benchmark_was_measured_by_the_report() -> None:
    figures = load_figures()
    quoted = {m.group(1).split(".")[0].removeprefix("table ").strip()
              for p in pages() for m in re.finditer(r"\{\{\s*(.*?)\s*\}\}", p.source.read_text(encoding="utf-8"))}
    quoted -= {"sources", "report_minutes"}
    assert quoted, "no page quotes a measured figure"
    assert quoted <= set(BENCHMARKS), quoted - set(BENCHMARKS)     # each is re-run by the report command
    for name in quoted:
        source = figures["sources"][name]
        assert source["date"] and source["commit"] and source["machine"] and source["versions"]["numpy"]


FIGS = {"sources": {"bench_x": {"date": "2026-01-01 00:00", "commit": "abc", "seconds": 1.0, "machine": "m",
                                "versions": {"python": "3.11"},
                                "figures": {"ms": 3.8412, "small": 1628.8, "flag": True, "n": 29, "big": 1234.5,
                                            "list": [1.5, 2.25],
                                            "rows": [{"case": "a", "s": 1.25}, {"case": "b", "s": None}]}}}}


def test_render_fills_numbers_tables_and_provenance() -> None:
    text = "R1 {{bench_x.ms|.2f}} ms, {{bench_x.n}} right, {{bench_x.big}}, {{bench_x.list.1}}\n" \
           "{{table bench_x.rows|case,s:.1f=time [s]}}\n{{sources}}"
    out = render(text, FIGS)
    assert out.startswith("R1 3.84 ms, 29 right, 1234, 2.25\n| case | time [s] |\n|---|---|\n| a | 1.2 |\n| b | – |")
    assert "| `bench_x` | 2026-01-01 00:00 | abc | 1 s | m | python 3.11 |" in out
    assert render("{{bench_x.small|.2g}} {{bench_x.flag|named/not named}} {{bench_x.list|.0%}} "
                  "{{bench_x.rows.case=b&s=None.case}}", FIGS) == "1.6e3 named 150%, 225% b"


@pytest.mark.parametrize("placeholder", ["{{bench_y.ms}}", "{{bench_x.missing}}", "{{bench_x.list.5}}",
                                         "{{bench_x.ms|.2q}}", "{{table bench_x.nothing}}"])
def test_a_placeholder_that_names_no_figure_is_refused(placeholder: str) -> None:
    with pytest.raises(PlaceholderError, match=re.escape(placeholder[2:-2])):
        render(f"x {placeholder} y", FIGS, "page.md")


def test_the_scanner_finds_typed_figures_and_spares_targets() -> None:
    found = typed_figures("median 21.8 s, R1 3.84 ms, speed-up 1.77×")
    assert [f for f, _ in found] == ["21.8 s", "3.84 ms", "1.77×"]
    assert typed_figures("target ≤ 60 s, at most 2 min; `3.1 ms` in code; {{bench_x.ms}} ms; a 2 s record") == []
    assert [f for f, _ in typed_figures("cases took 9.5–50.9 s")] == ["50.9 s"]


def test_the_command_refuses_an_unknown_benchmark(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--only", "bench_nothing"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bench_nothing" in err


def test_check_is_clean_on_the_repository(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--check"]) == 0
    assert capsys.readouterr().out == ""
