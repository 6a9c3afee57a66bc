"""One HTML page per run: the verdict, the tables and the figures of a result directory on one page a person opens
in a browser (:func:`write_page`).

The page is plain HTML5 with its style inline and no script; figures are linked by their path relative to the
page (they sit in the run's directory beside it), so the page stays small and opens wherever the directory is
copied.  Every text is escaped.  ``identify``, ``diagnose`` and ``demo`` each write ``report.html`` with it.
"""
from __future__ import annotations

import html
import platform
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Sequence

from .figureio import PAGE_WIDTH_PX
from .output import atomic_path

__all__ = ["Table", "Section", "write_page", "figures_in", "PAGE"]

#: The file name of a run's page.
PAGE = "report.html"

#: The page's style; its content width is the one the figures are measured against
#: (:data:`ebb_model.io.figureio.PAGE_WIDTH_PX`).
_STYLE = """
body { font-family: system-ui, sans-serif; max-width: PAGE_WIDTHpx; margin: 2em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; padding-bottom: .2em; }
table { border-collapse: collapse; margin: .5em 0 1em; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
caption { caption-side: top; text-align: left; font-style: italic; padding-bottom: .2em; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: .9em; color: #555; } pre { background: #f7f7f7; padding: .6em; overflow-x: auto; }
.verdict { font-size: 1.15em; font-weight: 600; } footer { margin-top: 2em; font-size: .8em; color: #777; }
""".replace("PAGE_WIDTH", str(PAGE_WIDTH_PX))


@dataclass(frozen=True)
class Table:
    """A table: its header, its rows (strings; a cell that parses as a number is right-aligned) and a caption."""

    header: Sequence[str]
    rows: Sequence[Sequence[str]]
    caption: str = ""


@dataclass(frozen=True)
class Section:
    """A section of the page: tables, paragraphs, figures ``(path, caption)`` and preformatted text, in that
    order; ``lead`` is a paragraph set in bold before them (a verdict)."""

    title: str
    lead: str = ""
    paragraphs: Sequence[str] = ()
    tables: Sequence[Table] = ()
    figures: Sequence[tuple[Path, str]] = ()
    preformatted: str = ""
    anchor: str = field(default="")


def _is_number(text: str) -> bool:
    words = text.split()
    try:
        float(words[0])
    except (ValueError, IndexError):
        return False
    return True


def _table(t: Table) -> str:
    e = html.escape
    head = "".join(f"<th>{e(h)}</th>" for h in t.header)
    body = "".join("<tr>" + "".join(f'<td class="num">{e(c)}</td>' if _is_number(c) else f"<td>{e(c)}</td>"
                                    for c in row) + "</tr>" for row in t.rows)
    cap = f"<caption>{e(t.caption)}</caption>" if t.caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _section(s: Section, base: Path) -> str:
    e = html.escape
    parts = [f'<section id="{e(s.anchor)}">' if s.anchor else "<section>", f"<h2>{e(s.title)}</h2>"]
    if s.lead:
        parts.append(f'<p class="verdict">{e(s.lead)}</p>')
    parts += [_table(t) for t in s.tables]
    parts += [f"<p>{e(p)}</p>" for p in s.paragraphs]
    for path, caption in s.figures:
        src = Path(path).resolve().relative_to(base.resolve()).as_posix()
        parts.append(f'<figure><img src="{e(src)}" alt="{e(caption)}"><figcaption>{e(caption)}</figcaption>'
                     "</figure>")
    if s.preformatted:
        parts.append(f"<pre>{e(s.preformatted)}</pre>")
    parts.append("</section>")
    return "\n".join(parts)


def _footer() -> str:
    try:
        version = metadata.version("ebb-ident")
    except metadata.PackageNotFoundError:  # pragma: no cover - run from a source tree without install
        version = "source"
    return (f"written {time.strftime('%Y-%m-%d %H:%M:%S %Z')} by ebb-ident {version}, Python "
            f"{platform.python_version()}, {platform.machine()} {platform.system()}")


def figures_in(directory: Path, captions: dict[str, str]) -> list[tuple[Path, str]]:
    """The PNG figures of ``directory`` named in ``captions`` (in that order, those that exist), then any other
    PNG in it, captioned by its name."""
    directory = Path(directory)
    known = [(directory / name, cap) for name, cap in captions.items() if (directory / name).is_file()]
    rest = [(p, p.stem.replace("_", " ")) for p in sorted(directory.glob("*.png")) if p.name not in captions]
    return known + rest


def write_page(path: str | Path, title: str, sections: Sequence[Section], *, subtitle: str = "") -> Path:
    """Write the page ``path`` (atomically): the title, an optional subtitle, a table of contents and the
    sections; figures must lie under the page's directory.

    Raises
    ------
    ValueError
        A figure outside the page's directory.
    ebb_model.errors.OutputError
        The page cannot be written.
    """
    path = Path(path)
    e = html.escape
    toc = "".join(f'<li><a href="#s{i}">{e(s.title)}</a></li>' for i, s in enumerate(sections))
    body = "\n".join(_section(Section(**{**s.__dict__, "anchor": f"s{i}"}), path.parent)
                     for i, s in enumerate(sections))
    text = (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>'
            f'<meta name="viewport" content="width=device-width, initial-scale=1"><style>{_STYLE}</style></head>\n'
            f"<body><h1>{e(title)}</h1>" + (f"<p>{e(subtitle)}</p>" if subtitle else "")
            + f"<nav><ul>{toc}</ul></nav>\n{body}\n<footer>{e(_footer())}</footer></body></html>\n")
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path
