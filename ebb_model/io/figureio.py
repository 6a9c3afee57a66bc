"""Every report figure written one way: a PNG, atomically, that stays legible on the run's page.

A figure is shown on the page (:mod:`ebb_model.io.htmlio`) at its natural width up to the page's content width
(:data:`PAGE_WIDTH_PX`), and scaled down beyond it.  Text that is 7 pt at 100 dpi is 9.7 px at natural size
and 5–6 px once a figure 1.8 times the page's width is scaled to it — the next experiment's chart was drawn so.
:func:`save_figure` therefore measures the figure before writing it (:func:`legibility`: its width in pixels
and the size of its smallest visible text) and writes that size into the PNG's text chunk under
:data:`TEXT_PX_KEY`, so that the page's check (``tests/browser.py``) scales it as the browser shows the image and
holds every figure of a run to :data:`MIN_TEXT_PX`.  A run is never refused for its figures' layout: the check
is the tests'.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .output import atomic_path

__all__ = ["save_figure", "legibility", "Legibility", "PAGE_WIDTH_PX", "MIN_TEXT_PX", "TEXT_PX_KEY",
           "DPI"]

#: The page's content width in CSS pixels (:mod:`ebb_model.io.htmlio` builds its style from it): a wider figure is
#: scaled down to it.
PAGE_WIDTH_PX = 1100
#: The smallest text a figure may show on the page [px], a web page's footnote: at 6–9 px the report's numbers
#: (tick labels, a panel's p-value) are read with a magnifier.
MIN_TEXT_PX = 10.0
#: Every figure's resolution [dots per inch]: 1 pt of text is 100/72 px at natural size.
DPI = 100
#: The PNG text chunk's key holding the figure's smallest text at natural size [px].
TEXT_PX_KEY = "ebb:smallest-text-px"


@dataclass(frozen=True)
class Legibility:
    """A drawn figure and how the page will show it: its natural width [px], the scale the page applies (1 when it
    fits), its smallest visible text at natural size [px] and what that text says."""

    width_px: float
    scale: float
    text_px: float
    smallest: str

    @property
    def shown_px(self) -> float:
        """The smallest text as the page shows it [px]."""
        return self.text_px * self.scale


def legibility(fig: Any, dpi: float = DPI) -> Legibility:
    """Measure ``fig`` drawn at ``dpi`` with a tight bounding box, as :func:`save_figure` writes it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, complete.
    dpi : float, optional
        Its resolution.

    Returns
    -------
    Legibility
        The natural width, the page's scale and the smallest visible, non-empty text drawn, at natural size
        (the labels of ticks outside an axis' view, which matplotlib keeps but does not draw, are not counted).
    """
    import matplotlib
    from matplotlib.text import Text

    fig.set_dpi(dpi)
    renderer = fig.canvas.get_renderer()      # the layout without rasterising: the ticks and text extents
    pad = float(matplotlib.rcParams["savefig.pad_inches"])           # savefig's margin around the tight box
    width = (float(fig.get_tightbbox(renderer).width) + 2 * pad) * dpi
    scale = min(1.0, PAGE_WIDTH_PX / width) if width > 0 else 1.0
    ticks: set[int] = set()
    drawn: list[Any] = []
    for ax in fig.get_axes():
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            span = hi - lo
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                ticks.update((id(tick.label1), id(tick.label2)))
                loc = tick.get_loc()
                if loc is not None and lo - 1e-9 * span <= loc <= hi + 1e-9 * span:    # drawn: in the view
                    drawn += [tick.label1, tick.label2]
    drawn += [t for t in fig.findobj(Text) if id(t) not in ticks]
    smallest, said = float("inf"), ""
    for t in drawn:
        if not (t.get_visible() and t.get_text().strip()):
            continue
        px = t.get_fontsize() * dpi / 72.0
        if px < smallest:
            smallest, said = px, t.get_text()
    return Legibility(width, scale, smallest if smallest < float("inf") else float("nan"), said)


def save_figure(fig: Any, path: str | Path, dpi: float = DPI) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically (tight bounding box), its smallest text at natural size [px]
    under :data:`TEXT_PX_KEY` (the page's check scales it as the browser shows the image), and close it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or Path
        Where to write.
    dpi : float, optional
        Its resolution.

    Returns
    -------
    Path
        ``path``.

    """
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        seen = legibility(fig, dpi)
        with atomic_path(path, suffix=".png") as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", metadata={TEXT_PX_KEY: f"{seen.text_px:.2f}"})
    finally:
        plt.close(fig)
    return path
