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

from typing import Any

import numpy as np

from ebb_model.errors import DataError

__all__ = ["band_limit", "check_band", "condition"]


def check_band(band: Any, dt: float, *, where: str) -> tuple[float, float]:
    """Validate ``band = [f_lo, f_hi]`` in Hz against the Nyquist frequency ``0.5/dt``."""
    try:
        lo, hi = (float(v) for v in band)  # any value: what is not two numbers raises TypeError or ValueError
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


def condition(x: np.ndarray, t: np.ndarray, *, mode: str | bool, pre_trigger: float | None, band: Any,
               dt: float, src: str) -> np.ndarray:
    """Remove the static offset (``mode``) and limit the band of the signals ``x``, as
    :func:`identification.data.loaders.load_experiment` says.

    Parameters
    ----------
    x, t
        Signals ``(n_samples, n_signals)`` and their times (on the uniform grid).
    mode, pre_trigger, band
        The checked ``remove_offset``, ``pre_trigger`` and the ``band``.
    dt, src
        The config's sample interval (the filter's for a one-sample record); the file, for messages.

    Returns
    -------
    numpy.ndarray
        The conditioned signals.

    Raises
    ------
    DataError
        No sample in the pre-trigger window; an invalid band.
    """
    if mode == "mean":
        x = x - x.mean(axis=0)
    elif mode == "pre-trigger":
        assert pre_trigger is not None
        quiet = t < t[0] + pre_trigger
        if not quiet.any():
            raise DataError(f"{src}: no sample in the pre-trigger window of {pre_trigger:g} s")
        x = x - x[quiet].mean(axis=0)
    if band is not None:
        dt_file = float(t[1] - t[0]) if t.size > 1 else dt
        f_lo, f_hi = check_band(band, dt_file, where=f"{src}: band")
        x = band_limit(x, dt_file, f_lo, f_hi)
    return x
