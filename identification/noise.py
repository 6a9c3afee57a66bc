"""Model-free estimate of the measurement noise of each sensor (identification and diagnosis alike).

The level of white measurement noise is read off where the measured signal
itself has no power: above the excited band and below the anti-alias roll-off
near Nyquist.  There the one-sided Welch PSD of a sensor is the noise floor
``N0`` and a white noise of standard deviation ``σ`` has ``N0 = 2 σ² dt``, so
``σ = sqrt(N0 / (2 dt))`` — the std of a white noise with that floor over the
whole band ``0 … 1/(2 dt)``.

The floor is found robustly: the quiet frequency range is cut into blocks of
contiguous bins, the quietest block is located, and all blocks within four
standard errors of it are pooled.  Blocks that still carry signal (a
resonance's tail, a harmonic, a spectral line) are louder and drop out, so the
estimate does not need to know the model, the resonances or the excitation.

When there is no usable quiet range (record too short, or the excited band
reaches Nyquist) the estimate falls back to the median absolute deviation of
high-order differences ``Δᵏy`` (for white noise ``var Δᵏe = C(2k, k) σ²``),
the least contaminated order ``k = 1 … 6`` being kept; for signals that are not
oversampled this is an upper bound.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from scipy import signal

from ebb_model.arrays import as_matrix
from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, DataError

from .settings import identification_settings

__all__ = ["NoiseEstimate", "noise_estimate", "noise_std", "records_noise_std", "given_noise_std", "psd_floor",
           "welch_dof", "welch_nperseg"]

#: Fraction of Nyquist above which anti-alias / decimation filters may pull the
#: measured spectrum below the true noise floor: excluded from the quiet range.
_TOP = 0.8
#: Minimum number of quiet PSD bins for the spectral estimate.
_MIN_BINS = 16
#: MAD → std for a Gaussian.
_MAD_TO_STD = 1.482602218505602


@dataclass(frozen=True, eq=False)
class NoiseEstimate:
    """Per-sensor white-noise estimate.

    Attributes
    ----------
    std
        Estimated noise standard deviation per sensor, shape ``(n_out,)``.
    method
        Per sensor ``"psd_floor"`` (Welch floor in the quiet range) or
        ``"difference_mad"`` (fallback).
    f_range
        The quiet frequency range ``(lo, hi)`` [Hz] used by the PSD method, or
        ``None`` when the fallback was used.
    """

    std: np.ndarray
    method: tuple[str, ...]
    f_range: tuple[float, float] | None





def _difference_mad(y: np.ndarray) -> np.ndarray:
    """Noise std per column from the MAD of differences of order 1…6 (smallest kept)."""
    best = np.full(y.shape[1], np.inf)
    d = y
    for k in range(1, 7):
        d = np.diff(d, axis=0)
        if d.shape[0] < 8:
            break
        scale = math.sqrt(math.comb(2 * k, k))
        mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
        best = np.minimum(best, _MAD_TO_STD * mad / scale)
    return best


def welch_nperseg(n: int) -> int:
    """The Welch segment length of the noise estimates for ``n`` samples: ``clip(n // 8, 256, 4096)``, at most
    ``n``."""
    return int(min(max(n // 8, 256), 4096, n))


def welch_dof(n: int, nperseg: int) -> float:
    """Equivalent chi-square degrees of freedom of one bin of a Hann, 50 %-overlap Welch estimate (Welch 1967:
    ``2K/(1 + 2·0.167²)`` for ``K`` segments; 2 for a single one)."""
    k = 1 + (n - nperseg) // (nperseg // 2)
    return 2.0 * k / (1.0 + 2.0 * 0.167 ** 2) if k > 1 else 2.0


def psd_floor(p: np.ndarray, m: int, nu: float) -> tuple[float, float]:
    """Pooled floor of a PSD segment ``p`` (quiet bins only) in blocks of ``m`` bins, and the relative standard
    error of one block mean.

    ``nu`` is the equivalent chi-square degrees of freedom of one Welch bin.  Blocks within four standard errors
    of the quietest are pooled; louder ones carry signal and drop out.
    """
    nb = len(p) // m
    blocks = p[: nb * m].reshape(nb, m)
    means = blocks.mean(axis=1)
    j = int(np.argmin(means))
    # relative standard error of a block mean; Hann bins are correlated over ~2 neighbours
    rel_block = math.sqrt(2.0 / nu) / math.sqrt(max(m / 2.0, 1.0))
    keep = means <= means[j] * (1.0 + 4.0 * rel_block)
    return float(np.mean(means[keep])), rel_block


def noise_estimate(y: np.ndarray, dt: float, *, band: tuple[float, float] | None = None,
                   nperseg: int | None = None) -> NoiseEstimate:
    """Estimate the white measurement noise of each sensor without a model.

    Parameters
    ----------
    y
        Measured outputs, shape ``(n,)`` or ``(n, n_out)``.
    dt
        Sample time [s], ``> 0``.
    band
        Excited band ``(f_lo, f_hi)`` [Hz]: the quiet range starts above
        ``1.1 f_hi``.  ``None``: the whole spectrum above the lowest 2 % is
        searched for its quietest part.
    nperseg
        Welch segment length (default ``clip(n // 8, 256, 4096)``).

    Returns
    -------
    NoiseEstimate
    """
    finite_scalar("dt", dt, minimum=0.0, strict=True, numbers_only=True, error=ConfigError)
    a = as_matrix(y, "y", min_rows=1)
    n = a.shape[0]
    fs = 1.0 / dt
    fn = fs / 2.0
    if band is not None and (len(band) != 2 or not all(math.isfinite(float(b)) for b in band)
                             or not 0 <= band[0] <= band[1]):
        raise ConfigError(f"band: expected (f_lo, f_hi) with 0 <= f_lo <= f_hi, got {band!r}")
    nperseg = welch_nperseg(n) if nperseg is None else min(int(nperseg), n)
    df = fs / nperseg
    lo = max(3 * df, 0.02 * fn) if band is None else 1.1 * float(band[1]) + 2 * df
    hi = _TOP * fn
    f = np.fft.rfftfreq(nperseg, dt)
    sel = (f >= lo) & (f <= hi)
    if n >= 256 and np.count_nonzero(sel) >= _MIN_BINS:
        _, p = signal.welch(a, fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2,
                            detrend="constant", scaling="density", axis=0)
        q = p[sel]
        m = max(8, q.shape[0] // 32)
        if q.shape[0] // m < 2:
            m = q.shape[0] // 2
        nu = welch_dof(n, nperseg)
        n0 = np.array([psd_floor(q[:, i], m, nu)[0] for i in range(a.shape[1])])
        return NoiseEstimate(std=np.sqrt(n0 / (2.0 * dt)), method=("psd_floor",) * a.shape[1],
                             f_range=(float(f[sel][0]), float(f[sel][-1])))
    return NoiseEstimate(std=_difference_mad(a), method=("difference_mad",) * a.shape[1], f_range=None)


def noise_std(y: np.ndarray, dt: float, *, band: tuple[float, float] | None = None) -> np.ndarray:
    """Per-sensor measurement-noise std, shape ``(n_out,)``; see :func:`noise_estimate`."""
    return noise_estimate(y, dt, band=band).std


def records_noise_std(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], dt: float) -> np.ndarray:
    """Per-sensor noise std of several records: the floor above the band the inputs excite, median over records.

    The one estimate of the identification (Fisher information, Cramér–Rao bounds, the fit's gap ratio) and
    of the diagnosis (noise-normalised residuals).  A lightly damped accelerometer record has signal up to
    the top of the excited band and little above it: estimates from differences of the samples see the
    signal too (measured 50× the noise variance on a record excited to fs/13), the floor above the band
    does not.

    Raises
    ------
    DataError
        When the records give no positive, finite estimate (noise-free or constant records, or inputs
        without power).
    """
    from ebb_model.space.adequacy import excited_band

    f_top = excited_band(list(inputs), dt)[1]
    sigma = np.median(np.array([noise_std(y, dt, band=(0.0, f_top)) for y in outputs]), axis=0)
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise DataError("noise: could not estimate the measurement noise from the data (noise-free or "
                        "constant records?); give noise_std in [identification]")
    return sigma


def given_noise_std(config: BeamConfig, noise_std: Any = None) -> np.ndarray | None:
    """The noise standard deviation per sensor that the caller gives, else the config's ``[identification]
    noise_std``; ``None`` when neither gives one (then :func:`records_noise_std` estimates it from the data).

    Raises
    ------
    ConfigError
        Not one finite number > 0 per sensor (strings, booleans, NaN, a wrong count).
    """
    if noise_std is None:
        noise_std = identification_settings(config).noise_std
    if noise_std is None:
        return None
    n = len(config.sensors)
    try:
        values = list(np.ravel(np.asarray(noise_std, dtype=object)))
    except ValueError:           # a ragged nesting of lists
        values = []
    numbers = [v for v in values if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)]
    sigma = np.array(numbers, dtype=float)
    if len(numbers) != len(values) or sigma.shape != (n,) or not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise ConfigError(f"noise_std: need one positive number per sensor ({n}), got {noise_std!r}")
    return sigma

