"""The report plots a person reads (issue 34): every axis labelled with its unit, signal names from the config,
unwrapped phase, the measurement drawn above the model, a zoom beside the whole record, plain tick labels, one
objective shown as what it is.  Each figure is rendered from small arrays and its axes inspected."""
from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from diagnosis.localise import localise  # noqa: E402
from diagnosis.report.plots import localisation_figures  # noqa: E402
from identification.plots import (ENVELOPE_BINS, dominant_hz, fit_figure, front_figure, spread_figure,  # noqa: E402
                                 zoom_window)

from test_localise import DT, FREQS, RES, ZETAS, _input, _modal, _noisy  # noqa: E402

UNIT = re.compile(r"\[[^\]]+\]")


@pytest.fixture(scope="module")
def localisation_plots():
    rng = np.random.default_rng(10)
    u = _input(rng, n=6000)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, _ = _noisy(_modal(u, [20.0, 55.0 * 0.97, 130.0], ZETAS, RES), rng, 0.05)
    loc = localise(DT, u, y, y_hat, ["y1", "y2"], FREQS, ZETAS, input_names=["force"])
    figures = localisation_figures(loc, DT, u, y, y_hat, units={"y1": "m", "y2": "m", "force": "N"})
    yield figures
    for fig in figures.values():
        plt.close(fig)


def test_every_localisation_axis_has_its_unit(localisation_plots):
    for name, fig in localisation_plots.items():
        for ax in fig.axes:
            if ax.get_ylabel():
                assert UNIT.search(ax.get_ylabel()), (name, ax.get_ylabel())
            if ax.get_xlabel():
                assert UNIT.search(ax.get_xlabel()), (name, ax.get_xlabel())
    frf = localisation_plots["frf.png"]
    assert "|H| y1/force [m/N]" in [ax.get_ylabel() for ax in frf.axes]           # the config's input name
    assert "y2 residual [m]" in [ax.get_ylabel() for ax in localisation_plots["residuals.png"].axes]
    texts = [t for fig in localisation_plots.values() for ax in fig.axes
             for t in (ax.get_xlabel(), ax.get_ylabel(), ax.get_title())]
    assert not any("u1" in t for t in texts), [t for t in texts if "u1" in t]


def test_the_windows_plot_draws_the_models_residual_against_the_noise(localisation_plots):
    """The drift plot's first panel: the model's residual per window and each sensor's noise σ — not the data's
    own linear fit, which is the reference of the gain and phase panels, not a rival model."""
    ax = localisation_plots["windows.png"].axes[0]
    lines = ax.get_lines()
    named = [line.get_label() for line in lines if not line.get_label().startswith("_")]
    assert named == ["y1: measured − model", "y2: measured − model"]
    flat = [line for line in lines if len(set(np.asarray(line.get_ydata(), dtype=float))) == 1]
    assert len(flat) == 2                                                     # one noise level per sensor
    assert all("linear fit" in a.get_ylabel() for a in localisation_plots["windows.png"].axes[1:3])


def test_phase_is_wrapped_and_the_measurement_is_drawn_above_the_model(localisation_plots):
    """The phase in (−180°, 180°], as labelled (an "unwrapped" phase of sparse or noisy bins picked its branch at
    random: issue 52), and the model's line broken where it wraps — no segment crosses the axes."""
    frf = localisation_plots["frf.png"]
    phase_axes = [ax for ax in frf.axes if ax.get_ylabel().startswith("phase")]
    assert phase_axes
    for ax in phase_axes:
        assert "unwrapped" not in ax.get_ylabel()
        for line in ax.get_lines():
            y = np.asarray(line.get_ydata(), dtype=float)
            y = y[np.isfinite(y)] if line.get_linestyle() in ("None", "") else y
            assert np.all(np.abs(y[np.isfinite(y)]) <= 180.0 + 1e-9), line.get_label()
            if line.get_linestyle() not in ("None", ""):
                # a drawn segment joins two finite points less than 180° apart (a wrap is a gap)
                d = np.abs(np.diff(y))
                assert np.all(d[np.isfinite(d)] < 180.0), line.get_label()
    for ax in frf.axes:
        z = {line.get_label(): line.get_zorder() for line in ax.get_lines()}
        if "measured" in z and "model" in z:
            assert z["measured"] > z["model"]


def test_no_offset_tick_labels_and_legends_outside_the_data(localisation_plots):
    for fig in localisation_plots.values():
        fig.canvas.draw()
        for ax in fig.axes:
            for axis in (ax.xaxis, ax.yaxis):
                assert getattr(axis.get_major_formatter(), "offset", 0) == 0     # no "+3.499" offsets
            legend = ax.get_legend()
            if legend is not None:      # anchored right of the axes, outside its data
                box = legend.get_window_extent()
                assert box.x0 >= ax.get_window_extent().x1 - 1.0


def test_fit_figure_has_a_zoom_and_the_data_on_top_and_a_long_record_as_envelopes():
    dt = 2.5e-4
    t = np.arange(80000) * dt                       # 20 s of a 120 Hz tone: a solid band if drawn whole
    y = np.column_stack([np.sin(2 * np.pi * 120 * t), 0.5 * np.sin(2 * np.pi * 120 * t + 1)])
    zoom = zoom_window(t.size, dt, periods_hz=dominant_hz(y[:, 0], dt))
    assert dominant_hz(y[:, 0], dt) == pytest.approx(120.0, abs=0.05)
    assert (zoom.stop - zoom.start) * dt == pytest.approx(10 / 120, rel=0.01)     # ten periods
    fig = fit_figure(t, y, {"model": 0.98 * y}, ["y1", "a1"], ["m", "m/s^2"], zoom=zoom)
    try:
        assert [ax.get_ylabel() for ax in fig.axes[::2]] == ["y1 [m]", "a1 [m/s^2]"]
        assert all(ax.get_xlabel() == "time [s]" for ax in fig.axes[-2:])
        left, right = fig.axes[0], fig.axes[1]
        assert right.get_xlim()[1] - right.get_xlim()[0] < 0.1 < left.get_xlim()[1] - left.get_xlim()[0]
        for ax in fig.axes[1::2]:                   # the zooms: cycles as lines, the data on top
            z = {line.get_label(): line.get_zorder() for line in ax.get_lines()}
            assert z["measured"] > z["model"]
        # the whole record (80,000 samples) as envelopes, not lines (a solid block): the measurement's and the
        # residual's, each at most ENVELOPE_BINS steps across
        for ax in fig.axes[0::2]:
            assert not ax.get_lines()
            bands = {c.get_label(): c for c in ax.collections}
            assert {"measured (envelope)", "measured − model (envelope)"} <= set(bands), bands
            for c in bands.values():
                assert len(c.get_paths()[0].vertices) <= 4 * ENVELOPE_BINS + 10
        # the envelope of the residual (2 % of the signal) spans 2 %, the measurement's the signal's range
        res = fig.axes[0].collections
        spans = {c.get_label(): np.ptp(c.get_paths()[0].vertices[:, 1]) for c in res}
        assert spans["measured (envelope)"] == pytest.approx(2.0, rel=1e-3)
        assert spans["measured − model (envelope)"] == pytest.approx(0.04, rel=1e-2)
        # the grey band on the whole record marks the zoom: named in the figure's legend, with the zoom's lines
        labels = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
        assert {"zoomed (right)", "measured", "model"} <= set(labels), labels
    finally:
        plt.close(fig)


def test_a_long_records_legend_stays_within_the_figure_below_its_panels():
    """Two models on a long record name seven lines (the envelopes, the zoom's lines, the zoom's band): in one row
    their legend was wider than the panels (the saved figure twice their width).  In rows of three it lies within
    the figure's width and below every panel."""
    dt = 2.5e-4
    t = np.arange(40000) * dt
    y = np.sin(2 * np.pi * 50 * t)[:, None]
    models = {"polished knee (finer numerics)": 0.98 * y, "knee (the GA's, not polished)": 0.9 * y}
    fig = fit_figure(t, y, models, ["a1"], ["m/s^2"])
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        (legend,) = fig.legends
        box, width = legend.get_window_extent(renderer), fig.bbox.width
        assert len(legend.get_texts()) == 7
        assert box.x0 >= 0.0 and box.x1 <= width, (box, width)
        assert box.y1 <= min(ax.get_tightbbox(renderer).y0 for ax in fig.axes) + 1.0
    finally:
        plt.close(fig)


def test_band_edges_in_plain_digits():
    from diagnosis.report.plots import _hz

    assert [_hz(v) for v in (2.0, 63.5, 99.94, 1000.0, 12500.0)] == ["2", "63.5", "99.9", "1000", "12500"]


def test_parameter_spread_has_plain_ticks_and_units():
    rng = np.random.default_rng(1)
    X = np.column_stack([3.499 + 1e-5 * rng.standard_normal(9), 1e-8 + 4e-5 + 1e-12 * rng.standard_normal(9)])
    fig = spread_figure(X, ["EI", "eta"], 0, X[0])
    try:
        fig.canvas.draw()
        assert [ax.get_ylabel() for ax in fig.axes] == ["EI [N.m2]", "eta [s]"]
        for ax in fig.axes:      # the values differ in their 5th and 8th digits: an offset would be chosen
            assert ax.yaxis.get_major_formatter().offset == 0
        assert fig.legends and all(ax.get_legend() is None for ax in fig.axes)   # one legend, below the panels
    finally:
        plt.close(fig)


def test_one_objective_is_drawn_as_the_searchs_convergence():
    history = np.array([[40, 0.5], [80, 0.3], [120, 0.3], [160, 0.12]])   # evaluations, best of the generation
    fig = front_figure(np.array([[0.12], [0.2]]), ["nrmse_y1"], 0, np.array([0.05]), history)
    try:
        ax = fig.axes[0]
        assert ax.get_xlabel() == "model evaluations [-]" and ax.get_ylabel() == "nrmse_y1 [-]"
        assert "convergence" in ax.get_title() and ax.get_yscale() == "log"
        line = ax.get_lines()[0]
        assert list(line.get_xdata()) == [40, 80, 120, 160] and list(line.get_ydata()) == [0.5, 0.3, 0.3, 0.12]
        assert ax.get_lines()[1].get_ydata()[0] == 0.05                    # the polished knee
    finally:
        plt.close(fig)


def test_one_objective_without_a_history_is_not_drawn_as_a_front():
    F = np.array([[0.3], [0.1], [0.2]])
    fig = front_figure(F, ["nrmse_y1"], 1, np.array([0.05]))
    try:
        ax = fig.axes[0]
        assert "front" not in ax.get_xlabel() and ax.get_xlabel().endswith("[-]")
        assert ax.get_ylabel() == "nrmse_y1 [-]"
        assert list(ax.get_lines()[0].get_ydata()) == [0.1, 0.2, 0.3]          # best first
    finally:
        plt.close(fig)


def test_the_held_out_residuals_are_read_against_the_noise_floor():
    """The diagnosis' held-out residual figure draws the residual's running RMS and spectrum in noise units: 1 where
    the residual is the noise, a line at its frequency where the model misses one.  Unit white noise, 60,000
    samples: 60 windows of 1,000 samples, each RMS within 1 ± 0.11 (its standard deviation 1/√2000 = 0.022, five of
    them; measured over 200 seeds: at most 0.081 off); Welch's 1,024-sample segments, the ratio to white noise's
    level averaged over the bins within 0.03 of 1 (measured over 200 seeds: 0.9985 ± 0.0065, the bound 4.6 of them),
    no bin above 2 (measured at most 1.49); a sine at 123 Hz of a quarter of the noise's power stands above 10 at
    its bin (measured 43)."""
    from diagnosis.report.figures import residual_spectrum, running_rms

    dt, n = 1e-3, 60_000
    r = np.random.default_rng(7).standard_normal(n)
    t, rms = running_rms(r, dt)
    assert rms.size == 60 and t[0] == pytest.approx(0.5) and t[-1] == pytest.approx(59.5)
    assert np.all(np.abs(rms - 1.0) <= 0.11), rms
    f, level = residual_spectrum(r, dt)
    assert f[0] > 0 and f[-1] == pytest.approx(500.0)
    assert abs(level.mean() - 1.0) <= 0.03 and level.max() < 2.0, (level.mean(), level.max())
    f, level = residual_spectrum(r + 0.5 * np.sin(2 * np.pi * 123.0 * np.arange(n) * dt), dt)
    assert abs(f[np.argmax(level)] - 123.0) < f[1] - f[0] and level.max() > 10.0
    t, rms = running_rms(r[:100], dt)      # shorter than RMS_WINDOWS stretches of 8: fewer, longer stretches
    assert rms.size == 12 and np.all(np.isfinite(rms))
