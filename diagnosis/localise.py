"""Where the sim-to-real gap lies: residual analysis of an identified model against data.

Given the measured inputs ``u``, the measured outputs ``y`` and the outputs
``y_hat`` that the identified model simulates from the same inputs,
:func:`localise` splits the residual ``r = y - y_hat`` along five axes:

* **per sensor** — NRMSE, the *gap ratio* ``var(r) / σ²`` against a model-free
  noise estimate (:mod:`.noise`; 1 means the model explains everything but
  noise) and the model-error share ``max(0, 1 - σ²/MSE)`` of the residual energy;
* **per mode / frequency band** — measured and model FRFs are estimated by the
  *same* H1 Welch estimator (``H = S_yu S_uu⁻¹``, Hann, 50 % overlap; only bins
  where the input has power), so estimator bias (leakage, smearing) cancels in
  the comparison.  Around each model mode a local SDOF rational fit
  ``(b0 + b1 s + b2 s²)/(s² + 2ζω_n s + ω_n²)`` (Sanathanan–Koerner start,
  Levenberg–Marquardt refinement, covariance from the Jacobian) gives the
  natural frequency and damping ratio of both FRFs with standard errors, hence
  the relative frequency shift, the damping ratio measured/model, amplitude ratio
  and phase difference at the mode.  When a fit fails (typically a lightly damped
  mode narrower than the resolution) the peaks of both FRFs are located on a 4×
  zero-padded grid with parabolic refinement; the error of that shift is the
  larger of the H1 random error and the scatter between the two halves of the
  record, and the damping is then reported as not measurable.  A mode at whose
  frequency the model FRF shows no peak (sensor at a node) is marked as not
  observed.  A least-squares complex gain of the measured
  over the model FRF over the mode's band gives amplitude/phase even when only a
  few lines are excited (multisine).  The residual PSD is integrated over bands
  between mode midpoints, minus the white-noise share, to say in which band the
  model-error energy sits;
* **per time window** — the model residual RMS per window (descriptive) and,
  to judge drift, the fit of ``y`` by its *best linear approximation*
  ``y_lin`` (``u`` filtered by the measured H1 FRF, i.e. the best time-invariant
  linear model the data allow): RMS of ``y - y_lin`` and the local complex gain
  ``c`` with ``y ≈ Re(c (y_lin + i H y_lin))`` (least squares on ``y_lin`` and its
  Hilbert transform: amplitude ratio and phase) per window; linear trends whose
  p-value is the larger of the OLS t-test and a t-test with the sampling variance
  of a window value estimated from four sub-windows.  A slowly drifting resonance shows as a phase trend even when the
  residual RMS is V-shaped (a model fitted to the whole record matches its
  middle); because ``y_lin`` already carries every time-invariant linear error,
  a sweep input with a wrong model cannot fake a trend;
* **per amplitude level** — within every time window the samples are binned by
  quantiles of the response envelope ``|y_lin + i H y_lin|`` and the local complex
  gain of ``y`` over ``y_lin`` is computed per bin; the slope of gain (and phase)
  against ``ln(level)`` is averaged over windows and t-tested across them.  A
  time-invariant linear system gives no slope (its output *is* ``y_lin`` plus
  noise), whatever the model error and whether the input is random, swept or a
  multisine; a significant slope indicates an amplitude-dependent (nonlinear)
  effect.  The model residual RMS per envelope bin and its log–log exponent
  (noise removed; linear errors ≤ 1, e.g. cubic distortion ≈ 2) are reported
  for reading;
* **whiteness and input correlation** — normalised residual autocorrelation at
  lags ``1 … max_lag`` with the 99 % band ``±2.58/√n`` and the Ljung–Box test,
  and the residual–input cross-correlation at lags ``-max_lag … max_lag`` with
  the 99 % band ``±2.58 √(Σ_τ ρ_r(τ) ρ_u(τ) / n)`` (as MATLAB's ``resid``); its
  decision is a portmanteau ``n rᵀ C⁺ r ~ χ²`` with ``C`` Bartlett's covariance
  of the lags under independence, so neighbouring lags correlated through a
  coloured input are not counted as separate evidence.

Significance decisions use the level ``alpha`` with a Bonferroni correction
over the tests of a family (all sensors × statistics), and also a minimal
practical size, so that long records do not name trivial deviations.  Nothing
is named for a sensor whose residual is consistent with its noise.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from scipy import fft as sfft
from scipy import optimize, signal, stats

from ebb_model.errors import ConfigError, DataError

from identification.noise import noise_estimate

__all__ = [
    "AmplitudeGap",
    "BandGap",
    "CrossCorrelation",
    "FrfEstimate",
    "Localisation",
    "ModeGap",
    "SensorGap",
    "Whiteness",
    "WindowGap",
    "choose_nperseg",
    "estimate_frf",
    "localise",
    "residual_correlations",
]

#: 99 % two-sided normal quantile used for the correlation bands.
Z99 = 2.5758293035489004
#: Input PSD below this fraction of its maximum: the bin is "not excited".
EXCITE_REL = 1e-3
#: Practical minimum sizes for naming something in the summary.
MIN_SHIFT = 1e-3          # relative frequency shift
MIN_DAMPING_RATIO = 1.2   # damping ratio measured/model (or its inverse)
MIN_GAIN = 0.05           # relative amplitude change
MIN_PHASE_DEG = 3.0       # phase change [deg]
MIN_RMS_CHANGE = 0.2      # relative RMS change over the record
#: Zero-padding factor of the FRFs used to locate peaks and to build the best linear approximation.
PAD = 4
#: Sub-windows per time window for the sampling variance of window statistics.
_SUB = 4


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
    gap_detected: bool           #: gap_ratio >= gap_threshold, or input-correlated residual and gap_ratio >= 1.1,
    #: or an offset with residual_mean² / noise_std² >= gap_threshold - 1


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
        """Plain JSON-able dict (NaN/inf → None, tuples → lists)."""
        return _jsonable({f.name: getattr(self, f.name) for f in fields(self)})

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


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if hasattr(x, "__dataclass_fields__"):
        return {f.name: _jsonable(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


# ----------------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------------
def _matrix(a: Any, name: str) -> np.ndarray:
    try:
        m = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"{name}: not a numeric array") from None
    if m.ndim == 1:
        m = m[:, None]
    if m.ndim != 2 or m.shape[1] == 0:
        raise DataError(f"{name}: expected shape (n_samples,) or (n_samples, n_channels), got {np.shape(a)}")
    bad = np.argwhere(~np.isfinite(m))
    if len(bad):
        raise DataError(f"{name}: non-finite value (NaN/inf) at sample {bad[0, 0]}, column {bad[0, 1]}")
    return m


def _names(names: Sequence[str] | None, k: int, what: str, default: str) -> tuple[str, ...]:
    if names is None:
        return tuple(f"{default}{i + 1}" for i in range(k))
    if isinstance(names, str):
        names = [names]
    names = tuple(str(s) for s in names)
    if len(names) != k:
        raise DataError(f"{what}: {len(names)} names for {k} columns")
    if len(set(names)) != len(names):
        raise ConfigError(f"{what}: names must be unique, got {list(names)}")
    return names


def _check_dt(dt: Any) -> float:
    try:
        v = float(dt)
    except (TypeError, ValueError):
        raise ConfigError(f"dt: must be a number > 0, got {dt!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ConfigError(f"dt: must be a finite number > 0, got {dt!r}")
    return v


# ----------------------------------------------------------------------------------------------
# spectra
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class FrfEstimate:
    """H1 frequency-response estimate (Welch, Hann, 50 % overlap).

    Attributes
    ----------
    f
        Frequencies [Hz], shape ``(nf,)``.
    H
        FRF ``(nf, n_out, n_in)``, ``H = S_yu S_uu⁻¹`` per bin.
    coherence
        Multiple coherence per output ``(nf, n_out)``.
    excited
        ``(nf, n_in)``: input PSD ≥ ``EXCITE_REL`` × its maximum.
    n_segments, nperseg
        Number of averaged segments and their length.
    """

    f: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    excited: np.ndarray
    n_segments: int
    nperseg: int


def _segment_fft(x: np.ndarray, nperseg: int, pad: int = 1) -> np.ndarray:
    """Hann-windowed, per-segment demeaned rFFT (zero-padded ``pad``×) of 50 %-overlapping segments.

    Returns ``(K, nf, c)``.
    """
    step = max(nperseg // 2, 1)
    k = 1 + (x.shape[0] - nperseg) // step
    idx = np.arange(nperseg)[None, :] + step * np.arange(k)[:, None]
    seg = x[idx]
    seg = seg - seg.mean(axis=1, keepdims=True)
    win = signal.get_window("hann", nperseg)
    return sfft.rfft(seg * win[None, :, None], n=pad * nperseg, axis=1)


def choose_nperseg(n: int, dt: float, mode_freqs_hz: Sequence[float],
                   mode_damping: Sequence[float] | None = None) -> int:
    """Welch segment length: ≈ 4 bins per half-power bandwidth of the sharpest mode.

    Capped so that at least 8 segments (50 % overlap) are averaged, and at least
    ``min(n, 256)``.
    """
    cap = max(2 * n // 9, min(n, 256))
    if len(mode_freqs_hz) == 0:
        return int(min(cap, max(min(n, 256), n // 8)))
    z = np.full(len(mode_freqs_hz), 0.01) if mode_damping is None else np.maximum(np.asarray(mode_damping), 1e-4)
    bw = float(np.min(np.asarray(mode_freqs_hz) * z))  # half of the half-power bandwidth 2ζf
    target = math.ceil(2.0 / (bw * dt))
    return int(min(cap, max(target, min(n, 256))))


def estimate_frf(dt: float, u: np.ndarray, y: np.ndarray, *, nperseg: int, pad: int = 1) -> FrfEstimate:
    """H1 FRF estimate from inputs ``u (n, n_in)`` to outputs ``y (n, n_out)``.

    Parameters
    ----------
    dt
        Sample time [s].
    u, y
        Input and output arrays with the same number of samples.
    nperseg
        Segment length.
    pad
        Zero-padding factor of the segments (``pad > 1`` samples the same,
        equally smeared spectra on a ``pad``× finer grid, e.g. to locate peaks).

    Returns
    -------
    FrfEstimate
    """
    u2 = _matrix(u, "u")
    y2 = _matrix(y, "y")
    nperseg = int(min(nperseg, u2.shape[0]))
    U = _segment_fft(u2, nperseg, pad)
    Y = _segment_fft(y2, nperseg, pad)
    k = U.shape[0]
    suu = np.einsum("kfi,kfj->fij", U, U.conj()) / k
    syu = np.einsum("kfo,kfj->foj", Y, U.conj()) / k
    syy = np.mean(np.abs(Y) ** 2, axis=0)
    n_in = u2.shape[1]
    reg = 1e-12 * np.maximum(np.trace(suu, axis1=1, axis2=2).real, 1e-300)[:, None, None] * np.eye(n_in)
    # H suu = syu  <=>  suu^T H^T = syu^T
    H = np.swapaxes(np.linalg.solve(np.swapaxes(suu + reg, 1, 2), np.swapaxes(syu, 1, 2)), 1, 2)
    num = np.einsum("foj,foj->fo", H, syu.conj()).real
    coh = np.clip(num / np.maximum(syy, 1e-300), 0.0, 1.0)
    pu = np.real(np.diagonal(suu, axis1=1, axis2=2))
    excited = pu >= EXCITE_REL * pu.max(axis=0, keepdims=True)
    f = sfft.rfftfreq(pad * nperseg, dt)
    return FrfEstimate(f=f, H=H, coherence=coh, excited=excited, n_segments=k, nperseg=nperseg)


def _welch_psd(x: np.ndarray, dt: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """One-sided PSD (density) per column, same segmentation as :func:`estimate_frf`."""
    X = _segment_fft(x, nperseg)
    win = signal.get_window("hann", nperseg)
    p = np.mean(np.abs(X) ** 2, axis=0) * dt / np.sum(win ** 2)
    p[1:] *= 2.0
    if nperseg % 2 == 0:
        p[-1] /= 2.0
    return sfft.rfftfreq(nperseg, dt), p


# ----------------------------------------------------------------------------------------------
# local SDOF fit
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Sdof:
    fn: float
    fn_std: float
    zeta: float
    zeta_std: float
    h_at_fn: complex
    rel_resid: float


def _fit_sdof(f: np.ndarray, h: np.ndarray, f0: float, zeta0: float) -> _Sdof | None:
    """Fit ``(b0 + b1 s + b2 s²)/(s² + 2ζω s + ω²)`` (s normalised by 2π f0) to ``h(f)``."""
    m = len(f)
    if m < 6 or not np.all(np.isfinite(h)):
        return None
    s = 1j * f / f0
    scale = float(np.max(np.abs(h)))
    if scale <= 0:
        return None
    hn = h / scale
    a1, a0 = 2.0 * zeta0, 1.0
    for _ in range(8):  # Sanathanan–Koerner iterations of Levy's linearisation
        wgt = 1.0 / np.abs(s ** 2 + a1 * s + a0)
        cols = np.stack([np.ones_like(s), s, s ** 2, -hn, -hn * s], axis=1) * wgt[:, None]
        rhs = hn * s ** 2 * wgt
        A = np.vstack([cols.real, cols.imag])
        b = np.concatenate([rhs.real, rhs.imag])
        theta, *_ = np.linalg.lstsq(A, b, rcond=None)
        a0, a1 = float(theta[3]), float(theta[4])
        if not (a0 > 0 and a1 > 0):
            return None
    wn0 = math.sqrt(a0)
    x0 = np.array([wn0, a1 / (2 * wn0), *theta[:3]])

    def resid(x: np.ndarray) -> np.ndarray:
        wn, z, b0, b1, b2 = x
        r = (b0 + b1 * s + b2 * s ** 2) / (s ** 2 + 2 * z * wn * s + wn ** 2) - hn
        return np.concatenate([r.real, r.imag])

    try:
        sol = optimize.least_squares(resid, x0, method="lm", x_scale="jac", max_nfev=400)
    except (ValueError, np.linalg.LinAlgError):
        return None
    wn, z, b0, b1, b2 = sol.x
    if not (wn > 0 and 0 < z < 0.5 and f[0] <= wn * f0 <= f[-1]):
        return None
    dof = 2 * m - 5
    s2 = float(np.sum(sol.fun ** 2)) / dof
    jtj = sol.jac.T @ sol.jac
    try:
        cov = np.linalg.pinv(jtj) * s2 * 2.0  # ×2: neighbouring Hann bins are correlated
    except np.linalg.LinAlgError:
        return None
    sn = 1j * wn
    h_fn = (b0 + b1 * sn + b2 * sn ** 2) / (sn ** 2 + 2 * z * wn * sn + wn ** 2) * scale
    rel = float(np.linalg.norm(sol.fun) / np.linalg.norm(np.concatenate([hn.real, hn.imag])))
    return _Sdof(fn=wn * f0, fn_std=math.sqrt(max(cov[0, 0], 0.0)) * f0, zeta=float(z),
                 zeta_std=math.sqrt(max(cov[1, 1], 0.0)), h_at_fn=complex(h_fn), rel_resid=rel)


def _peak_bin(f: np.ndarray, mag: np.ndarray, lo: float, hi: float) -> int | None:
    sel = np.flatnonzero((f >= lo) & (f <= hi) & np.isfinite(mag))
    if len(sel) == 0:
        return None
    return int(sel[np.argmax(mag[sel])])


# ----------------------------------------------------------------------------------------------
# small statistics helpers
# ----------------------------------------------------------------------------------------------
def _trend(t: np.ndarray, v: np.ndarray, var_v: float | None = None, dof_v: int = 0) -> tuple[float, float]:
    """OLS slope of ``v`` on ``t`` and a conservative two-sided p-value.

    The p-value is the larger of the plain OLS t-test (scatter about the line,
    ``n - 2`` dof) and, if ``var_v`` (the sampling variance of one value of
    ``v``, e.g. from sub-windows, with ``dof_v`` dof) is given, the t-test with
    that variance.  The first guards against correlated sub-windows, the second
    against a chance small scatter of a few points.
    """
    ok = np.isfinite(v)
    t, v = t[ok], v[ok]
    n = len(v)
    if n < 3:
        return float("nan"), float("nan")
    tc = t - t.mean()
    sxx = float(tc @ tc)
    slope = float(tc @ (v - v.mean()) / sxx)
    res = v - v.mean() - slope * tc
    ss = float(res @ res)
    if ss <= 1e-30 * max(float(v @ v), 1e-300):
        p = 0.0 if abs(slope) > 0 else 1.0
    else:
        p = float(2 * stats.t.sf(abs(slope) / math.sqrt(ss / (n - 2) / sxx), n - 2))
    if var_v is not None and dof_v > 0:
        p_w = 1.0 if var_v <= 0 and slope == 0 else \
            float(2 * stats.t.sf(abs(slope) / math.sqrt(max(var_v, 1e-300) / sxx), dof_v))
        p = max(p, p_w)
    return slope, p


def _local_gain(y: np.ndarray, yh: np.ndarray, yq: np.ndarray) -> complex:
    """Complex c with y ≈ Re(c (yh + i yq)) = Re(c) yh - Im(c) yq, least squares."""
    A = np.stack([yh, yq], axis=1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return complex(coef[0], -coef[1])


def _hilbert(x: np.ndarray) -> np.ndarray:
    """Hilbert transform of the columns of ``x`` (imaginary part of the analytic signal)."""
    n = x.shape[0]
    return np.imag(signal.hilbert(x, N=sfft.next_fast_len(n), axis=0)[:n])


def _peak_location(f: np.ndarray, h: np.ndarray, coh: np.ndarray, usable: np.ndarray, k_seg: int, pad: int,
                   lo: float, hi: float) -> tuple[float, float, int] | None:
    """Peak of ``|h|`` in ``[lo, hi]`` on a ``pad``× zero-padded grid, refined by a parabola in ``ln|h|``.

    The parabola uses the points one *resolution* bin (``pad`` fine bins) either
    side, whose errors are nearly independent; the standard error follows from
    the H1 random error of ``ln|h|``, ``(1 - γ²) / (2 K γ²)`` (Bendat & Piersol),
    plus 1 % of a bin for the interpolation.  Returns ``(f_peak, std, index)``
    or ``None`` when the maximum lies on the border of the range (no peak).
    """
    sel = np.flatnonzero((f >= lo) & (f <= hi) & usable & np.isfinite(h))
    if len(sel) < 3:
        return None
    i = int(sel[np.argmax(np.abs(h[sel]))])
    if i - pad < 0 or i + pad >= len(f) or not (usable[i - pad] and usable[i + pad]) \
            or i in (sel[0], sel[-1]):
        return None
    a, b, c = (math.log(max(abs(h[j]), 1e-300)) for j in (i - pad, i, i + pad))
    den = a - 2 * b + c
    if not den < 0:
        return None
    x = 0.5 * (a - c) / den
    step = float(f[pad] - f[0])
    g2 = np.clip(coh[[i - pad, i, i + pad]], 1e-6, 1 - 1e-9)
    var = (1 - g2) / (2 * k_seg * g2)
    grad = np.array([c - b, a - c, b - a]) / den ** 2
    std = step * math.sqrt(float(grad ** 2 @ var) + 1e-4)
    return float(f[i] + x * step), std, i


def _linear_prediction(dt: float, u: np.ndarray, frf: FrfEstimate) -> np.ndarray:
    """Demeaned output predicted from ``u`` through ``frf.H`` (interpolated, zero where not excited)."""
    n = u.shape[0]
    nfft = sfft.next_fast_len(n + frf.nperseg)  # zero padding: no wrap-around of the response
    U = sfft.rfft(u - u.mean(axis=0), nfft, axis=0)
    ff = sfft.rfftfreq(nfft, dt)
    near = np.clip(np.rint(ff / frf.f[1]).astype(int), 0, len(frf.f) - 1)
    out = np.zeros((n, frf.H.shape[1]))
    for j in range(u.shape[1]):
        mask = frf.excited[near, j]
        for o in range(frf.H.shape[1]):
            h = np.interp(ff, frf.f, frf.H[:, o, j].real) + 1j * np.interp(ff, frf.f, frf.H[:, o, j].imag)
            out[:, o] += sfft.irfft(np.where(mask, h, 0.0) * U[:, j], nfft)[:n]
    return out


def _quantile_bins(x: np.ndarray, k: int) -> np.ndarray:
    """Label 0 … k-1 of each sample of ``x`` by its quantile bin."""
    qs = np.quantile(x, np.linspace(0, 1, k + 1))
    return np.clip(np.searchsorted(qs, x, side="right") - 1, 0, k - 1)


def _mean_t(v: Sequence[float]) -> tuple[float, float]:
    """Mean of ``v`` and the two-sided one-sample t-test p-value of mean = 0."""
    if len(v) < 3:
        return float("nan"), float("nan")
    a = np.asarray(v, dtype=float)
    sd = float(np.std(a, ddof=1))
    if sd == 0:
        return float(a.mean()), (0.0 if a.mean() != 0 else 1.0)
    return float(a.mean()), float(2 * stats.t.sf(abs(a.mean()) / (sd / math.sqrt(len(a))), len(a) - 1))


def _autocorr_full(x: np.ndarray) -> np.ndarray:
    """Biased autocorrelation ``Σ_t x(t) x(t+k)`` for k = 0 … n-1 (columns)."""
    n = x.shape[0]
    nf = sfft.next_fast_len(2 * n)
    X = sfft.rfft(x, nf, axis=0)
    return sfft.irfft(np.abs(X) ** 2, nf, axis=0)[:n]


def residual_correlations(r: np.ndarray, u: np.ndarray, max_lag: int
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Normalised residual autocorrelation and residual–input cross-correlation with bands.

    Parameters
    ----------
    r
        Residuals ``(n, n_out)``.
    u
        Inputs ``(n, n_in)``.
    max_lag
        Largest lag ``m``.

    Returns
    -------
    acf
        ``(m, n_out)`` autocorrelation at lags ``1 … m``.
    xcf
        ``(2m+1, n_out, n_in)`` cross-correlation ``Σ r(t) u(t-k) / √(Σr² Σu²)``, ``k = -m … m``.
    xband
        ``(n_out, n_in)`` 99 % band half-widths of ``xcf``.
    chi2, dof
        ``(n_out, n_in)`` portmanteau statistic ``n r^T C⁺ r`` over all lags, with
        ``C`` the Bartlett covariance of the lags under independence (so lags
        correlated through a coloured input are not counted twice), and its
        degrees of freedom (rank kept in ``C⁺``); ``chi2 ~ χ²(dof)`` under independence.
    """
    n = r.shape[0]
    rc = r - r.mean(axis=0)
    uc = u - u.mean(axis=0)
    ar = _autocorr_full(rc)
    au = _autocorr_full(uc)
    r0 = ar[0]
    u0 = au[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        rho_r = np.where(r0 > 0, ar / np.where(r0 > 0, r0, 1.0), 0.0)
        rho_u = au / u0
    acf = rho_r[1:max_lag + 1]
    nf = sfft.next_fast_len(2 * n)
    R = sfft.rfft(rc, nf, axis=0)
    U = sfft.rfft(uc, nf, axis=0)
    cc = sfft.irfft(R[:, :, None] * U[:, None, :].conj(), nf, axis=0)  # cc[k] = Σ_t r(t+k) u(t)... see below
    lags = np.arange(-max_lag, max_lag + 1)
    # Σ_t r(t) u(t-k) = Σ_s r(s+k) u(s) = cc[k mod nf]
    xc = cc[lags % nf]
    norm = np.sqrt(np.maximum(r0, 1e-300)[:, None] * u0[None, :])
    xcf = np.where(r0[None, :, None] > 0, xc / norm[None], 0.0)
    L = int(min(n // 5, 20 * max_lag))
    # Bartlett: cov(√n r(k), √n r(j)) = g(k - j) = Σ_τ ρ_r(τ) ρ_u(τ + k - j) under independence
    m2 = 2 * max_lag
    lr = np.concatenate([rho_r[L:0:-1], rho_r[:L + 1]], axis=0)  # lags -L … L
    lu_full = rho_u[:L + m2 + 1]
    lu = np.concatenate([lu_full[:0:-1], lu_full], axis=0)  # lags -(L+2m) … L+2m
    n_out, n_in = r.shape[1], u.shape[1]
    xband = np.empty((n_out, n_in))
    chi2 = np.empty((n_out, n_in))
    dof = np.zeros((n_out, n_in), dtype=int)
    for o in range(n_out):
        for j in range(n_in):
            g = np.correlate(lu[:, j], lr[:, o], mode="valid")  # g[i] ↔ lag difference i - 2m
            xband[o, j] = Z99 * math.sqrt(max(g[m2], 0.25) / n)
            cov = g[np.abs(np.arange(-max_lag, max_lag + 1)[:, None] - np.arange(-max_lag, max_lag + 1)[None, :])
                    + m2]
            lam, vec = np.linalg.eigh(0.5 * (cov + cov.T))
            keep = lam > 1e-3 * max(lam.max(), 1e-300)
            proj = vec[:, keep].T @ xcf[:, o, j]
            chi2[o, j] = float(n * np.sum(proj ** 2 / lam[keep]))
            dof[o, j] = int(np.count_nonzero(keep))
    return acf, xcf, xband, chi2, dof


# ----------------------------------------------------------------------------------------------
# main entry point
# ----------------------------------------------------------------------------------------------
def localise(dt: float, u: np.ndarray, y: np.ndarray, y_hat: np.ndarray, sensor_names: Sequence[str],
             mode_freqs_hz: Sequence[float], mode_damping: Sequence[float] | None = None, *,
             noise_std: float | Sequence[float] | None = None, windows: int = 8, amplitude_bins: int = 4,
             input_names: Sequence[str] | None = None, max_lag: int = 25, alpha: float = 1e-3,
             gap_threshold: float = 1.5, nperseg: int | None = None) -> Localisation:
    """Locate the gap between measured outputs and model outputs.

    Parameters
    ----------
    dt
        Sample time [s], ``> 0``.
    u
        Measured inputs (forces), shape ``(n,)`` or ``(n, n_in)``.
    y
        Measured outputs, ``(n,)`` or ``(n, n_out)``.
    y_hat
        Model outputs simulated from the same ``u``, same shape as ``y``.
    sensor_names
        One name per output column.
    mode_freqs_hz
        Model modal frequencies [Hz] (modes in the excited band), each in ``(0, Nyquist)``.
    mode_damping
        Model damping ratios of those modes in ``[0, 1)`` (optional; used for the
        frequency resolution and the fit windows).
    noise_std
        Measurement-noise std per sensor (scalar or ``(n_out,)``); default: the
        model-free estimate of :func:`identification.noise.noise_estimate` with the
        excited band taken from the input PSD.
    windows
        Number of equal time windows (≥ 3).
    amplitude_bins
        Number of envelope-quantile bins (≥ 2).
    input_names
        One name per input column (default ``u1, u2, …``).
    max_lag
        Lags of the auto- and cross-correlation (MATLAB ``resid`` default 25).
    alpha
        Family-wise significance level for naming drift, nonlinearity and mode deviations.
    gap_threshold
        Gap ratio ``var(r)/σ²`` from which a sensor counts as having a model error.
    nperseg
        Welch segment length (default :func:`choose_nperseg`).

    Returns
    -------
    Localisation

    Raises
    ------
    ConfigError
        Bad ``dt``, modes, damping, counts or levels.
    DataError
        Non-finite values, mismatched shapes or names, constant channels, too few samples.
    """
    dt = _check_dt(dt)
    u2 = _matrix(u, "u")
    y2 = _matrix(y, "y")
    yh2 = _matrix(y_hat, "y_hat")
    n, n_out = y2.shape
    n_in = u2.shape[1]
    if u2.shape[0] != n:
        raise DataError(f"u has {u2.shape[0]} samples but y has {n}")
    if yh2.shape != y2.shape:
        raise DataError(f"y_hat has shape {yh2.shape} but y has shape {y2.shape}")
    snames = _names(sensor_names, n_out, "sensor_names", "y")
    inames = _names(input_names, n_in, "input_names", "u")
    problems = []
    if not (isinstance(windows, (int, np.integer)) and windows >= 3):
        problems.append(f"windows: must be an integer >= 3, got {windows!r}")
    if not (isinstance(amplitude_bins, (int, np.integer)) and amplitude_bins >= 2):
        problems.append(f"amplitude_bins: must be an integer >= 2, got {amplitude_bins!r}")
    if not (isinstance(max_lag, (int, np.integer)) and max_lag >= 1):
        problems.append(f"max_lag: must be an integer >= 1, got {max_lag!r}")
    if not (isinstance(alpha, (int, float)) and 0 < alpha < 1):
        problems.append(f"alpha: must be in (0, 1), got {alpha!r}")
    if not (isinstance(gap_threshold, (int, float)) and math.isfinite(gap_threshold) and gap_threshold > 1):
        problems.append(f"gap_threshold: must be a number > 1, got {gap_threshold!r}")
    if nperseg is not None and not (isinstance(nperseg, (int, np.integer)) and 16 <= nperseg <= n):
        problems.append(f"nperseg: must be an integer in [16, n_samples = {n}], got {nperseg!r}")
    fnyq = 0.5 / dt
    try:
        mf = np.atleast_1d(np.asarray(mode_freqs_hz, dtype=float))
    except (TypeError, ValueError):
        raise ConfigError(f"mode_freqs_hz: not a list of numbers: {mode_freqs_hz!r}") from None
    if mf.ndim != 1 or not np.all(np.isfinite(mf)) or np.any(mf <= 0) or np.any(mf >= fnyq):
        problems.append(f"mode_freqs_hz: must be finite frequencies in (0, Nyquist = {fnyq:.6g} Hz), got {mf.tolist()}")
    elif np.any(np.diff(np.sort(mf)) <= 0):
        problems.append(f"mode_freqs_hz: frequencies must be distinct, got {mf.tolist()}")
    md = None
    if mode_damping is not None:
        try:
            md = np.atleast_1d(np.asarray(mode_damping, dtype=float))
        except (TypeError, ValueError):
            raise ConfigError(f"mode_damping: not a list of numbers: {mode_damping!r}") from None
        if md.shape != mf.shape or not np.all(np.isfinite(md)) or np.any(md < -1e-6) or np.any(md >= 1):
            problems.append(f"mode_damping: must be one ratio in [0, 1) per mode, got {md.tolist()}")
        else:
            md = np.maximum(md, 0.0)  # round-off of an undamped model
    if problems:
        raise ConfigError(problems)
    if n < max(64 * windows, 4 * max_lag + 8, 256):
        raise DataError(f"need at least {max(64 * windows, 4 * max_lag + 8, 256)} samples for {windows} windows, "
                        f"got {n}")
    for name, a, names in (("u", u2, inames), ("y", y2, snames)):
        flat = np.flatnonzero(np.ptp(a, axis=0) == 0)
        if len(flat):
            raise DataError(f"{name}: column {names[flat[0]]!r} is constant (no information)")
    order = np.argsort(mf)  # analysis in increasing frequency; reported indices refer to the caller's list
    mf = mf[order]
    mode_no = [int(i) + 1 for i in order]
    if md is not None:
        md = md[order]

    # ---- spectra -----------------------------------------------------------------------------
    if nperseg is None:
        nperseg = choose_nperseg(n, dt, mf, md)
    nperseg = int(nperseg)
    fr_m = estimate_frf(dt, u2, y2, nperseg=nperseg)
    fr_h = estimate_frf(dt, u2, yh2, nperseg=nperseg)
    fp_m = estimate_frf(dt, u2, y2, nperseg=nperseg, pad=PAD)
    fp_h = estimate_frf(dt, u2, yh2, nperseg=nperseg, pad=PAD)
    # the two halves of the record, for an empirical error of peak locations
    half = n // 2
    halves = [(estimate_frf(dt, u2[sl], y2[sl], nperseg=min(nperseg, half), pad=PAD),
               estimate_frf(dt, u2[sl], yh2[sl], nperseg=min(nperseg, half), pad=PAD))
              for sl in (slice(0, half), slice(half, n))]
    f = fr_m.f
    df = float(f[1] - f[0])

    # ---- noise -------------------------------------------------------------------------------
    if noise_std is None:
        pu = np.real(_welch_psd(u2, dt, nperseg)[1])
        exc_any = np.any(pu >= 1e-2 * pu.max(axis=0, keepdims=True), axis=1)  # within 20 dB of the peak
        f_hi = float(f[np.flatnonzero(exc_any)[-1]]) if exc_any.any() else 0.0
        if len(mf):
            f_hi = max(f_hi, 1.2 * float(mf[-1]))
        ne = noise_estimate(y2, dt, band=(0.0, f_hi))
        sig = ne.std
        nmeth = ne.method
    else:
        try:
            sig = np.broadcast_to(np.asarray(noise_std, dtype=float), (n_out,)).copy() \
                if np.ndim(noise_std) == 0 or np.size(noise_std) == n_out else None
        except (TypeError, ValueError):
            sig = None
        if sig is None or not np.all(np.isfinite(sig)) or np.any(sig <= 0):
            raise ConfigError(f"noise_std: must be > 0, one value or one per sensor ({n_out}), got {noise_std!r}")
        nmeth = ("given",) * n_out
    sig = np.maximum(sig, 1e-300)

    r = y2 - yh2
    mse = np.mean(r ** 2, axis=0)
    rmean = r.mean(axis=0)
    var_r = np.var(r, axis=0)

    # ---- correlations ------------------------------------------------------------------------
    acf, xcf, xband, xchi2, xdof = residual_correlations(r, u2, max_lag)
    wband = Z99 / math.sqrt(n)
    white_list: list[Whiteness] = []
    for o in range(n_out):
        rho = acf[:, o]
        k = np.arange(1, max_lag + 1)
        q = float(n * (n + 2) * np.sum(rho ** 2 / (n - k)))
        pq = float(stats.chi2.sf(q, max_lag))
        white_list.append(Whiteness(snames[o], tuple(map(float, rho)), wband,
                                    float(np.mean(np.abs(rho) > wband)), float(np.max(np.abs(rho))), q, pq,
                                    pq >= 0.01))
    xc_list: list[CrossCorrelation] = []
    for o in range(n_out):
        for j in range(n_in):
            c = xcf[:, o, j]
            outside = np.abs(c) > xband[o, j]
            kmax = int(np.argmax(np.abs(c)))
            px = float(stats.chi2.sf(xchi2[o, j], xdof[o, j]))
            xc_list.append(CrossCorrelation(snames[o], inames[j], tuple(map(float, c)), float(xband[o, j]),
                                            float(np.mean(outside)), float(np.abs(c[kmax])), kmax - max_lag,
                                            float(xchi2[o, j]), int(xdof[o, j]), px,
                                            bool(px * n_out * n_in < 0.01 and np.any(outside))))

    # ---- per sensor --------------------------------------------------------------------------
    sensors = []
    for o in range(n_out):
        yc = y2[:, o] - y2[:, o].mean()
        gap = float(var_r[o] / sig[o] ** 2)
        xsig = any(c.significant for c in xc_list if c.sensor == snames[o])
        sensors.append(SensorGap(
            sensor=snames[o], nrmse=float(np.linalg.norm(r[:, o]) / np.linalg.norm(yc)),
            residual_rms=float(math.sqrt(mse[o])), residual_mean=float(rmean[o]), noise_std=float(sig[o]),
            noise_method=nmeth[o], gap_ratio=gap,
            model_error_fraction=float(max(0.0, 1.0 - sig[o] ** 2 / mse[o])) if mse[o] > 0 else 0.0,
            gap_detected=bool(gap >= gap_threshold or (xsig and gap >= 1.1)
                              or rmean[o] ** 2 >= (gap_threshold - 1) * sig[o] ** 2)))

    # ---- bands -------------------------------------------------------------------------------
    _, pr = _welch_psd(r, dt, nperseg)
    if len(mf):
        mids = list((mf[1:] + mf[:-1]) / 2)
        top = min(fnyq, float(mf[-1]) + (float(mf[-1]) - (mids[-1] if mids else 0.0)))
        edges = [0.0] + mids + [top]
        band_modes: list[int | None] = list(mode_no)
        if top < fnyq * (1 - 1e-9):
            edges.append(fnyq)
            band_modes.append(None)
    else:
        edges, band_modes = [0.0, fnyq], [None]
    bands: list[BandGap] = []
    excess_by_mode: dict[tuple[int, int], float] = {}
    for o in range(n_out):
        n0 = 2.0 * sig[o] ** 2 * dt
        e_tot = float(np.sum(pr[:, o]) * df)
        rows = []
        for b in range(len(edges) - 1):
            lo, hi = edges[b], edges[b + 1]
            sel = (f >= lo) & ((f < hi) if b < len(edges) - 2 else (f <= hi))
            e = float(np.sum(pr[sel, o]) * df)
            en = n0 * (hi - lo)
            rows.append((lo, hi, e, en))
        exc = np.array([max(e - en, 0.0) for *_, e, en in rows])
        ex_tot = float(exc.sum())
        for b, (lo, hi, e, en) in enumerate(rows):
            ef = float(exc[b] / ex_tot) if ex_tot > 0 else float("nan")
            bands.append(BandGap(snames[o], float(lo), float(hi), band_modes[b],
                                 e / e_tot if e_tot > 0 else float("nan"),
                                 en / e_tot if e_tot > 0 else float("nan"), ef))
            if band_modes[b] is not None:
                excess_by_mode[(o, band_modes[b])] = ef

    # ---- modes -------------------------------------------------------------------------------
    modes: list[ModeGap] = []
    n_mode_tests = max(1, n_out * len(mf) * 3)
    for o in range(n_out):
        for k, fk in enumerate(mf):
            lo_s = edges[k] if k > 0 else 0.0
            hi_s = edges[k + 1]
            lo_s, hi_s = max(lo_s, 0.85 * fk), min(hi_s, 1.15 * fk)
            zk = max(float(md[k]), 1e-3) if md is not None else 0.02
            # input with the largest model response around the mode
            band_sel = (f >= lo_s) & (f <= hi_s)
            contrib = [float(np.max(np.abs(fr_h.H[band_sel & fr_h.excited[:, j], o, j]), initial=0.0))
                       * math.sqrt(float(np.var(u2[:, j]))) for j in range(n_in)]
            j = int(np.argmax(contrib))
            exc = fr_m.excited[:, j]
            hm = fr_m.H[:, o, j]
            hh = fr_h.H[:, o, j]
            mode_kw: dict[str, Any] = {"sensor": snames[o], "mode": mode_no[k], "input": inames[j],
                                       "model_freq_hz": float(fk),
                                       "model_damping": None if md is None else float(md[k])}
            nan = float("nan")
            empty: dict[str, Any] = {
                "observed": False, "fit_ok": False, "freq_method": "none", "model_fit_freq_hz": nan,
                "measured_freq_hz": nan, "freq_shift_rel": nan,
                "freq_shift_std": nan, "freq_shift_p": nan, "model_fit_damping": nan, "measured_damping": nan,
                "damping_ratio": nan, "damping_ratio_std": nan, "damping_p": nan, "damping_resolved": False,
                "amplitude_ratio": nan, "phase_diff_deg": nan, "band_gain": nan, "band_phase_deg": nan,
                "band_gain_p": nan, "coherence": nan,
                "band_excess_fraction": excess_by_mode.get((o, mode_no[k]), nan), "significant": ()}
            if contrib[j] <= 0 or np.count_nonzero(band_sel & exc) < 3:
                modes.append(ModeGap(excited=False, **{**mode_kw, **empty}))
                continue
            hw = min(max(4.0 * zk * fk, 6.0 * df), 0.15 * fk)
            ph = _peak_bin(f, np.where(exc, np.abs(hh), np.nan), lo_s, hi_s)
            pm = _peak_bin(f, np.where(exc, np.abs(hm), np.nan), lo_s, hi_s)
            res = dict(empty)
            # band complex gain over the model window (excited bins)
            fc = f[ph] if ph is not None else fk
            wsel = (f >= max(fc - hw, lo_s)) & (f <= min(fc + hw, hi_s)) & exc
            if np.count_nonzero(wsel) < 2:
                wsel = band_sel & exc
            a, b_ = hh[wsel], hm[wsel]
            den = float(np.sum(np.abs(a) ** 2))
            if den > 0:
                c = complex(np.sum(b_ * a.conj()) / den)
                e = b_ - c * a
                m_ = len(a)
                var_c = 2.0 * float(np.sum(np.abs(e) ** 2)) / max(m_ - 1, 1) / den
                zc = abs(c - 1.0) / math.sqrt(var_c) if var_c > 0 else (math.inf if c != 1 else 0.0)
                # |c - 1| is Rayleigh-distributed under H0 (complex Gaussian, variance var_c)
                res.update(band_gain=abs(c), band_phase_deg=math.degrees(np.angle(c)),
                           band_gain_p=float(math.exp(-zc ** 2)),
                           coherence=float(np.mean(fr_m.coherence[wsel, o])))
            # is the mode visible in the model FRF at this sensor (not at a node)?
            pad_exc = fp_h.excited[:, j]
            pk_h = _peak_location(fp_h.f, fp_h.H[:, o, j], fp_h.coherence[:, o], pad_exc, fp_h.n_segments, PAD,
                                  lo_s, hi_s)
            pk_m = _peak_location(fp_m.f, fp_m.H[:, o, j], fp_m.coherence[:, o], pad_exc, fp_m.n_segments, PAD,
                                  lo_s, hi_s)
            observed = pk_h is not None and abs(pk_h[0] - fk) <= max(2.0 * df, 0.02 * fk)
            res["observed"] = bool(observed)
            # local SDOF fits, each centred on its own peak
            fits: list[_Sdof | None] = []
            for pk, hx in ((ph, hh), (pm, hm)):
                if pk is None or not observed:
                    fits.append(None)
                    continue
                sel = (f >= max(f[pk] - hw, lo_s)) & (f <= min(f[pk] + hw, hi_s)) & exc
                full = (f >= max(f[pk] - hw, lo_s)) & (f <= min(f[pk] + hw, hi_s))
                if np.count_nonzero(sel) < max(6, 0.6 * np.count_nonzero(full)):
                    fits.append(None)  # too few excited lines for a peak fit (e.g. sparse multisine)
                    continue
                ft = _fit_sdof(f[sel], hx[sel], float(f[pk]), zk)
                fits.append(ft if ft is not None and ft.rel_resid < 0.3 else None)
            sh, sm = fits
            if sh is not None and sm is not None:
                shift = sm.fn / sh.fn - 1.0
                sshift = math.hypot(sm.fn_std, sh.fn_std) / sh.fn
                dr = sm.zeta / sh.zeta
                sl = math.hypot(sm.zeta_std / sm.zeta, sh.zeta_std / sh.zeta)
                hr = sm.h_at_fn / sh.h_at_fn if sh.h_at_fn != 0 else complex(nan)
                res.update(fit_ok=True, freq_method="sdof_fit", model_fit_freq_hz=sh.fn, measured_freq_hz=sm.fn,
                           freq_shift_rel=shift, freq_shift_std=sshift,
                           freq_shift_p=float(2 * stats.norm.sf(abs(shift) / sshift)) if sshift > 0 else 0.0,
                           model_fit_damping=sh.zeta, measured_damping=sm.zeta, damping_ratio=dr,
                           damping_ratio_std=dr * sl,
                           damping_p=float(2 * stats.norm.sf(abs(math.log(dr)) / sl)) if sl > 0 else 0.0,
                           damping_resolved=bool(2 * min(sh.zeta * sh.fn, sm.zeta * sm.fn) >= 3 * df),
                           amplitude_ratio=abs(hr), phase_diff_deg=math.degrees(np.angle(hr)))
            elif observed and pk_m is not None:
                # unresolved or poorly fitting peak: compare the peak locations of the two
                # identically smeared FRFs (the damping is not measurable).  Leakage of modes
                # that outlast a segment makes these locations scatter more than the H1 random
                # error says, so the error is also taken from the two halves of the record.
                shift = pk_m[0] / pk_h[0] - 1.0
                sshift = math.hypot(pk_m[1], pk_h[1]) / pk_h[0]
                sh_half = []
                for hm_, hh_ in halves:
                    a_ = _peak_location(hm_.f, hm_.H[:, o, j], hm_.coherence[:, o], hm_.excited[:, j],
                                        hm_.n_segments, PAD, lo_s, hi_s)
                    b_ = _peak_location(hh_.f, hh_.H[:, o, j], hh_.coherence[:, o], hh_.excited[:, j],
                                        hh_.n_segments, PAD, lo_s, hi_s)
                    sh_half.append(math.nan if a_ is None or b_ is None else a_[0] / b_[0] - 1.0)
                # var(full) ≈ var(half) / 2 ≈ (d_A - d_B)² / 4; a failed half counts as a 15 % scatter
                sshift = max(sshift, abs(sh_half[0] - sh_half[1]) / 2 if all(map(np.isfinite, sh_half)) else 0.15)
                hr = fp_m.H[pk_m[2], o, j] / fp_h.H[pk_h[2], o, j]
                res.update(freq_method="peak", model_fit_freq_hz=pk_h[0], measured_freq_hz=pk_m[0],
                           freq_shift_rel=shift, freq_shift_std=sshift,
                           freq_shift_p=float(2 * stats.norm.sf(abs(shift) / sshift)),
                           amplitude_ratio=float(abs(hr)), phase_diff_deg=math.degrees(np.angle(hr)))
            sig_list = []
            if res["freq_method"] != "none" and res["freq_shift_p"] * n_mode_tests < alpha \
                    and abs(res["freq_shift_rel"]) >= MIN_SHIFT:
                sig_list.append("frequency")
            if (res["fit_ok"] and res["damping_resolved"] and res["damping_p"] * n_mode_tests < alpha
                    and abs(math.log(res["damping_ratio"])) >= math.log(MIN_DAMPING_RATIO)):
                sig_list.append("damping")
            if np.isfinite(res["band_gain_p"]) and res["band_gain_p"] * n_mode_tests < alpha and (
                    abs(res["band_gain"] - 1) >= MIN_GAIN or abs(res["band_phase_deg"]) >= MIN_PHASE_DEG):
                sig_list.append("amplitude/phase")
            res["significant"] = tuple(sig_list)
            modes.append(ModeGap(excited=True, **{**mode_kw, **res}))

    # ---- time windows and amplitude levels ---------------------------------------------------
    yc2 = y2 - y2.mean(axis=0)
    yhc = yh2 - yh2.mean(axis=0)
    # linear prediction of y from u through the *measured* FRF: the best linear approximation.
    # The amplitude test compares y with it, so linear model errors (frequency-dependent gain
    # and phase, which would otherwise alias into envelope bins for multisines and sweeps) cancel.
    ylin = _linear_prediction(dt, u2, fp_m)
    ylq = _hilbert(ylin)
    env = np.hypot(ylin, ylq)
    idx_w = np.array_split(np.arange(n), windows)
    tc = np.array([(w[0] + w[-1]) / 2 * dt for w in idx_w])
    span = tc[-1] - tc[0]
    n_drift = 3 * n_out
    n_nl = 2 * n_out
    wins: list[WindowGap] = []
    amps: list[AmplitudeGap] = []
    for o in range(n_out):
        rms = np.array([math.sqrt(float(np.mean(r[w, o] ** 2))) for w in idx_w])
        # drift is judged against the time-invariant best linear approximation ylin, so a
        # non-stationary input (sweep) with a time-invariant model error cannot fake a trend
        lrms = np.array([math.sqrt(float(np.mean((yc2[w, o] - ylin[w, o]) ** 2))) for w in idx_w])
        cw = np.array([_local_gain(yc2[w, o], ylin[w, o], ylq[w, o]) for w in idx_w])
        gw = np.abs(cw)
        pw = np.degrees(np.unwrap(np.angle(cw)))
        # sampling variance of a window value from _SUB sub-windows of each window (pooled)
        vr, vg, vp = [], [], []
        for w, c in zip(idx_w, cw):
            subs = np.array_split(w, _SUB)
            cs = np.array([_local_gain(yc2[q, o], ylin[q, o], ylq[q, o]) for q in subs])
            rs = np.array([math.sqrt(float(np.mean((yc2[q, o] - ylin[q, o]) ** 2))) for q in subs])
            vr.append(np.var(rs, ddof=1) / _SUB)
            vg.append(np.var(np.abs(cs), ddof=1) / _SUB)
            vp.append(np.var(np.degrees(np.angle(cs / c)), ddof=1) / _SUB)
        dof_sub = windows * (_SUB - 1)
        s_r, p_r = _trend(tc, lrms, float(np.mean(vr)), dof_sub)
        s_g, p_g = _trend(tc, gw, float(np.mean(vg)), dof_sub)
        s_p, p_p = _trend(tc, pw, float(np.mean(vp)), dof_sub)
        rms_change = s_r * span / float(np.mean(lrms)) if np.mean(lrms) > 0 else 0.0
        drift = ((p_r * n_drift < alpha and abs(rms_change) >= MIN_RMS_CHANGE)
                 or (p_g * n_drift < alpha and abs(s_g * span) >= MIN_GAIN / 2)
                 or (p_p * n_drift < alpha and abs(s_p * span) >= MIN_PHASE_DEG / 2))
        wins.append(WindowGap(snames[o], tuple(map(float, tc)), tuple(map(float, rms)), tuple(map(float, lrms)),
                              tuple(map(float, gw)), tuple(map(float, pw)), float(rms_change), p_r,
                              float(s_g * span), p_g, float(s_p * span), p_p, bool(drift)))
        # within-window slopes of the local gain of y over the linear prediction vs ln(envelope)
        gs, ps = [], []
        for w in idx_w:
            lab = _quantile_bins(env[w, o], amplitude_bins)
            lv, gg, pp = [], [], []
            for b in range(amplitude_bins):
                s = w[lab == b]
                if len(s) < 8 or np.mean(env[s, o]) <= 0:
                    continue
                cb = _local_gain(yc2[s, o], ylin[s, o], ylq[s, o])
                lv.append(math.log(float(np.mean(env[s, o]))))
                gg.append(abs(cb))
                pp.append(np.angle(cb))
            if len(lv) >= 2 and np.ptp(lv) > 0:
                lv_a = np.array(lv)
                gs.append(float(np.polyfit(lv_a, gg, 1)[0]))
                ps.append(float(np.polyfit(lv_a, np.degrees(np.unwrap(pp)), 1)[0]))
        g_sl, g_p = _mean_t(gs)
        p_sl, p_p2 = _mean_t(ps)
        # record-wide bins for the table and plots
        lab = _quantile_bins(env[:, o], amplitude_bins)
        lvl, rr, rel, gb, pb = [], [], [], [], []
        for b in range(amplitude_bins):
            s = np.flatnonzero(lab == b)
            if len(s) < 8:
                continue
            cb = _local_gain(yc2[s, o], ylin[s, o], ylq[s, o])
            lvl.append(float(np.mean(env[s, o])))
            rr.append(math.sqrt(float(np.mean(r[s, o] ** 2))))
            rel.append(rr[-1] / max(math.sqrt(float(np.mean(yhc[s, o] ** 2))), 1e-300))
            gb.append(abs(cb))
            pb.append(math.degrees(np.angle(cb)))
        corr = np.array(rr) ** 2 - sig[o] ** 2
        okb = (corr > 0) & (np.array(lvl) > 0)
        expo = float(np.polyfit(np.log(np.array(lvl)[okb]), 0.5 * np.log(corr[okb]), 1)[0]) \
            if np.count_nonzero(okb) >= 2 else float("nan")
        log_range = math.log(lvl[-1] / lvl[0]) if len(lvl) >= 2 and lvl[0] > 0 else 0.0
        nonlin = bool((np.isfinite(g_p) and g_p * n_nl < alpha and abs(g_sl * log_range) >= MIN_GAIN / 2)
                      or (np.isfinite(p_p2) and p_p2 * n_nl < alpha and abs(p_sl * log_range) >= MIN_PHASE_DEG / 2))
        amps.append(AmplitudeGap(snames[o], tuple(lvl), tuple(rr), tuple(rel), tuple(gb), tuple(pb), expo,
                                 g_sl, g_p, p_sl, p_p2, nonlin))

    summary = _summary(sensors, modes, bands, wins, amps, xc_list, white_list)
    return Localisation(sensor_names=snames, input_names=inames, dt=dt, n_samples=n, nperseg=nperseg, df_hz=df,
                        max_lag=int(max_lag), alpha=float(alpha), gap_detected=any(s.gap_detected for s in sensors),
                        sensors=tuple(sensors), modes=tuple(modes), bands=tuple(bands), windows=tuple(wins),
                        amplitude=tuple(amps), whiteness=tuple(white_list), cross_correlation=tuple(xc_list),
                        summary=tuple(summary))


def _fmt_p(p: float) -> str:
    return f"{p:.0e}" if p < 1e-3 else f"{p:.2g}"


def _summary(sensors: Sequence[SensorGap], modes: Sequence[ModeGap], bands: Sequence[BandGap],
             wins: Sequence[WindowGap], amps: Sequence[AmplitudeGap], xcs: Sequence[CrossCorrelation],
             whites: Sequence[Whiteness]) -> list[str]:
    """Short human-readable statements, most important first; empty if no sensor has a gap."""
    out: list[str] = []
    for s in sorted(sensors, key=lambda s: -s.gap_ratio):
        if not s.gap_detected:
            continue
        name = s.sensor
        n_before = len(out)
        out.append(f"sensor {name}: residual variance is {s.gap_ratio:.3g}× the noise variance "
                   f"(NRMSE {s.nrmse:.3g}, {s.model_error_fraction:.0%} of the residual is model error)")
        if s.residual_mean ** 2 >= 0.25 * s.noise_std ** 2:
            out.append(f"sensor {name}: residual has a mean offset of {s.residual_mean:.3g} "
                       f"({abs(s.residual_mean) / s.noise_std:.2g}× the noise std): static/offset error")
        ms = [m for m in modes if m.sensor == name and m.significant]
        ms.sort(key=lambda m: -(m.band_excess_fraction if np.isfinite(m.band_excess_fraction) else 0.0))
        for m in ms[:3]:
            parts = []
            if "frequency" in m.significant:
                parts.append(f"measured {abs(m.freq_shift_rel):.2%} {'below' if m.freq_shift_rel < 0 else 'above'} "
                             f"model")
            if "damping" in m.significant:
                parts.append(f"damping {m.damping_ratio:.2g}× model ({m.measured_damping:.3g} vs "
                             f"{m.model_fit_damping:.3g})")
            share_ok = not np.isfinite(m.band_excess_fraction) or m.band_excess_fraction >= 0.05
            if ("amplitude/phase" in m.significant and not {"frequency", "damping"} & set(m.significant)
                    and share_ok):
                parts.append(f"amplitude ×{m.band_gain:.3g}, phase {m.band_phase_deg:+.1f}°")
            if not parts:
                continue
            share = (f"; {m.band_excess_fraction:.0%} of the model-error energy is in this band"
                     if np.isfinite(m.band_excess_fraction) else "")
            out.append(f"sensor {name}: mode {m.mode} ({m.model_freq_hz:.4g} Hz) " + ", ".join(parts) + share)
        if not ms:
            bs = [b for b in bands if b.sensor == name and np.isfinite(b.excess_fraction)]
            if bs:
                b = max(bs, key=lambda b: b.excess_fraction)
                if b.excess_fraction >= 0.5:
                    where = f"the band of mode {b.mode}" if b.mode is not None else "above the modes"
                    out.append(f"sensor {name}: {b.excess_fraction:.0%} of the model-error energy lies in "
                               f"{b.f_lo:.4g}–{b.f_hi:.4g} Hz ({where})")
        w = next(w for w in wins if w.sensor == name)
        if w.drift:
            if w.phase_p <= min(w.gain_p, w.rms_p):
                out.append(f"sensor {name}: measured phase relative to a time-invariant linear fit changes by "
                           f"{w.phase_change_deg:+.2f}° over the record (slope p={_fmt_p(w.phase_p)}): "
                           "drift (time-varying dynamics)")
            elif w.gain_p <= w.rms_p:
                out.append(f"sensor {name}: measured gain relative to a time-invariant linear fit changes by "
                           f"{w.gain_change:+.3g} over the record (slope p={_fmt_p(w.gain_p)}): drift")
            else:
                out.append(f"sensor {name}: residual of a time-invariant linear fit "
                           f"{'grows' if w.rms_change > 0 else 'shrinks'} over the record "
                           f"({w.rms_change:+.0%}, slope p={_fmt_p(w.rms_p)}): drift")
        a = next(a for a in amps if a.sensor == name)
        if a.nonlinear:
            if np.isfinite(a.gain_p) and (not np.isfinite(a.phase_p) or a.gain_p <= a.phase_p):
                out.append(f"sensor {name}: gain {'grows' if a.gain_slope > 0 else 'falls'} with "
                           f"amplitude ({a.gain_slope:+.3g} per e-fold, p={_fmt_p(a.gain_p)}): nonlinearity")
            else:
                out.append(f"sensor {name}: phase changes with amplitude ({a.phase_slope_deg:+.2f}° per e-fold, "
                           f"p={_fmt_p(a.phase_p)}): nonlinearity")
        for c in xcs:
            if c.sensor == name and c.significant:
                out.append(f"sensor {name}: residual correlated with input {c.input} (max |r| = {c.max_abs:.2g} "
                           f"at lag {c.max_lag}, 99 % band {c.band:.2g}): input-related model error")
        h = next(h for h in whites if h.sensor == name)
        if not h.white and len(out) == n_before + 1:
            out.append(f"sensor {name}: residual is coloured (Ljung–Box p={_fmt_p(h.ljung_box_p)}): "
                       "unmodelled dynamics rather than noise")
    return out
