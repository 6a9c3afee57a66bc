"""Report figures written one way (:mod:`ebb_model.io.figureio`): measured as the page shows them."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402
from PIL import Image  # noqa: E402

from ebb_model.io.figureio import DPI, PAGE_WIDTH_PX, TEXT_PX_KEY, legibility, save_figure  # noqa: E402


def test_a_figure_wider_than_the_page_is_measured_as_the_page_scales_it(tmp_path):
    """A 20 in figure at 100 dpi is about 1,600 px wide once its tight box crops the margins: the page shows it at
    1,100 / 1,600 of its size, so its smallest text (6 pt, 8.3 px written) is shown at about 5.8 px; the written
    PNG carries the 8.3 and is as wide as measured."""
    fig, ax = plt.subplots(figsize=(20, 3))
    ax.plot([0, 1], [0, 1])
    ax.set_title("a title", fontsize=14)
    ax.text(0.5, 0.5, "small", fontsize=6)
    seen = legibility(fig)
    assert seen.smallest == "small" and seen.text_px == pytest.approx(6 * DPI / 72)
    assert seen.width_px > 1500 and seen.scale == pytest.approx(PAGE_WIDTH_PX / seen.width_px)
    assert seen.shown_px == pytest.approx(seen.text_px * PAGE_WIDTH_PX / seen.width_px)
    with Image.open(save_figure(fig, tmp_path / "wide.png")) as im:
        assert float(im.text[TEXT_PX_KEY]) == pytest.approx(seen.text_px, abs=0.01)
        assert abs(im.size[0] - seen.width_px) <= 2


def test_only_text_that_is_drawn_counts():
    """Tick labels matplotlib keeps for ticks outside the view, empty and hidden texts are not drawn and not
    counted; a tick label in view is."""
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.plot([0, 1], [0, 1])
    ax.set_xticks([-5.0, 0.0, 0.5, 1.0, 7.0])          # two outside the view
    ax.set_xlim(0, 1)
    ax.tick_params(labelsize=12)
    ax.xaxis.get_major_ticks()[0].label1.set_fontsize(3)    # the tick at -5: outside the view
    hidden = ax.text(0.2, 0.2, "hidden", fontsize=4)
    hidden.set_visible(False)
    ax.text(0.3, 0.3, "   ", fontsize=2)
    seen = legibility(fig)
    assert seen.text_px == pytest.approx(12 * DPI / 72), seen       # the tick labels in view, the smallest text
    ax.xaxis.get_major_ticks()[1].label1.set_fontsize(5)    # the tick at 0: in view
    assert legibility(fig).text_px == pytest.approx(5 * DPI / 72)
    plt.close(fig)
