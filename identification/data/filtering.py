"""Zero-phase band limitation of records (the same linear filter on inputs and outputs).

A record whose excitation covers only a band (three tones, a band-limited
multisine) still carries broadband measurement noise in its *input*
channel.  The model, driven by the measured input, answers that noise at
every resonance, including those the excitation never reached, while the
real structure (driven by the true force) does not — an errors-in-variables
gap that no beam effect can explain.  Filtering input and output with the
same linear time-invariant filter keeps the input–output relation of a
linear model (the filter commutes with it) and removes the out-of-band part
of the problem.

The filter is an FFT mask: 1 inside ``[f_lo, f_hi]``, 0 outside, with
raised-cosine edges of ``edge`` Hz on each side (inside the band), applied
to the whole record after removing its mean (zero phase, no delay).
"""
from __future__ import annotations

import numpy as np

from ebb_model.errors import DataError

__all__ = ["band_limit", "check_band"]


def check_band(band: object, dt: float, *, where: str) -> tuple[float, float]:
    """Validate ``band = [f_lo, f_hi]`` in Hz against the Nyquist frequency ``0.5/dt``."""
    try:
        lo, hi = (float(v) for v in band)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise DataError(f"{where}: band must be two numbers [f_lo, f_hi] in Hz, got {band!r}") from None
    nyq = 0.5 / dt
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi <= nyq):
        raise DataError(f"{where}: band [{lo:g}, {hi:g}] Hz must satisfy 0 <= f_lo < f_hi <= {nyq:g} "
                        f"(the Nyquist frequency)")
    return lo, hi


def band_limit(x: np.ndarray, dt: float, f_lo: float, f_hi: float, *, edge: float | None = None
               ) -> np.ndarray:
    """Zero-phase band limitation of the columns of ``x`` to ``[f_lo, f_hi]`` Hz.

    Parameters
    ----------
    x
        Signals, one column each (n, k) or a vector.
    dt
        Sample time [s].
    f_lo, f_hi
        Pass band [Hz]; ``f_lo = 0`` keeps the low end (low-pass).
    edge
        Width [Hz] of the raised-cosine transition at each band edge, inside
        the band; default 10 % of the band width.

    Returns
    -------
    numpy.ndarray
        Filtered signals, same shape; the mean is removed unless ``f_lo = 0``.
    """
    a = np.asarray(x, dtype=float)
    vec = a.ndim == 1
    a = a.reshape(len(a), -1)
    n = a.shape[0]
    f = np.fft.rfftfreq(n, dt)
    w = 0.1 * (f_hi - f_lo) if edge is None else float(edge)
    mask = ((f >= f_lo) & (f <= f_hi)).astype(float)
    if w > 0:
        if f_lo > 0:
            rise = (f >= f_lo) & (f < f_lo + w)
            mask[rise] = 0.5 - 0.5 * np.cos(np.pi * (f[rise] - f_lo) / w)
        if f_hi < 0.5 / dt:
            fall = (f > f_hi - w) & (f <= f_hi)
            mask[fall] = 0.5 - 0.5 * np.cos(np.pi * (f_hi - f[fall]) / w)
    mean = a.mean(axis=0) if f_lo > 0 else 0.0
    out = np.fft.irfft(np.fft.rfft(a - mean, axis=0) * mask[:, None], n=n, axis=0)
    return out.ravel() if vec else out
