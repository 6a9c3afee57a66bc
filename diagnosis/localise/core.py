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
  Hilbert transform: amplitude ratio and phase) per window; linear trends of their
  differences from the record's *linear twins* (the model's output plus noise of the
  measured level, analysed the same way: what the approximation itself makes of a
  linear record under this input is no drift), tested against the twins' spread plus
  the differences' own scatter (:mod:`.trends`; false alarms on linear records at
  most the level, tests/test_localise_calibration.py).  A slowly drifting resonance shows as a phase trend even when the
  residual RMS is V-shaped (a model fitted to the whole record matches its
  middle); because ``y_lin`` already carries every time-invariant linear error,
  a sweep input with a wrong model cannot fake a trend;
* **per amplitude level** — within every time window the samples are binned by
  quantiles of the response envelope ``|y_lin + i H y_lin|`` and the local complex
  gain of ``y`` over ``y_lin`` is computed per bin; the slope of gain (and phase)
  against ``ln(level)`` beyond the linear twins' is averaged over windows and tested
  like the trends.  A
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

The sections are modules: the spectra (:mod:`.spectra`), the residual tests per sensor, band and lag
(:mod:`.residual_tests`), the modes (:mod:`.modes`), the trends over time and amplitude (:mod:`.trends`), the
result types (:mod:`.results`) and the summary (:mod:`.summary`); this module checks the input and runs them.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ebb_model.errors import ConfigError, DataError

from identification.noise import noise_estimate

from .modes import FrfSet, mode_gaps
from .residual_tests import band_gaps, correlation_tests, sensor_gaps
from .results import Localisation
from .spectra import _check_dt, _matrix, _names, _welch_psd, choose_nperseg, estimate_frf
from .summary import _summary
from .thresholds import NOISE_BAND_BEYOND_MODE, NOISE_BAND_REL, PAD
from .trends import window_and_amplitude_gaps

# ----------------------------------------------------------------------------------------------
# main entry point
# ----------------------------------------------------------------------------------------------
def localise(dt: float, u: np.ndarray, y: np.ndarray, y_hat: np.ndarray, sensor_names: Sequence[str],
             mode_freqs_hz: ArrayLike, mode_damping: ArrayLike | None = None, *,
             noise_std: ArrayLike | None = None, windows: int = 8, amplitude_bins: int = 4,
             input_names: Sequence[str] | None = None, max_lag: int = 25, alpha: float = 1e-3,
             gap_ratio_limit: float = 1.5, nperseg: int | None = None) -> Localisation:
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
    gap_ratio_limit
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
    u2, y2, yh2, snames, inames, mf, md, mode_no = _checked(dt, u, y, y_hat, sensor_names, input_names,
                                                            mode_freqs_hz, mode_damping, windows, amplitude_bins,
                                                            max_lag, alpha, gap_ratio_limit, nperseg)
    n = y2.shape[0]

    # ---- spectra -----------------------------------------------------------------------------
    if nperseg is None:
        nperseg = choose_nperseg(n, dt, mf, md)
    nperseg = int(nperseg)
    frfs = _frfs(dt, u2, y2, yh2, nperseg)
    f = frfs.fr_m.f
    sig, nmeth = _noise(noise_std, u2, y2, dt, nperseg, f, mf)
    r = y2 - yh2
    white_list, xc_list = correlation_tests(r, u2, max_lag, snames, inames)
    sensors = sensor_gaps(y2, r, sig, nmeth, snames, xc_list, gap_ratio_limit)
    bands, edges, excess_by_mode = band_gaps(r, dt, nperseg, f, mf, mode_no, sig, snames)
    modes = mode_gaps(frfs, u2, mf, md, mode_no, edges, excess_by_mode, snames, inames, alpha)
    wins, amps = window_and_amplitude_gaps(dt, u2, y2, yh2, frfs.fp_m, sig, snames, windows, amplitude_bins, alpha)
    summary = _summary(sensors, modes, bands, wins, amps, xc_list, white_list)
    return Localisation(sensor_names=snames, input_names=inames, dt=dt, n_samples=n, nperseg=nperseg,
                        df_hz=float(f[1] - f[0]), max_lag=int(max_lag), alpha=float(alpha),
                        gap_detected=any(s.gap_detected for s in sensors), sensors=tuple(sensors), modes=tuple(modes),
                        bands=tuple(bands), windows=tuple(wins), amplitude=tuple(amps), whiteness=tuple(white_list),
                        cross_correlation=tuple(xc_list), summary=tuple(summary))


def _checked(dt: float, u: np.ndarray, y: np.ndarray, y_hat: np.ndarray, sensor_names: Sequence[str],
             input_names: Sequence[str] | None, mode_freqs_hz: ArrayLike, mode_damping: ArrayLike | None,
             windows: int, amplitude_bins: int, max_lag: int, alpha: float, gap_ratio_limit: float,
             nperseg: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...], tuple[str, ...],
                                           np.ndarray, np.ndarray | None, list[int]]:
    """:func:`localise`'s arguments checked (every problem of the settings reported at once): the signals as
    2-D arrays, the names, and the modes in increasing frequency with their damping and 1-based numbers in
    the caller's list.

    Raises
    ------
    ConfigError, DataError
        As :func:`localise`.
    """
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
    if not (isinstance(gap_ratio_limit, (int, float)) and math.isfinite(gap_ratio_limit) and gap_ratio_limit > 1):
        problems.append(f"gap_ratio_limit: must be a number > 1, got {gap_ratio_limit!r}")
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
    return u2, y2, yh2, snames, inames, mf, md, mode_no


def _frfs(dt: float, u2: np.ndarray, y2: np.ndarray, yh2: np.ndarray, nperseg: int) -> FrfSet:
    """Measured and model FRFs: plain, zero-padded, and padded per half of the record (for an empirical error
    of peak locations)."""
    n = y2.shape[0]
    half = n // 2
    return FrfSet(estimate_frf(dt, u2, y2, nperseg=nperseg), estimate_frf(dt, u2, yh2, nperseg=nperseg),
                  estimate_frf(dt, u2, y2, nperseg=nperseg, pad=PAD),
                  estimate_frf(dt, u2, yh2, nperseg=nperseg, pad=PAD),
                  tuple((estimate_frf(dt, u2[sl], y2[sl], nperseg=min(nperseg, half), pad=PAD),
                         estimate_frf(dt, u2[sl], yh2[sl], nperseg=min(nperseg, half), pad=PAD))
                        for sl in (slice(0, half), slice(half, n))))


def _noise(noise_std: ArrayLike | None, u2: np.ndarray, y2: np.ndarray, dt: float, nperseg: int,
           f: np.ndarray, mf: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
    """Noise standard deviation per sensor and how it was obtained (given, or the model-free estimate over the
    excited band)."""
    n_out = y2.shape[1]
    sig: np.ndarray | None
    if noise_std is None:
        pu = np.real(_welch_psd(u2, dt, nperseg)[1])
        exc_any = np.any(pu >= NOISE_BAND_REL * pu.max(axis=0, keepdims=True), axis=1)
        f_hi = float(f[np.flatnonzero(exc_any)[-1]]) if exc_any.any() else 0.0
        if len(mf):
            f_hi = max(f_hi, NOISE_BAND_BEYOND_MODE * float(mf[-1]))
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
    return np.maximum(sig, 1e-300), tuple(nmeth)
