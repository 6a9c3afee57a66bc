"""Trends and residual tests of the localisation: time and amplitude trends, Hilbert envelopes, residual
whiteness and input cross-correlation."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import fft as sfft
from scipy import signal, stats


from .thresholds import Z99

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


