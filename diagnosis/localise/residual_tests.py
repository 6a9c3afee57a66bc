"""Residual tests of the localisation: whiteness, residual–input cross-correlation, the gap per sensor and the
model-error energy per frequency band (see :mod:`diagnosis.localise.core`)."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import fft as sfft
from scipy import stats

from .results import BandGap, CrossCorrelation, SensorGap, Whiteness
from .spectra import _welch_psd
from .thresholds import Z99

__all__ = ["residual_correlations", "correlation_tests", "sensor_gaps", "band_gaps"]


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


def correlation_tests(r: np.ndarray, u2: np.ndarray, max_lag: int, snames: Sequence[str], inames: Sequence[str]
                      ) -> tuple[list[Whiteness], list[CrossCorrelation]]:
    """Ljung–Box whiteness per sensor and the portmanteau residual–input cross-correlation test per pair."""
    n, n_out = r.shape
    n_in = u2.shape[1]
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
    return white_list, xc_list


def sensor_gaps(y2: np.ndarray, r: np.ndarray, sig: np.ndarray, nmeth: Sequence[str], snames: Sequence[str],
                xc_list: Sequence[CrossCorrelation], gap_ratio_limit: float) -> list[SensorGap]:
    """NRMSE, gap ratio against the noise and model-error share per sensor, and whether it has a gap."""
    n_out = y2.shape[1]
    mse = np.mean(r ** 2, axis=0)
    rmean = r.mean(axis=0)
    var_r = np.var(r, axis=0)
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
            gap_detected=bool(gap >= gap_ratio_limit or (xsig and gap >= 1.1)
                              or rmean[o] ** 2 >= (gap_ratio_limit - 1) * sig[o] ** 2)))
    return sensors


def band_gaps(r: np.ndarray, dt: float, nperseg: int, f: np.ndarray, mf: np.ndarray, mode_no: Sequence[int],
              sig: np.ndarray, snames: Sequence[str]
              ) -> tuple[list[BandGap], list[float], dict[tuple[int, int], float]]:
    """Residual and model-error energy per band between mode midpoints; the band edges and each (sensor, mode)'s
    share of the model-error energy."""
    n_out = r.shape[1]
    fnyq = 0.5 / dt
    df = float(f[1] - f[0])
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
            mode = band_modes[b]
            if mode is not None:
                excess_by_mode[(o, mode)] = ef
    return bands, edges, excess_by_mode
