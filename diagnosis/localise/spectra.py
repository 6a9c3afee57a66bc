"""Spectra of the localisation: input checks, H1 FRF estimates, local SDOF fits of resonances, the data's
best linear prediction."""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import fft as sfft
from scipy import optimize, signal

from ebb_model.errors import ConfigError, DataError
from ebb_model.arrays import as_matrix
from ebb_model.checks import finite_scalar

from .thresholds import EXCITE_REL

# ----------------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------------
def _matrix(a: Any, name: str) -> np.ndarray:
    """``(n_samples, n_channels)`` float array of ``a`` (:func:`ebb_model.arrays.as_matrix`)."""
    return as_matrix(a, name)


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
    return finite_scalar("dt", dt, minimum=0.0, strict=True, error=ConfigError)


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


def choose_nperseg(n: int, dt: float, mode_freqs_hz: Sequence[float] | np.ndarray,
                   mode_damping: Sequence[float] | np.ndarray | None = None) -> int:
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


