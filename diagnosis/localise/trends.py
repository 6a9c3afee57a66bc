"""Trends of the localisation: drift over time windows and amplitude dependence over envelope levels, against
the best linear approximation (Hilbert envelopes, local complex gains, trend tests)."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import fft as sfft
from scipy import signal, stats

from .results import AmplitudeGap, WindowGap
from .spectra import FrfEstimate, _linear_prediction
from .thresholds import _SUB, MIN_GAIN, MIN_PHASE_DEG, MIN_RMS_CHANGE

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


def window_and_amplitude_gaps(dt: float, u2: np.ndarray, y2: np.ndarray, yh2: np.ndarray, fp_m: FrfEstimate,
                              sig: np.ndarray, snames: Sequence[str], windows: int, amplitude_bins: int,
                              alpha: float) -> tuple[list[WindowGap], list[AmplitudeGap]]:
    """Drift per time window and amplitude dependence per envelope level, both against the best linear
    approximation (see :mod:`diagnosis.localise.core`)."""
    n, n_out = y2.shape
    r = y2 - yh2
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
    return wins, amps
