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

(This module is :func:`localise` alone; at ~440 lines that function is still the longest in the project — its
sections, one per table above, are the next split.)
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import stats

from ebb_model.errors import ConfigError, DataError

from identification.noise import noise_estimate

from .results import (AmplitudeGap, BandGap, CrossCorrelation, Localisation, ModeGap, SensorGap, Whiteness,
                      WindowGap)
from .spectra import (_check_dt, _fit_sdof, _linear_prediction, _matrix, _names, _peak_bin, _peak_location,
                      _Sdof, _welch_psd, choose_nperseg, estimate_frf)
from .summary import _summary
from .thresholds import (_SUB, MIN_DAMPING_RATIO, MIN_GAIN, MIN_PHASE_DEG, MIN_RMS_CHANGE, MIN_SHIFT, PAD,
                         Z99)
from .trends import _hilbert, _local_gain, _mean_t, _quantile_bins, _trend, residual_correlations

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


