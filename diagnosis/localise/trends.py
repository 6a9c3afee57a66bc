"""Trends of the localisation: drift over time windows and amplitude dependence over envelope levels, against
the best linear approximation (Hilbert envelopes, local complex gains, trend tests)."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import fft as sfft
from scipy import signal, stats

from .results import AmplitudeGap, WindowGap
from .spectra import FrfEstimate, _linear_prediction, estimate_frf
from .thresholds import MIN_GAIN, MIN_PHASE_DEG, MIN_RMS_CHANGE, PAD

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


#: Seed of the linear twins' noise (:func:`window_and_amplitude_gaps`): the same record gives the same tests.
TWIN_SEED = 20261127
#: Linear twins per record: the estimator's bias and its spread under noise (:func:`_twins`).
TWINS = 16


def _window_values(yc: np.ndarray, ylin: np.ndarray, ylq: np.ndarray, env: np.ndarray, idx_w: list[np.ndarray],
                   amplitude_bins: int) -> np.ndarray:
    """Per time window (columns) of one sensor's record ``yc`` (centred) against its best linear approximation
    ``ylin`` (its Hilbert transform ``ylq``, envelope ``env``), five rows: the RMS of ``yc − ylin``, the local gain
    and phase [deg] of ``yc`` over ``ylin``, and the within-window slopes of that gain and phase against
    ln(envelope) (NaN where a window has too few levels)."""
    out = np.full((5, len(idx_w)), np.nan)
    out[0] = [math.sqrt(float(np.mean((yc[w] - ylin[w]) ** 2))) for w in idx_w]
    cw = np.array([_local_gain(yc[w], ylin[w], ylq[w]) for w in idx_w])
    out[1], out[2] = np.abs(cw), np.degrees(np.unwrap(np.angle(cw)))
    for k, w in enumerate(idx_w):
        lab = _quantile_bins(env[w], amplitude_bins)
        lv, gg, pp = [], [], []
        for b in range(amplitude_bins):
            q = w[lab == b]
            if len(q) < 8 or np.mean(env[q]) <= 0:
                continue
            cb = _local_gain(yc[q], ylin[q], ylq[q])
            lv.append(math.log(float(np.mean(env[q]))))
            gg.append(abs(cb))
            pp.append(np.angle(cb))
        if len(lv) >= 2 and np.ptp(lv) > 0:
            out[3, k] = float(np.polyfit(lv, gg, 1)[0])
            out[4, k] = float(np.polyfit(lv, np.degrees(np.unwrap(pp)), 1)[0])
    return out


def _twins(dt: float, u2: np.ndarray, yh2: np.ndarray, sig: np.ndarray, nperseg: int
           ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The record's linear twins — the model's output plus white noise of the measured level, :data:`TWINS`
    realisations — each centred, with its best linear approximation estimated as the record's, that
    approximation's Hilbert transform and envelope."""
    rng = np.random.default_rng(TWIN_SEED)
    out = []
    for _ in range(TWINS):
        ys = yh2 + rng.standard_normal(yh2.shape) * np.asarray(sig, dtype=float)[None, :]
        ylin = _linear_prediction(dt, u2, estimate_frf(dt, u2, ys, nperseg=nperseg, pad=PAD))
        ylq = _hilbert(ylin)
        out.append((ys - ys.mean(axis=0), ylin, ylq, np.hypot(ylin, ylq)))
    return out


def _beyond_twins(tc: np.ndarray, values: np.ndarray, twins: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The record's five statistics beyond its twins (:func:`_window_values` rows: changes over the record of the
    relative RMS, gain and phase — OLS slope × span —, and the mean gain and phase slopes against ln(level)) and
    their two-sided p-values.

    A statistic is taken on the per-window differences ``d`` between the record and the twins' mean (the
    estimator's bias for a linear record under this input removed); its variance is the twins' spread of the same
    statistic (the noise's share, including the part every window shares through the approximation's own noise
    error) plus the sampling variance the differences' scatter across windows shows (what the twins do not
    share with the record: a linear model error changes the estimator's bias window by window)."""
    span = tc[-1] - tc[0]
    n = values.shape[1]
    rel = np.vstack([values[0] / np.nanmean(values[0])] + [t[0] / np.nanmean(t[0]) for t in twins])
    stack = np.concatenate([rel[:, None, :], np.stack([values[1:3]] + [t[1:3] for t in twins])], axis=1)
    d = stack[0] - stack[1:].mean(axis=0)                    # (3, n): rel. RMS, gain, phase differences
    tcc = tc - tc.mean()
    sxx = float(tcc @ tcc)
    excess, p = np.full(5, np.nan), np.full(5, np.nan)
    for i in range(3):
        slope = float(tcc @ (d[i] - d[i].mean()) / sxx)
        res = d[i] - d[i].mean() - slope * tcc
        var = float(res @ res) / (n - 2) / sxx + float(np.var([tcc @ t[i] / sxx for t in stack[1:]], ddof=1))
        excess[i], p[i] = slope * span, _p(slope, var, n - 2)
    for i, row in ((3, 3), (4, 4)):
        dd = values[row] - np.nanmean(np.stack([t[row] for t in twins]), axis=0)
        dd = dd[np.isfinite(dd)]
        if dd.size < 3:
            continue
        means = [float(np.nanmean(t[row])) for t in twins]
        var = float(np.var(dd, ddof=1)) / dd.size + float(np.var(means, ddof=1))
        excess[i], p[i] = float(dd.mean()), _p(float(dd.mean()), var, dd.size - 1)
    return excess, p


def _bin_values(yc: np.ndarray, ylin: np.ndarray, ylq: np.ndarray, env: np.ndarray, r: np.ndarray | None,
                yhc: np.ndarray | None, bins: int) -> tuple[list[float], list[float], list[float], list[float],
                                                            list[float]]:
    """One sensor's record-wide envelope bins (quantiles of ``env``; a bin of fewer than 8 samples left out): the
    mean level, the model residual's RMS and its share of the centred model output's (``r``, ``yhc``; NaN when
    not given), and the gain and phase [deg] of ``yc`` over its best linear approximation ``ylin``."""
    lab = _quantile_bins(env, bins)
    lvl, rr, rel, gb, pb = [], [], [], [], []
    for b in range(bins):
        s = np.flatnonzero(lab == b)
        if len(s) < 8:
            continue
        cb = _local_gain(yc[s], ylin[s], ylq[s])
        lvl.append(float(np.mean(env[s])))
        rr.append(math.sqrt(float(np.mean(r[s] ** 2))) if r is not None else math.nan)
        rel.append(rr[-1] / max(math.sqrt(float(np.mean(yhc[s] ** 2))), 1e-300) if yhc is not None else math.nan)
        gb.append(abs(cb))
        pb.append(math.degrees(np.angle(cb)))
    return lvl, rr, rel, gb, pb


def _mean_sd(stack: np.ndarray) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The mean and standard deviation over the twins (rows) of each column."""
    return tuple(map(float, np.mean(stack, axis=0))), tuple(map(float, np.std(stack, axis=0, ddof=1)))


def _p(value: float, var: float, dof: int) -> float:
    """Two-sided t-test p-value of ``value`` against zero with variance ``var``."""
    if var <= 0:
        return 0.0 if value != 0 else 1.0
    return float(2 * stats.t.sf(abs(value) / math.sqrt(var), dof))


def window_and_amplitude_gaps(dt: float, u2: np.ndarray, y2: np.ndarray, yh2: np.ndarray, fp_m: FrfEstimate,
                              sig: np.ndarray, snames: Sequence[str], windows: int, amplitude_bins: int,
                              alpha: float) -> tuple[list[WindowGap], list[AmplitudeGap]]:
    """Drift per time window and amplitude dependence per envelope level, both against the best linear
    approximation (see :mod:`diagnosis.localise.core`), judged beyond the record's linear twins
    (:func:`_twins`, :func:`_beyond_twins`): records linear and time-invariant by construction, driven by the same
    input, whose best linear approximation is estimated the same way.  The approximation of a short or lightly
    damped record is coarse (a Welch estimate cannot resolve a resonance narrower than its bins), and what it then
    makes of a linear record — the gain over it changing by half from window to window, its errors weighing more
    where the envelope is low — is no drift and no nonlinearity.  Measured on 60 linear records of 2 s (two
    sensors each, three kinds, three supports, random and multisine inputs) with t-tests across windows instead: a
    gain-against-amplitude p below 0.05 in 45 % of them, below 0.01 in 13 %; tests/test_localise_calibration.py
    measures the rates now.
    """
    n, n_out = y2.shape
    r = y2 - yh2
    yc2 = y2 - y2.mean(axis=0)
    yhc = yh2 - yh2.mean(axis=0)
    # linear prediction of y from u through the *measured* FRF: the best linear approximation.
    ylin = _linear_prediction(dt, u2, fp_m)
    ylq = _hilbert(ylin)
    env = np.hypot(ylin, ylq)
    twins = _twins(dt, u2, yh2, sig, fp_m.nperseg)
    idx_w = np.array_split(np.arange(n), windows)
    tc = np.array([(w[0] + w[-1]) / 2 * dt for w in idx_w])
    n_drift = 3 * n_out
    n_nl = 2 * n_out
    wins: list[WindowGap] = []
    amps: list[AmplitudeGap] = []
    for o in range(n_out):
        rms = np.array([math.sqrt(float(np.mean(r[w, o] ** 2))) for w in idx_w])
        values = _window_values(yc2[:, o], ylin[:, o], ylq[:, o], env[:, o], idx_w, amplitude_bins)
        null = [_window_values(yc_t[:, o], lin_t[:, o], lq_t[:, o], env_t[:, o], idx_w, amplitude_bins)
                for yc_t, lin_t, lq_t, env_t in twins]
        (rms_change, d_g, d_p, g_sl, p_sl), (p_r, p_g, p_p, g_p, p_p2) = _beyond_twins(tc, values, null)
        lrms, gw, pw = values[0], values[1], values[2]
        drift = ((p_r * n_drift < alpha and abs(rms_change) >= MIN_RMS_CHANGE)
                 or (p_g * n_drift < alpha and abs(d_g) >= MIN_GAIN / 2)
                 or (p_p * n_drift < alpha and abs(d_p) >= MIN_PHASE_DEG / 2))
        twin_g, twin_gsd = _mean_sd(np.stack([t[1] for t in null]))
        twin_p, twin_psd = _mean_sd(np.stack([t[2] for t in null]))
        wins.append(WindowGap(snames[o], tuple(map(float, tc)), tuple(map(float, rms)), tuple(map(float, lrms)),
                              tuple(map(float, gw)), tuple(map(float, pw)), float(rms_change), float(p_r),
                              float(d_g), float(p_g), float(d_p), float(p_p), bool(drift), twin_g, twin_gsd,
                              twin_p, twin_psd))
        g_sl, g_p, p_sl, p_p2 = float(g_sl), float(g_p), float(p_sl), float(p_p2)
        # record-wide bins for the table and plots
        lvl, rr, rel, gb, pb = _bin_values(yc2[:, o], ylin[:, o], ylq[:, o], env[:, o], r[:, o], yhc[:, o],
                                           amplitude_bins)
        twin_bins = [_bin_values(yc_t[:, o], lin_t[:, o], lq_t[:, o], env_t[:, o], None, None, amplitude_bins)[3]
                     for yc_t, lin_t, lq_t, env_t in twins]
        tg = (np.array(twin_bins) if all(len(g) == len(gb) for g in twin_bins)
              else np.full((len(twins), len(gb)), np.nan))     # a twin whose bins came out otherwise: no band
        corr = np.array(rr) ** 2 - sig[o] ** 2
        okb = (corr > 0) & (np.array(lvl) > 0)
        expo = float(np.polyfit(np.log(np.array(lvl)[okb]), 0.5 * np.log(corr[okb]), 1)[0]) \
            if np.count_nonzero(okb) >= 2 else float("nan")
        log_range = math.log(lvl[-1] / lvl[0]) if len(lvl) >= 2 and lvl[0] > 0 else 0.0
        nonlin = bool((np.isfinite(g_p) and g_p * n_nl < alpha and abs(g_sl * log_range) >= MIN_GAIN / 2)
                      or (np.isfinite(p_p2) and p_p2 * n_nl < alpha and abs(p_sl * log_range) >= MIN_PHASE_DEG / 2))
        amps.append(AmplitudeGap(snames[o], tuple(lvl), tuple(rr), tuple(rel), tuple(gb), tuple(pb), expo,
                                 g_sl, g_p, p_sl, p_p2, nonlin, *_mean_sd(tg)))
    return wins, amps
