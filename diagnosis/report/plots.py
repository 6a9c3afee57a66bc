"""Report plots of a gap localisation (matplotlib, Agg backend, PNG files).

:func:`plot_localisation` draws what :func:`diagnosis.localise.localise`
computed: residual time series, measured versus model FRFs with the mode
markers, residual statistics per time window and per amplitude level, and the
residual auto- and cross-correlations with their 99 % bands.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model.arrays import as_matrix
from ebb_model.errors import DataError
from ebb_model.io.figureio import save_figure
from ebb_model.io.output import make_dir
from identification.plots import plain_ticks, trace

from ..localise import Localisation, estimate_frf

__all__ = ["plot_localisation", "localisation_figures"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def localisation_figures(loc: Localisation, dt: float, u: np.ndarray, y: np.ndarray, y_hat: np.ndarray,
                         units: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The localisation's figures by file name (``residuals.png``, ``frf.png``, ``windows.png``,
    ``amplitude.png``, ``correlation.png``, ``bands.png``); arguments as :func:`plot_localisation`."""
    u2, y2, yh2 = as_matrix(u, "u"), as_matrix(y, "y"), as_matrix(y_hat, "y_hat")
    if y2.shape != yh2.shape or y2.shape[1] != len(loc.sensor_names) or u2.shape[0] != y2.shape[0] \
            or u2.shape[1] != len(loc.input_names):
        raise DataError(f"plot_localisation: data shapes u {u2.shape}, y {y2.shape}, y_hat {yh2.shape} do not "
                        f"match the localisation ({len(loc.input_names)} inputs, {len(loc.sensor_names)} sensors)")
    plt = _pyplot()
    unit = _Units(dict(units or {}))
    t = np.arange(y2.shape[0]) * dt
    figures = {"residuals.png": _residuals_figure(plt, loc, t, y2, yh2, unit),
               "frf.png": _frf_figure(plt, loc, dt, u2, y2, yh2, unit),
               "windows.png": _windows_figure(plt, loc, unit),
               "amplitude.png": _amplitude_figure(plt, loc, unit),
               "correlation.png": _correlation_figure(plt, loc),
               "bands.png": _bands_figure(plt, loc)}
    for fig in figures.values():
        fig.tight_layout()
        for ax in fig.axes:
            plain_ticks(ax)
    return figures


def plot_localisation(loc: Localisation, dt: float, u: np.ndarray, y: np.ndarray, y_hat: np.ndarray,
                      out_dir: str | Path, units: Mapping[str, str] | None = None) -> list[Path]:
    """Write the localisation plots as PNG files into ``out_dir``.

    Parameters
    ----------
    loc
        Result of :func:`diagnosis.localise.localise` on the same data.
    dt, u, y, y_hat
        The data given to :func:`~diagnosis.localise.localise`.
    out_dir
        Directory (created if missing).
    units
        The unit of each signal by name (sensors and inputs, e.g. ``{"y1": "m", "F1": "N"}``); a signal
        without one is labelled without a unit.

    Returns
    -------
    list of Path
        ``residuals.png``, ``frf.png``, ``windows.png``, ``amplitude.png``,
        ``correlation.png``, ``bands.png``.
    """
    figures = localisation_figures(loc, dt, u, y, y_hat, units)
    out = Path(out_dir)
    make_dir(out, exist_ok=True, parents=True)
    return [save_figure(fig, out / name) for name, fig in figures.items()]


class _Units:
    """Axis-label units of the signals by name."""

    def __init__(self, units: dict[str, str]) -> None:
        self.units = units

    def of(self, name: str) -> str:
        """`` [unit]`` of a signal, or nothing."""
        u = self.units.get(name)
        return f" [{u}]" if u else ""

    def ratio(self, out: str, inp: str) -> str:
        """`` [out/in]`` of a frequency response, or nothing."""
        a, b = self.units.get(out), self.units.get(inp)
        return f" [{a}/{b}]" if a and b else ""

    def common(self, names: list[str]) -> str:
        """`` [unit]`` when every named signal has the same unit, else nothing."""
        found = {self.units.get(n) for n in names}
        return f" [{found.pop()}]" if len(found) == 1 and None not in found else ""


def _outside_legend(ax: Any) -> None:
    """The axis' legend to the right of its data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)


def _residuals_figure(plt: Any, loc: Localisation, t: np.ndarray, y2: np.ndarray, yh2: np.ndarray, unit: _Units
                      ) -> Any:
    """The residual time series per sensor with the ±2σ noise band."""
    names = loc.sensor_names
    n_out = len(names)
    # residual time series with the ±2σ noise band
    fig, axes = plt.subplots(n_out, 1, figsize=(8, 2.2 * n_out), squeeze=False, sharex=True)
    for o, ax in enumerate(axes[:, 0]):
        s = loc.sensors[o]
        trace(ax, t, y2[:, o] - yh2[:, o], lw=0.5, color="C3", label="residual y - ŷ")   # envelope when long
        ax.axhline(2 * s.noise_std, color="k", ls=":", lw=0.8, label="±2σ noise")
        ax.axhline(-2 * s.noise_std, color="k", ls=":", lw=0.8)
        ax.set_ylabel(f"{names[o]} residual{unit.of(names[o])}")
        ax.set_title(f"{names[o]}: NRMSE {s.nrmse:.3g}, gap ratio {s.gap_ratio:.3g}", fontsize=9)
    _outside_legend(axes[0, 0])
    axes[-1, 0].set_xlabel("time [s]")
    return fig


#: Fewer excited frequencies than this (tones): the model's FRF is marked at them, not joined by lines that would
#: cross resonances the tones do not see.
_FEW_LINES = 12


def _frf_figure(plt: Any, loc: Localisation, dt: float, u2: np.ndarray, y2: np.ndarray, yh2: np.ndarray,
                unit: _Units) -> Any:
    """FRF magnitude and phase, measured against model, with the modes marked.

    The phase is drawn wrapped to (−180°, 180°]: the excited bins need not be contiguous (tones, a band with
    gaps) and near an antiresonance the measured phase turns by more than 180° between bins, where unwrapping
    picks a branch at random (measured: an "unwrapped" curve falling to −360° and jumping back to −200°)."""
    names = loc.sensor_names
    n_out = len(names)
    # FRF magnitude and phase, measured vs model, with mode markers
    fm = estimate_frf(dt, u2, y2, nperseg=loc.nperseg)
    fh = estimate_frf(dt, u2, yh2, nperseg=loc.nperseg)
    n_in = u2.shape[1]
    fig, axes = plt.subplots(2 * n_out, n_in, figsize=(6 * n_in, 3.2 * n_out), squeeze=False, sharex=True)
    for o in range(n_out):
        for j in range(n_in):
            exc = fm.excited[:, j]
            f = fm.f[exc]
            axm, axp = axes[2 * o, j], axes[2 * o + 1, j]
            style = "x" if f.size < _FEW_LINES else "-"
            axm.semilogy(f, np.abs(fh.H[exc, o, j]), style, lw=0.8, color="C1", label="model")
            axm.semilogy(f, np.abs(fm.H[exc, o, j]), ".", ms=3, color="C0", label="measured", zorder=5)
            axp.plot(*_broken_at_wraps(f, np.degrees(np.angle(fh.H[exc, o, j]))), style, lw=0.8, color="C1")
            axp.plot(f, np.degrees(np.angle(fm.H[exc, o, j])), ".", ms=3, color="C0", zorder=5)
            axp.set_ylim(-185, 185)
            axp.set_yticks([-180, -90, 0, 90, 180])
            for m in loc.modes:
                if m.sensor != names[o] or m.input != loc.input_names[j]:
                    continue
                for ax in (axm, axp):
                    ax.axvline(m.model_freq_hz, color="C1", ls="--", lw=0.6)
                    if m.fit_ok:
                        ax.axvline(m.measured_freq_hz, color="C0", ls=":", lw=0.8)
            axm.set_ylabel(f"|H| {names[o]}/{loc.input_names[j]}{unit.ratio(names[o], loc.input_names[j])}")
            axp.set_ylabel("phase [deg]")
    _outside_legend(axes[0, -1])
    for j in range(n_in):
        axes[-1, j].set_xlabel("frequency [Hz]  (dashed: model modes, dotted: measured fit)")
    return fig


def _windows_figure(plt: Any, loc: Localisation, unit: _Units) -> Any:
    """The model's residual RMS per time window against the noise level, and the data's gain and phase per window
    relative to their own time-invariant linear fit (drift: a trend there; the fit is a reference for change
    over time, not a model of the beam, so its own residual is not drawn)."""
    # per time window
    fig, axes = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    noise = {s.sensor: s.noise_std for s in loc.sensors}
    for o, w in enumerate(loc.windows):
        tc = np.asarray(w.t_center)
        axes[0].plot(tc, w.rms, "o-", color=f"C{o}", label=f"{w.sensor}: measured − model")
        if w.sensor in noise:
            axes[0].axhline(noise[w.sensor], color=f"C{o}", ls=":", lw=0.8)
        axes[1].plot(tc, w.gain, "o-", color=f"C{o}", label=f"{w.sensor} (trend p={w.gain_p:.2g})")
        axes[2].plot(tc, w.phase_deg, "o-", color=f"C{o}", label=f"{w.sensor} (trend p={w.phase_p:.2g})")
        for ax, mid, sd in ((axes[1], w.twin_gain, w.twin_gain_sd), (axes[2], w.twin_phase_deg, w.twin_phase_sd)):
            _twin_band(ax, tc, mid, sd, o)
    axes[0].set_ylabel(f"model residual RMS{unit.common([w.sensor for w in loc.windows])}\n(dotted: noise σ)")
    axes[1].set_ylabel("gain vs. time-invariant\nlinear fit [-]")
    axes[2].set_ylabel("phase vs. time-invariant\nlinear fit [deg]")
    axes[2].set_xlabel("window centre [s]")
    for ax in axes:
        _outside_legend(ax)
    drifting = [w.sensor for w in loc.windows if w.drift]
    axes[0].set_title("per time window: " + (f"drift in {', '.join(drifting)} (a trend beyond a linear record's)"
                                              if drifting else "no drift (every trend within a linear record's)"),
                      fontsize=10)
    axes[1].set_title("pale line: a linear time-invariant record under the same input (shaded: its ±2σ)", fontsize=8)
    return fig


def _twin_band(ax: Any, x: np.ndarray, mid: Sequence[float], sd: Sequence[float], o: int) -> None:
    """Draw what the record's linear twins show at ``x`` in the sensor's colour: their mean as a broad pale line
    under the record's, ± 2 standard deviations shaded; nothing where the twins were not formed.  A record's
    points on the pale line show what a linear time-invariant record under the same input shows (a short
    record's gain per window swings by half with its input's spectrum, and so do its twins')."""
    if len(mid) == len(x) and len(sd) == len(x):
        m, s = np.asarray(mid, dtype=float), np.asarray(sd, dtype=float)
        ax.plot(x, m, "-", color=f"C{o}", lw=8, alpha=0.25, zorder=0, solid_capstyle="round")
        ax.fill_between(x, m - 2 * s, m + 2 * s, color=f"C{o}", alpha=0.2, lw=0)


def _amplitude_figure(plt: Any, loc: Localisation, unit: _Units) -> Any:
    """Residual RMS and gain per response amplitude level (nonlinearity)."""
    # per amplitude level
    fig, axes = plt.subplots(2, 1, figsize=(7, 5.5))
    for o, a in enumerate(loc.amplitude):
        lv = np.asarray(a.level)
        axes[0].loglog(lv, a.residual_rms, "o-", color=f"C{o}",
                       label=f"{a.sensor} (exponent {a.rms_exponent:.2g})")
        axes[0].axhline(loc.sensors[o].noise_std, color=f"C{o}", ls=":", lw=0.8)
        axes[1].semilogx(lv, a.gain, "o-", color=f"C{o}", label=f"{a.sensor} (p={a.gain_p:.2g})")
        _twin_band(axes[1], lv, a.twin_gain, a.twin_gain_sd, o)
    common = unit.common([a.sensor for a in loc.amplitude])
    axes[0].set_ylabel(f"residual RMS{common}\n(dotted: noise σ)")
    axes[1].set_ylabel("gain vs. time-invariant\nlinear fit [-]")
    axes[1].set_xlabel(f"response envelope level{common}")
    for ax in axes:
        _outside_legend(ax)
    bent = [a.sensor for a in loc.amplitude if a.nonlinear]
    axes[0].set_title("per amplitude level: " + (f"nonlinear in {', '.join(bent)} (beyond a linear record's)" if bent
                                                  else "no amplitude dependence beyond a linear record's"),
                      fontsize=10)
    axes[1].set_title("pale line: a linear record under the same input (shaded: its ±2σ)", fontsize=8)
    return fig


def _correlation_figure(plt: Any, loc: Localisation) -> Any:
    """Residual autocorrelation and input cross-correlation with their bands."""
    n_in = len(loc.input_names)
    names = loc.sensor_names
    n_out = len(names)
    # correlations
    fig, axes = plt.subplots(n_out, 1 + n_in, figsize=(3.5 * (1 + n_in), 2.4 * n_out), squeeze=False)
    for o, h in enumerate(loc.whiteness):
        ax = axes[o, 0]
        lags = np.arange(1, len(h.autocorr) + 1)
        ax.bar(lags, h.autocorr, color="C0", width=0.8)
        ax.axhspan(-h.band, h.band, color="k", alpha=0.15)
        ax.set_title(f"{h.sensor}: residual {'white' if h.white else 'not white'} (Ljung-Box p={h.ljung_box_p:.2g})",
                     fontsize=8)
        ax.set_xlabel("lag [samples] (grey: 99 % band of white noise)", fontsize=8)
        ax.set_ylabel("correlation [-]")
    for c in loc.cross_correlation:
        o = names.index(c.sensor)
        j = loc.input_names.index(c.input)
        ax = axes[o, 1 + j]
        m = (len(c.xcorr) - 1) // 2
        ax.bar(np.arange(-m, m + 1), c.xcorr, color="C1", width=0.8)
        ax.axhspan(-c.band, c.band, color="k", alpha=0.15)
        said = ("input-related error" if c.significant
                else "no input-related error" + ("" if c.p * len(loc.cross_correlation) >= 0.01
                                                 else ": no lag outside the band"))
        ax.set_title(f"{c.sensor} vs {c.input}: {said} (p={c.p:.2g})", fontsize=8)
        ax.set_xlabel("lag [samples] (grey: 99 % band of an error unrelated to the input)", fontsize=8)
        ax.set_ylabel("correlation [-]")
    return fig


def _broken_at_wraps(f: np.ndarray, deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``f`` and the wrapped phase ``deg`` with a gap (NaN) where the phase wraps, so that a line does not cross
    the axes from +180° to −180°."""
    cut = np.flatnonzero(np.abs(np.diff(deg)) > 180.0) + 1
    return np.insert(f.astype(float), cut, np.nan), np.insert(deg.astype(float), cut, np.nan)


def _hz(f: float) -> str:
    """A band edge in plain digits (``1000``, not ``1e+03``): whole hertz from 100 Hz, else three digits."""
    return f"{f:.0f}" if f >= 100 else f"{f:.3g}"


def _bands_figure(plt: Any, loc: Localisation) -> Any:
    """Residual and model-error energy per frequency band."""
    names = loc.sensor_names
    n_out = len(names)
    # residual energy per band
    fig, axes = plt.subplots(n_out, 1, figsize=(7, 2.2 * n_out), squeeze=False)
    for o, ax in enumerate(axes[:, 0]):
        bs = [b for b in loc.bands if b.sensor == names[o]]
        labels = [f"{_hz(b.f_lo)}–{_hz(b.f_hi)}" + (f"\nmode {b.mode}" if b.mode else "") for b in bs]
        x = np.arange(len(bs))
        ax.bar(x - 0.2, [b.residual_fraction or 0.0 for b in bs], width=0.4, label="residual energy")
        ax.bar(x + 0.2, [0.0 if not np.isfinite(b.excess_fraction) else b.excess_fraction for b in bs],
               width=0.4, label="model-error energy")
        ax.set_xticks(x, labels, fontsize=8)
        ax.set_ylabel(f"{names[o]}: energy fraction [-]", fontsize=8)
        ax.set_ylim(0, 1)
    _outside_legend(axes[0, 0])
    axes[-1, 0].set_xlabel("band [Hz]")
    return fig
