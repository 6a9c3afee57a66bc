"""Time vectors of measured data: recognising uniform sampling and resampling to the model's dt.

Two pure functions over arrays:

* :func:`regularise_time` -- a text file prints its time column with a few
  decimals (``0.000312`` for 3.125e-4 s in the ARTS-Lab record), so its steps
  wobble by up to one printed quantum (0.16 % there) although the sampling is
  uniform.  If every sample lies within the printing accuracy of a uniform
  grid ``t0 + k dt`` -- tried first with the config's dt, then with the
  end-point estimate ``(t[-1] - t[0]) / (n - 1)`` -- the grid replaces the
  printed values; otherwise the record is irregular and the first
  offending sample is reported.

* :func:`resample_uniform` -- to the model's sample time.

  - **Rational ratio** ``f_new / f_old = up / down`` (both <= 1000, e.g.
    3200 Hz -> 10 kHz is 25/8): :func:`scipy.signal.resample_poly`, i.e.
    zero insertion, a linear-phase FIR low-pass and decimation, done
    polyphase.  The filter is our own Kaiser design (``kaiserord``: pass band
    to 80 % of the lower of the two Nyquist frequencies, stop band from 100 %,
    80 dB, i.e. ripple 1e-4) rather than resample_poly's default (Kaiser
    beta = 5, whose pass-band ripple is ~3e-3).  So content below 80 % of
    the lower Nyquist frequency is kept to ~1e-4 and nothing above the new
    Nyquist frequency aliases.  The ends are extended linearly
    (``padtype="line"``) so that offsets and trends do not ring.
  - **Otherwise**: anti-aliased interpolation -- the same polyphase filter
    first interpolates 16x (its pass band ending at 80 % of the lower of
    the two Nyquist frequencies, so it also removes what would alias at the
    new rate), then a cubic spline maps the dense grid to the new one.  On
    the dense grid the spline's error on a tone of frequency f is about
    ``(5/384) (2 pi f dt_old / 16)**4`` (de Boor, *A Practical Guide to
    Splines*, ch. V), < 1e-5 for f up to 0.4 f_old.

  FFT resampling (:func:`scipy.signal.resample`) is not used: it treats the
  record as periodic and rings at the ends of a non-periodic measurement.
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import firwin, kaiserord, resample_poly

from ebb_model.errors import DataError
from ebb_model.io.signals_io import check_time_vector

__all__ = ["regularise_time", "mean_step", "resample_uniform", "MAX_RATE_FACTOR"]

#: Largest up/down factor of the rational (polyphase) path.
MAX_RATE_FACTOR = 1000
#: Densification factor before the spline of the irrational path.
_DENSE = 16
#: Stop-band attenuation of the anti-aliasing / interpolation filters [dB] (1e-4).
_ATTENUATION_DB = 80.0


def mean_step(t: np.ndarray) -> float:
    """``(t[-1] - t[0]) / (n - 1)``, the sample time of a uniform record."""
    return float((t[-1] - t[0]) / (t.size - 1))


def regularise_time(t: np.ndarray, tolerance: float, dt_hint: float | None = None, *,
                    where: str = "time") -> np.ndarray:
    """Replace printed times by the uniform grid they round.

    Parameters
    ----------
    t
        Finite, strictly increasing times, shape (n,).
    tolerance
        Maximum error of each stored time (half a printed quantum); ``0``
        means "stored exactly": ``t`` is returned unchanged (the timebase
        check then applies its own 1e-6 relative tolerance).  Capped at a
        quarter of the step: no sample is ever moved by more.
    dt_hint
        A sample time to try first (the config's dt).
    where
        Prefix of error messages.

    Returns
    -------
    numpy.ndarray
        ``t0 + k * dt`` with ``|t_k - (t0 + k dt)| <= tolerance`` for all k
        (``2 * tolerance`` for the end-point estimate of dt, whose own error
        adds); else ``t`` itself if its steps agree with the mean step within
        1e-6 relative (the tolerance of
        :func:`ebb_model.io.signals_io.check_time_vector`).

    Raises
    ------
    DataError
        If neither holds: the times are irregular beyond their printed
        precision.  Names the first step that differs from the mean step by
        more than two quanta, or else the first sample off the grid.
    """
    n = t.size
    if tolerance <= 0 or n < 2:
        return t
    k = np.arange(n, dtype=float)
    slack = 16 * np.finfo(float).eps * float(np.max(np.abs(t)))
    candidates = [] if dt_hint is None else [(float(dt_hint), tolerance)]
    dt_mean = mean_step(t)
    candidates.append((dt_mean, 2 * tolerance))
    for dt, tol in candidates:
        tol = min(tol, 0.25 * dt)      # never move a sample by more than a quarter step
        r = t - k * dt
        for t0 in (float(t[0]), 0.5 * float(r.max() + r.min())):
            if float(np.max(np.abs(r - t0))) <= tol * (1 + 1e-6) + slack:
                return t0 + k * dt
    steps = np.diff(t)
    if np.all(np.abs(steps - dt_mean) <= 1e-6 * dt_mean):
        return t            # uniform within the timebase rule's own 1e-6 (e.g. times summed in floating point)
    bad = np.flatnonzero(np.abs(steps - dt_mean) > 2 * tolerance * (1 + 1e-6) + slack)
    if bad.size:
        i = int(bad[0]) + 1
        raise DataError(f"{where}: not uniformly sampled: step {steps[i - 1]:.9g} s at sample {i} "
                        f"(t = {t[i]:.9g} s) differs from the mean step {dt_mean:.9g} s by more than the "
                        f"printed precision (+-{2 * tolerance:.3g} s)")
    r = t - t[0] - k * dt_mean
    i = int(np.argmax(np.abs(r)))
    raise DataError(f"{where}: not uniformly sampled: sample {i} (t = {t[i]:.9g} s) is {r[i]:.3g} s off the "
                    f"uniform grid of step {dt_mean:.9g} s (printed precision +-{tolerance:.3g} s)")


def _rational(ratio: float) -> Fraction | None:
    frac = Fraction(ratio).limit_denominator(MAX_RATE_FACTOR)
    if frac.numerator <= MAX_RATE_FACTOR and abs(float(frac) - ratio) <= 1e-9 * ratio:
        return frac
    return None


def _kaiser_lowpass(fs: float, f_nyq_low: float) -> np.ndarray:
    """Kaiser FIR at rate ``fs``: pass band to 0.8, stop band (80 dB) from 1.0 of ``f_nyq_low``; unit DC gain."""
    numtaps, beta = kaiserord(_ATTENUATION_DB, 0.2 * f_nyq_low / (0.5 * fs))
    numtaps |= 1                                    # odd length: integer group delay, zero phase
    return firwin(numtaps, 0.9 * f_nyq_low, window=("kaiser", beta), fs=fs)


def resample_uniform(t: np.ndarray, x: np.ndarray, dt_new: float, *, where: str = "data"
                     ) -> tuple[np.ndarray, np.ndarray, str]:
    """Resample uniformly sampled signals to the sample time ``dt_new``.

    Parameters
    ----------
    t
        Uniform sample times, shape (n,), n >= 2.
    x
        Signals, shape (n, m).
    dt_new
        Target sample time [s].
    where
        Prefix of error messages.

    Returns
    -------
    t_new : numpy.ndarray
        ``t[0] + k * dt_new`` for all k with ``t_new <= t[-1]``.
    x_new : numpy.ndarray
        Shape (len(t_new), m).
    method : str
        ``"none"``, ``"polyphase up/down"`` or ``"polyphase 16/1 + spline"``.

    Raises
    ------
    DataError
        If ``t`` is not uniformly sampled (within 1e-6 of its mean step) or
        has fewer than 2 samples.
    """
    if t.size < 2:
        raise DataError(f"{where}: cannot resample fewer than 2 samples")
    dt_old = mean_step(t)
    try:
        check_time_vector(t, dt_old, where=where)
    except DataError as exc:
        raise DataError(f"cannot resample data that are not uniformly sampled: {exc}") from None
    k_max = int(np.floor((t[-1] - t[0]) / dt_new * (1 + 1e-12) + 1e-9))
    t_new = t[0] + dt_new * np.arange(k_max + 1)
    ratio = dt_old / dt_new                         # = f_new / f_old
    if abs(ratio - 1.0) <= 1e-9:
        return t[0] + dt_new * np.arange(t.size), x.copy(), "none"
    f_old, f_new = 1.0 / dt_old, 1.0 / dt_new
    frac = _rational(ratio)
    if frac is not None:
        up, down = frac.numerator, frac.denominator
        h = _kaiser_lowpass(f_old * up, 0.5 * min(f_old, f_new))
        y = resample_poly(x, up, down, axis=0, window=h, padtype="line")
        m = min(y.shape[0], t_new.size)
        return t_new[:m], y[:m], f"polyphase {up}/{down}"
    # irrational ratio: band-limited interpolation onto a 16x denser grid (anti-aliased for the new rate
    # too), then a cubic spline from the dense grid to the new one
    h = _kaiser_lowpass(f_old * _DENSE, 0.5 * min(f_old, f_new))
    dense = resample_poly(x, _DENSE, 1, axis=0, window=h, padtype="line")
    t_dense = t[0] + (dt_old / _DENSE) * np.arange(dense.shape[0])
    return t_new, CubicSpline(t_dense, dense, axis=0)(t_new), f"polyphase {_DENSE}/1 + spline"
