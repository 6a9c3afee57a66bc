"""Result types of the localisation (per sensor, mode, band, time window, amplitude level; residual tests),
serialised to JSON in one place."""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ebb_model.io.jsonio import jsonable


# ----------------------------------------------------------------------------------------------
# result types
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SensorGap:
    """Overall residual statistics of one sensor."""

    sensor: str
    nrmse: float                 #: ||y - y_hat|| / ||y - mean(y)||
    residual_rms: float          #: RMS of y - y_hat
    residual_mean: float         #: mean of y - y_hat (static offset; excluded from gap_ratio)
    noise_std: float             #: noise std (model-free estimate or given)
    noise_method: str            #: "psd_floor", "difference_mad" or "given"
    gap_ratio: float             #: var(y - y_hat) / noise_std²
    model_error_fraction: float  #: max(0, 1 - noise_std² / MSE)
    gap_detected: bool           #: gap_ratio >= gap_ratio_limit, or input-correlated residual and gap_ratio >= 1.1,
    #: or an offset with residual_mean² / noise_std² >= gap_ratio_limit - 1


@dataclass(frozen=True)
class ModeGap:
    """Measured versus model behaviour at one model mode, seen by one sensor."""

    sensor: str
    mode: int                    #: 1-based index into mode_freqs_hz
    input: str                   #: input whose FRF to this sensor is analysed (largest model response)
    model_freq_hz: float         #: given model modal frequency
    model_damping: float | None  #: given model damping ratio
    excited: bool                #: the input has power in the mode's band
    observed: bool               #: the model FRF peaks at the mode here (the sensor is not at a node)
    fit_ok: bool                 #: both local SDOF fits succeeded (frequency, damping, amplitude from fits)
    freq_method: str             #: "sdof_fit", "peak" (unresolved: interpolated peaks of both FRFs) or "none"
    model_fit_freq_hz: float     #: natural frequency fitted to (or peak of) the model FRF
    measured_freq_hz: float      #: natural frequency fitted to (or peak of) the measured FRF
    freq_shift_rel: float        #: (measured - model_fit) / model_fit
    freq_shift_std: float        #: standard error of freq_shift_rel
    freq_shift_p: float          #: two-sided p-value of the shift (not corrected)
    model_fit_damping: float     #: damping ratio fitted to the model FRF
    measured_damping: float      #: damping ratio fitted to the measured FRF
    damping_ratio: float         #: measured / model_fit damping
    damping_ratio_std: float     #: standard error of damping_ratio
    damping_p: float             #: two-sided p-value of ln(damping_ratio) != 0
    damping_resolved: bool       #: half-power bandwidth spans >= 3 frequency bins
    amplitude_ratio: float       #: |H_meas(f_meas)| / |H_model(f_model)| from the fits
    phase_diff_deg: float        #: angle(H_meas(f_meas) / H_model(f_model)) [deg]
    band_gain: float             #: |c|, c = LS complex gain of H_meas over H_model in the mode window
    band_phase_deg: float        #: angle(c) [deg]
    band_gain_p: float           #: p-value of c != 1 (not corrected)
    coherence: float             #: mean coherence of the measured FRF in the window
    band_excess_fraction: float  #: share of the sensor's model-error energy in this mode's band
    significant: tuple[str, ...]  #: subset of ("frequency", "damping", "amplitude/phase")


@dataclass(frozen=True)
class BandGap:
    """Residual energy of one sensor in one frequency band."""

    sensor: str
    f_lo: float
    f_hi: float
    mode: int | None             #: 1-based mode the band contains, None for the band above the last mode
    residual_fraction: float     #: residual energy in the band / total residual energy
    noise_fraction: float        #: white-noise energy expected in the band / total residual energy
    excess_fraction: float       #: max(0, residual - noise) in the band / sum over bands (model-error share)


@dataclass(frozen=True)
class WindowGap:
    """Per-time-window statistics of one sensor and their trends (drift).

    ``y_lin`` is the best linear approximation of ``y``: the inputs filtered by
    the measured H1 FRF.
    """

    sensor: str
    t_center: tuple[float, ...]  #: window centres [s]
    rms: tuple[float, ...]       #: model residual RMS (y - y_hat) per window
    linear_rms: tuple[float, ...]  #: RMS of y - y_lin per window (y_lin: best linear approximation, see below)
    gain: tuple[float, ...]      #: |c| per window, y ≈ Re(c · analytic(y_lin))
    phase_deg: tuple[float, ...]  #: angle(c) per window [deg], unwrapped
    rms_change: float            #: fitted change of linear_rms over the record / its mean
    rms_p: float
    gain_change: float           #: fitted gain change over the record
    gain_p: float
    phase_change_deg: float      #: fitted phase change over the record [deg]
    phase_p: float
    drift: bool                  #: a significant (Bonferroni) and non-trivial trend
    #: what a linear time-invariant record shows per window under the same input (the linear twins of
    #: :mod:`diagnosis.localise.trends`): the mean gain and phase [deg] and their standard deviations
    twin_gain: tuple[float, ...] = ()
    twin_gain_sd: tuple[float, ...] = ()
    twin_phase_deg: tuple[float, ...] = ()
    twin_phase_sd: tuple[float, ...] = ()


@dataclass(frozen=True)
class AmplitudeGap:
    """Statistics of one sensor conditioned on the response envelope (nonlinearity).

    Levels are the envelope ``|y_lin + i H y_lin|`` of the best linear
    approximation; gains are those of ``y`` over ``y_lin``.
    """

    sensor: str
    level: tuple[float, ...]     #: mean envelope per (record-wide) quantile bin
    residual_rms: tuple[float, ...]  #: model residual (y - y_hat) RMS per bin
    relative_residual: tuple[float, ...]  #: residual RMS / RMS(y_hat - mean) per bin
    gain: tuple[float, ...]      #: |c| per bin
    phase_deg: tuple[float, ...]  #: angle(c) per bin [deg]
    rms_exponent: float          #: d ln(noise-corrected model residual RMS) / d ln(level); linear error <= 1
    gain_slope: float            #: d|c| / d ln(level), within-window, mean over windows
    gain_p: float
    phase_slope_deg: float       #: d angle(c) / d ln(level) [deg]
    phase_p: float
    nonlinear: bool              #: a significant (Bonferroni) and non-trivial slope
    #: the linear twins' gain per bin (mean, standard deviation): what a linear record shows there
    twin_gain: tuple[float, ...] = ()
    twin_gain_sd: tuple[float, ...] = ()


@dataclass(frozen=True)
class Whiteness:
    """Residual autocorrelation of one sensor."""

    sensor: str
    autocorr: tuple[float, ...]  #: normalised autocorrelation at lags 1 … max_lag
    band: float                  #: 99 % band ±2.58/√n
    fraction_outside: float
    max_abs: float
    ljung_box_q: float
    ljung_box_p: float
    white: bool                  #: ljung_box_p >= 0.01


@dataclass(frozen=True)
class CrossCorrelation:
    """Residual of one sensor versus one input."""

    sensor: str
    input: str
    xcorr: tuple[float, ...]     #: normalised r_eu(k) = Σ e(t) u(t-k) / √(Σe² Σu²), k = -max_lag … max_lag
    band: float                  #: 99 % band
    fraction_outside: float
    max_abs: float
    max_lag: int                 #: lag of max |r_eu| (positive: residual follows the input)
    chi2: float                  #: portmanteau n r^T C⁺ r over all lags (C: Bartlett covariance under independence)
    dof: int                     #: its degrees of freedom
    p: float                     #: chi-square p-value (not corrected)
    significant: bool            #: p × (n_out n_in) < 0.01 and at least one lag outside the 99 % band


@dataclass(frozen=True)
class Localisation:
    """Result of :func:`localise`; ``to_dict()`` is JSON-able, ``table()`` gives rows."""

    sensor_names: tuple[str, ...]
    input_names: tuple[str, ...]
    dt: float
    n_samples: int
    nperseg: int                 #: Welch segment length of the FRF / PSD estimates
    df_hz: float                 #: their frequency resolution
    max_lag: int
    alpha: float
    gap_detected: bool
    sensors: tuple[SensorGap, ...]
    modes: tuple[ModeGap, ...]
    bands: tuple[BandGap, ...]
    windows: tuple[WindowGap, ...]
    amplitude: tuple[AmplitudeGap, ...]
    whiteness: tuple[Whiteness, ...]
    cross_correlation: tuple[CrossCorrelation, ...]
    summary: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict (:func:`ebb_model.io.jsonio.jsonable`: NaN → None, ±inf → "inf", tuples → lists)."""
        return jsonable({f.name: getattr(self, f.name) for f in fields(self)})

    def table(self) -> list[tuple[str, str, str, str]]:
        """Rows ``(sensor, where, quantity, value)``; the first row is the header."""
        rows: list[tuple[str, str, str, str]] = [("sensor", "where", "quantity", "value")]
        for s in self.sensors:
            rows += [(s.sensor, "overall", "NRMSE", f"{s.nrmse:.4g}"),
                     (s.sensor, "overall", "gap ratio var(r)/σ²", f"{s.gap_ratio:.3g}"),
                     (s.sensor, "overall", "model-error share", f"{s.model_error_fraction:.1%}")]
        for m in self.modes:
            where = f"mode {m.mode} ({m.model_freq_hz:.4g} Hz, {m.input})"
            if not m.excited:
                rows.append((m.sensor, where, "excited", "no"))
                continue
            if m.fit_ok:
                rows += [(m.sensor, where, "frequency shift", f"{m.freq_shift_rel:+.3%} ± {m.freq_shift_std:.2%}"),
                         (m.sensor, where, "damping measured/model",
                          f"{m.damping_ratio:.3g} ({m.measured_damping:.3g}/{m.model_fit_damping:.3g})"
                          + ("" if m.damping_resolved else " unresolved")),
                         (m.sensor, where, "amplitude ratio, phase",
                          f"{m.amplitude_ratio:.3g}, {m.phase_diff_deg:+.1f}°")]
            rows.append((m.sensor, where, "band gain, phase", f"{m.band_gain:.3g}, {m.band_phase_deg:+.1f}°"))
            rows.append((m.sensor, where, "share of model-error energy", _pct(m.band_excess_fraction)))
        for b in self.bands:
            rows.append((b.sensor, f"{b.f_lo:.4g}–{b.f_hi:.4g} Hz", "residual / model-error energy",
                         f"{_pct(b.residual_fraction)} / {_pct(b.excess_fraction)}"))
        for w in self.windows:
            rows += [(w.sensor, "time", "linear-fit residual RMS change", f"{w.rms_change:+.1%} (p={w.rms_p:.2g})"),
                     (w.sensor, "time", "gain change over record", f"{w.gain_change:+.3g} (p={w.gain_p:.2g})"),
                     (w.sensor, "time", "phase change over record",
                      f"{w.phase_change_deg:+.2f}° (p={w.phase_p:.2g})")]
        for a in self.amplitude:
            rows += [(a.sensor, "amplitude", "gain slope per ln(level)", f"{a.gain_slope:+.3g} (p={a.gain_p:.2g})"),
                     (a.sensor, "amplitude", "phase slope per ln(level)",
                      f"{a.phase_slope_deg:+.2f}° (p={a.phase_p:.2g})"),
                     (a.sensor, "amplitude", "residual RMS exponent", f"{a.rms_exponent:.3g}")]
        for h in self.whiteness:
            rows.append((h.sensor, "whiteness", "Ljung–Box p, lags outside 99 %",
                         f"{h.ljung_box_p:.3g}, {h.fraction_outside:.0%}"))
        for c in self.cross_correlation:
            value = f"{c.max_abs:.3g} ({c.max_lag}), {c.fraction_outside:.0%} (band {c.band:.3g}), {c.p:.2g}"
            rows.append((c.sensor, f"input {c.input}", "max |xcorr| (lag), lags outside 99 %, p", value))
        return rows

    def table_text(self) -> str:
        """The :meth:`table` as aligned text, followed by the summary."""
        rows = self.table()
        w = [max(len(r[i]) for r in rows) for i in range(4)]
        lines = ["  ".join(c.ljust(w[i]) for i, c in enumerate(r)).rstrip() for r in rows]
        lines.insert(1, "  ".join("-" * x for x in w))
        lines.append("")
        lines += [f"* {s}" for s in self.summary] or ["* no significant gap: residuals are consistent with noise"]
        return "\n".join(lines)


def _pct(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{x:.0%}"
