r"""The modes of a record under a force nobody measured: ambient or operational excitation.

A structure driven by a broadband random force that is not recorded (wind, traffic, a machine nearby, a shaker
whose load cell is missing) shows its modes in the records' correlations — the natural excitation technique
(James, Carne and Lauffer, 1993).  Under a stationary force whose spectrum is smooth across each mode's
bandwidth, the correlation of sensor ``i`` with a reference sensor ``r``,

.. math::

    R_{ir}(τ) = E[\,y_i(t + τ)\, y_r(t)\,], \qquad τ ≥ 0,

obeys the structure's free vibration: it is a sum of the modes' damped oscillations, mode ``k``'s amplitude across
the sensors ``i`` proportional to its shape.  So every column ``R_{·r}`` is read as a free decay
(:func:`identification.output_modes.decay_fit`: the records' stabilised estimator for the start, then the poles
fitted in time, each column weighted by its own residual level), all references together — a mode at one
reference's node is seen from another — and each mode's shape ratios come from the reference that sees it best.

- The correlations are the unbiased estimates (``1/(n − τ)``) from :data:`SEGMENTS` equal segments of the
  record, averaged, over lags :data:`FIRST_LAG` … a :data:`LAG_SHARE` of a segment: lag 0 and the first few carry
  the sensors' own noise (white, or through the anti-alias filter a few samples wide) and the force's own memory.
- **Uncertainty by the delete-one-segment jackknife**: the poles are fitted again on the average of every
  segments' correlations but one, and the scatter of those fits gives the standard uncertainties of the
  frequencies, damping ratios and shape ratios.  A correlation estimate's errors are correlated across lags and
  across columns, so the least-squares covariance that serves a free decay would misstate them; the segments'
  scatter does not assume anything of that structure.  With :data:`SEGMENTS` segments the uncertainty is itself
  known to about a quarter.
- A line that does not decay in the correlations is a tone in the force or a machine's harmonic, not a mode: it
  is fitted with the modes and reported apart (:data:`~identification.output_modes.HARMONIC_DAMPING`; the ARTS
  bench's shaker record read as ambient holds its three tones and their harmonics, and no mode).
- The record must be stationary: a structure left ringing, a force switched on or a change during the record
  (a moving support) is cut into stationary parts first (:mod:`identification.segments`).  A record whose start
  finds no significant mode shows none.
"""
from __future__ import annotations

import math

import numpy as np

from ebb_model.errors import DataError

from .output_modes import OutputModes, decay_fit, fit_poles, shape_ratios

__all__ = ["SEGMENTS", "FIRST_LAG", "LAG_SHARE", "ambient_modes", "correlations"]

#: Segments the record is cut into: their correlations are averaged, and left out one at a time for the jackknife.
SEGMENTS = 8
#: The first lag read [samples]: lag 0 holds the sensors' own (white) noise, the next few the anti-alias filter's
#: width of it and the force's own memory.
FIRST_LAG = 8
#: The correlations' length, as a share of a segment (longer lags are estimated from fewer products).
LAG_SHARE = 0.25
#: The fewest samples per segment: the correlations' length must hold a few periods of the modes sought.
MIN_SEGMENT = 256


def correlations(y: np.ndarray, segments: int = SEGMENTS) -> np.ndarray:
    """Each segment's correlations ``(segments, lags, n_sensors · n_sensors)``: column ``r · n + i`` is
    ``R_{ir}(τ)`` for ``τ = FIRST_LAG … FIRST_LAG + lags − 1`` (unbiased; the segment's mean taken out)."""
    n, n_out = y.shape
    size = n // segments
    lags = int(LAG_SHARE * size)
    out = np.empty((segments, lags, n_out * n_out))
    nfft = 1 << int(math.ceil(math.log2(2 * size)))
    taus = np.arange(FIRST_LAG, FIRST_LAG + lags)
    for s in range(segments):
        part = y[s * size:(s + 1) * size]
        part = part - part.mean(axis=0)
        spec = np.fft.rfft(part, nfft, axis=0)
        for r in range(n_out):
            # R_ir(τ) = Σ_t y_i(t + τ) y_r(t) / (size − τ): the cross spectrum's inverse
            cross = np.fft.irfft(spec * np.conj(spec[:, r:r + 1]), nfft, axis=0)[taus]
            out[s, :, r * n_out:(r + 1) * n_out] = cross / (size - taus)[:, None]
    return out


def _as_ambient(outputs: np.ndarray, dt: float, segments: int) -> np.ndarray:
    """The outputs as ``(n, n_sensors)`` finite floats long enough for ``segments``, refused in one line."""
    y = np.asarray(outputs, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if not (math.isfinite(dt) and dt > 0):
        raise DataError(f"the sample interval must be a positive number, got {dt!r}")
    if y.ndim != 2 or y.shape[0] < segments * MIN_SEGMENT:
        raise DataError(f"an ambient record needs at least {segments * MIN_SEGMENT} samples of each sensor "
                        f"({segments} segments of {MIN_SEGMENT}), got shape {np.shape(outputs)}")
    if not np.all(np.isfinite(y)):
        raise DataError("the record holds NaN or infinite values")
    if np.any(np.ptp(y, axis=0) == 0):
        raise DataError("a sensor's record is constant: it shows no mode")
    return y


def _block_shapes(amp: np.ndarray, cov_amp: np.ndarray, m: int, n_out: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per mode, from the reference whose columns see it best: the shape ratios, their least-squares standard
    uncertainties, the sensor they are relative to, the mode's significance there, and that reference."""
    blocks = [shape_ratios(amp[:, r * n_out:(r + 1) * n_out], cov_amp[r * n_out:(r + 1) * n_out], m)
              for r in range(n_out)]
    best = np.argmax(np.stack([b[3] for b in blocks]), axis=0)            # (m,): the reference per mode
    pick = np.arange(m)
    shapes = np.stack([b[0] for b in blocks])[best, pick]
    std = np.stack([b[1] for b in blocks])[best, pick]
    ref = np.stack([b[2] for b in blocks])[best, pick]
    signif = np.stack([b[3] for b in blocks])[best, pick]
    return shapes, std, ref, signif, best


def ambient_modes(outputs: np.ndarray, dt: float, segments: int = SEGMENTS) -> OutputModes:
    """The modes of a stationary record under an unmeasured broadband force (module docstring).

    Parameters
    ----------
    outputs : array_like
        ``(n, n_sensors)`` (or ``(n,)``): the records, stationary throughout.
    dt : float
        Sample interval [s].
    segments : int
        Segments averaged and left out one at a time for the uncertainties (at least 4).

    Returns
    -------
    OutputModes
        The significant modes (:data:`~identification.output_modes.SIGNIFICANCE` in the averaged correlations),
        ascending, with their jackknife uncertainties (``inflation`` is 1: the scatter needs none); none when the
        correlations' start finds no stable pole.

    Raises
    ------
    DataError
        Too short for ``segments`` segments, a NaN or a constant sensor, a bad ``dt``.
    """
    if segments < 4:
        raise DataError(f"the jackknife needs at least 4 segments, got {segments}")
    y = _as_ambient(outputs, dt, segments)
    n_out = y.shape[1]
    parts = correlations(y, segments)
    full = parts.mean(axis=0)
    fit = decay_fit(full, dt)
    if fit is None:
        return OutputModes.none(n_out, np.std(y, axis=0), kind="ambient")
    m = fit.p.size // 2
    shapes, _, ref, signif, best = _block_shapes(fit.amp, fit.cov_amp, m, n_out)
    f0, z0 = fit.frequencies_hz, fit.damping
    est_p, est_shape = [], []
    for s in range(segments):                   # the jackknife: every segment left out once
        rest = (full * segments - parts[s]) / (segments - 1)
        p, _, amp, cov_amp, _, _ = fit_poles(rest, dt, f0, z0)
        order = np.argsort(p[0::2])
        est_p.append(np.column_stack([p[0::2][order], p[1::2][order]]))
        # each mode's ratios from the reference and to the sensor the full fit chose
        est_shape.append(np.stack([_ratios(amp[:, best[k] * n_out:(best[k] + 1) * n_out], order[k], ref[k])
                                   for k in range(m)]))
    jack = (segments - 1) / segments
    lp = np.stack(est_p)                        # (segments, m, 2): ln f, ln ζ
    sd = np.sqrt(jack * np.sum((lp - lp.mean(axis=0)) ** 2, axis=0))
    sh = np.stack(est_shape)
    shape_std = np.sqrt(jack * np.sum((sh - sh.mean(axis=0)) ** 2, axis=0))
    keep = ~fit.tones                           # lines that do not decay: tones in the force, not modes
    return OutputModes(f0[keep], (f0 * sd[:, 0])[keep], z0[keep], (z0 * sd[:, 1])[keep], shapes[keep],
                       shape_std[keep], ref[keep], signif[keep], np.std(y, axis=0), 1.0, "ambient", f0[fit.tones])


def _ratios(amp: np.ndarray, k: int, ref: int) -> np.ndarray:
    """Mode ``k``'s shape ratios to sensor ``ref`` from one reference's amplitudes ``amp`` (2m + 1, n_sensors):
    the real part of its complex amplitude ``a − i b`` over the one at ``ref`` (as
    :func:`~identification.output_modes.shape_ratios` forms them; a leave-one-out fit may see the mode best at
    another sensor, the ratios stay relative to the full fit's)."""
    c = amp[2 * k] - 1j * amp[2 * k + 1]
    return np.asarray((c / c[ref]).real, dtype=float)
