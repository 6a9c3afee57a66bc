"""A noise model per record and per sensor: level and spectrum, estimated from data, used to whiten residuals.

Why
---
A white level per sensor, read from the spectrum above the excited band, is the right yardstick only when the
noise is white and the same in every record.  Labs have coloured noise (1/f of amplifiers and cables, a
transducer's own resonance) and records of unequal quality; then the in-band noise is not the floor above the
band, and a model at the noise floor looks like a model error (the held-out residual "12× the noise variance").

The model
---------
For record ``i`` and sensor ``s`` the noise is an autoregressive process

.. math::

    A_{is}(q)\\, e_{is}(t) = \\sigma_{is}\\, w(t), \\qquad A(q) = 1 + a_1 q^{-1} + \\dots + a_p q^{-p},

with ``w`` white and of unit variance; ``p = 0`` is white noise of standard deviation ``σ``.  Its one-sided
PSD is ``2 dt σ² / |A(e^{iωdt})|²``.  Residuals are whitened by ``A(q) r / σ`` (:meth:`NoiseModel.whiten`) —
the output-error criterion with a noise model of prediction-error identification (Ljung, *System
Identification*, 2nd ed., §7.3): a model at the truth leaves whitened residuals of unit variance whatever the
noise's colour, so the gap ratio 1 is the noise floor on every record.

Estimation
----------
From the residual ``r`` of the best fit of the record (:func:`estimate_noise_model`; before any fit, from the
measured outputs themselves) the part coherent with the measured inputs is removed:

.. math::

    \\hat S_n(f) = \\frac{K}{K - m} \\Big( S_{rr} - S_{ru} S_{uu}^{-1} S_{ur} \\Big)(f)

(Welch cross-spectra, ``m`` inputs, ``K`` equivalent independent averages — the conditioned spectrum of
Bendat & Piersol, *Random Data*, 4th ed., §7.3, with its bias ``m/K`` removed).  A linear time-invariant model
error is a response to the inputs and is coherent with them, so it does not enter the noise model; the noise
does.  Its shape is fitted on the *quiet* bins only — outside the record's own excited band (from its input
spectrum), where the record carries noise and no response: ``log S = c₀ + c₁ log f + c₂ (log f)²`` (degree 0:
white; 1: a power law such as 1/f), either alone or ending in an acquisition's anti-alias edge
``− log(1 + (f/f_c)^{2n})`` (a Butterworth-like roll-off of order ``n`` from its corner ``f_c``: every real
record's noise has passed one), or a white floor plus one second-order resonance (a transducer's mounted
resonance), chosen by BIC, carried across the excited band, and realised as the AR whitening polynomial of that
shape (Yule–Walker, the smallest order within 5 % of it).  A model error lies in the excited band, where nothing
is fitted, so it is not absorbed.  Quiet bins that follow none of these shapes (a shelf) claim
no colour: the noise is then white at the Welch floor above the
band (:func:`identification.noise.noise_std`).  A record without a quiet range (an impact) takes another record's
shape, levelled on its own spectrum.  The level's uncertainty is its relative standard error over the bins used.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import linalg, signal, stats

from ebb_model.arrays import as_matrix
from ebb_model.errors import DataError

from .noise import psd_floor, welch_dof, welch_nperseg
from .noise_shapes import MIN_QUIET, TOP, common_edge, shapes


class ShapeError(ValueError):
    """A noise spectrum this model cannot represent (internal: the estimator then claims no colour)."""


__all__ = ["MAX_ORDER", "NoiseModel", "NoiseSpectrum", "conditioned_spectrum", "estimate_noise_model",
           "fit_spectrum", "quiet_bins"]

#: Largest AR order of the whitening filter of a coloured noise spectrum (smooth shapes such as 1/f).
MAX_ORDER = 48
#: Misfit of the smooth shape (rms in the natural log of the spectrum, beyond the estimate's own scatter) above
#: which the quiet bins are said to follow no smooth shape: 0.2 ≈ 20 % in the spectrum.
_SHAPE_TOLERANCE = 0.2

@dataclass(frozen=True, eq=False)
class NoiseSpectrum:
    """The noise of one sensor in one record: ``A(q) e = σ w`` (module docstring).

    Attributes
    ----------
    std
        Innovation standard deviation ``σ`` (white noise: its standard deviation).
    ar
        Whitening polynomial ``[1, a_1, …, a_p]`` (``[1.0]``: white).
    variance
        Variance of the noise itself (``σ²`` for white noise, more for coloured noise of the same ``σ``).
    rel_std_error
        Relative standard error of the level (of ``variance``).
    """

    std: float
    ar: np.ndarray
    variance: float
    rel_std_error: float

    @property
    def white(self) -> bool:
        """Whether the spectrum is flat (AR order 0)."""
        return len(self.ar) == 1

    def whiten(self, r: np.ndarray) -> np.ndarray:
        """``A(q) r / σ`` along axis 0 (zero initial conditions)."""
        if self.white:
            return r / self.std
        return signal.lfilter(self.ar, [1.0], r, axis=0) / self.std

    def psd(self, f: np.ndarray, dt: float) -> np.ndarray:
        """One-sided PSD ``2 dt σ² / |A(e^{i2πf dt})|²`` at frequencies ``f`` [Hz]."""
        z = np.exp(-2j * np.pi * np.outer(np.asarray(f, dtype=float) * dt, np.arange(len(self.ar))))
        return 2.0 * dt * self.std ** 2 / np.abs(z @ self.ar) ** 2

    @classmethod
    def of_std(cls, std: float) -> NoiseSpectrum:
        """White noise of standard deviation ``std``, its level taken as exact."""
        return cls(float(std), np.array([1.0]), float(std) ** 2, 0.0)


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """The noise of every sensor in every record (``spectra[i][s]``)."""

    spectra: tuple[tuple[NoiseSpectrum, ...], ...]

    @classmethod
    def white(cls, std: Sequence[float] | np.ndarray, n_records: int) -> NoiseModel:
        """The same white noise of standard deviation ``std[s]`` per sensor in every record."""
        row = tuple(NoiseSpectrum.of_std(float(v)) for v in np.ravel(std))
        return cls(tuple(row for _ in range(n_records)))

    def whiten(self, record: int, r: np.ndarray) -> np.ndarray:
        """Whitened residuals of record ``record``: each column ``s`` through ``A_s(q)/σ_s``."""
        r = np.asarray(r, dtype=float)
        return np.column_stack([sp.whiten(r[:, s]) for s, sp in enumerate(self.spectra[record])])

    @property
    def std(self) -> np.ndarray:
        """White-equivalent standard deviation ``sqrt(variance)`` per record and sensor, ``(n_records, n_sensors)``."""
        return np.array([[math.sqrt(sp.variance) for sp in row] for row in self.spectra])

    @property
    def white_everywhere(self) -> bool:
        """Whether every spectrum is flat."""
        return all(sp.white for row in self.spectra for sp in row)

    def describe(self, names: Sequence[str], records: Sequence[str]) -> list[str]:
        """One line per record: each sensor's level and colour (``white`` or ``AR(p)``)."""
        lines = []
        for rec, row in zip(records, self.spectra):
            parts = [f"{n} {math.sqrt(sp.variance):.3g} ({'white' if sp.white else f'AR({len(sp.ar) - 1})'}"
                     f" ±{100 * sp.rel_std_error:.0f} %)" for n, sp in zip(names, row)]
            lines.append(f"{rec}: " + ", ".join(parts))
        return lines


def conditioned_spectrum(r: np.ndarray, u: np.ndarray, dt: float, *, nperseg: int | None = None
                         ) -> tuple[np.ndarray, np.ndarray, float]:
    """The part of ``r``'s spectrum not coherent with the inputs ``u`` (module docstring), bias-corrected.

    Parameters
    ----------
    r
        Residuals (or outputs), ``(n, n_out)``.
    u
        Inputs, ``(n, m)``.
    dt
        Sample time [s].
    nperseg
        Welch segment length (default ``clip(n // 8, 256, 4096)``).

    Returns
    -------
    f, S, nu
        Frequencies [Hz], the conditioned one-sided PSD ``(n_f, n_out)`` and the equivalent chi-square degrees
        of freedom of one bin.
    """
    r = as_matrix(r, "r")
    u = as_matrix(u, "u")
    n = r.shape[0]
    nperseg = welch_nperseg(n) if nperseg is None else min(int(nperseg), n)
    fs = 1.0 / dt
    kw = dict(fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2, detrend="constant",
              scaling="density", axis=0)
    f, Srr = signal.welch(r, **kw)
    m = u.shape[1]
    Suu = np.empty((len(f), m, m), dtype=complex)
    Sur = np.empty((len(f), m, r.shape[1]), dtype=complex)
    for a in range(m):
        for b in range(m):
            Suu[:, a, b] = signal.csd(u[:, a], u[:, b], **kw)[1]
        for s in range(r.shape[1]):
            Sur[:, a, s] = signal.csd(u[:, a], r[:, s], **kw)[1]
    nu = welch_dof(n, nperseg)
    k_eff = nu / 2.0                     # equivalent independent averages
    scale = np.trace(Suu, axis1=1, axis2=2).real
    excited = scale > 1e-6 * scale.max() if scale.max() > 0 else np.zeros(len(f), dtype=bool)
    S = Srr.copy()
    for i in np.flatnonzero(excited):
        coh = np.real(np.einsum("as,ab,bs->s", Sur[i].conj(), np.linalg.pinv(Suu[i], rcond=1e-10), Sur[i]))
        S[i] = np.maximum(Srr[i] - coh, 0.0)
    if k_eff > m + 1:
        S[excited] *= k_eff / (k_eff - m)
    return f, S, nu


def _yule_walker(S: np.ndarray, p: int) -> tuple[np.ndarray, float]:
    """AR(p) polynomial and innovation variance of a process whose autocovariance is the inverse FFT of the
    one-sided PSD ``S`` on an evenly spaced grid from 0 to Nyquist (up to a constant factor)."""
    acov = np.fft.irfft(S)
    if p == 0:
        return np.array([1.0]), float(acov[0])
    a = linalg.solve_toeplitz(acov[:p], -acov[1:p + 1])
    return np.concatenate([[1.0], a]), float(acov[0] + acov[1:p + 1] @ a)


def fit_spectrum(f: np.ndarray, S: np.ndarray, nu: float, dt: float, quiet: np.ndarray, *,
                 max_degree: int = 2, max_order: int = MAX_ORDER, edge: tuple[float, int] | None = None
                 ) -> NoiseSpectrum:
    """The noise spectrum that fits the PSD estimate ``S`` on the ``quiet`` bins (where the record carries no
    signal), carried smoothly across the band the inputs excite.

    The shape is either ``log S = c₀ + c₁ log f + … + c_d (log f)^d`` (``d = 0``: white; ``d = 1``: a power law
    such as 1/f; ``d ≤ max_degree``) or a white floor plus one second-order resonance (a transducer's mounted
    resonance), each ending in the record's anti-alias ``edge`` ``(corner, order)`` when it has one (the shapes:
    :mod:`identification.noise_shapes`), chosen by BIC of the log-periodogram regression (the log of a Welch bin
    with ``ν`` degrees of freedom has variance ``ψ′(ν/2)``; every other bin, Hann bins being correlated in
    pairs); bins far above the fit (a response's tail, a harmonic) are dropped and the fit repeated.  The
    whitening polynomial is the Yule–Walker AR fit of that shape (the smallest order up to ``max_order`` within
    5 % of it in the mean log spectrum); white noise keeps ``[1]``.

    Raises
    ------
    DataError
        Fewer than :data:`MIN_QUIET` quiet bins with power.
    ShapeError
        The quiet bins follow none of the shapes, or no AR order up to ``max_order`` realises it.
    """
    from scipy.special import digamma, polygamma

    keep = quiet & (f > 0) & (f <= TOP * f[-1]) & (S > 0)
    idx = np.flatnonzero(keep)[::2]
    if idx.size < MIN_QUIET:
        raise DataError("noise: too few frequency bins outside the excited band to estimate the noise")
    fq, logS = f[idx], np.log(S[idx])
    var_log = float(polygamma(1, nu / 2.0))
    best: tuple[float, str, object, int, np.ndarray] | None = None
    for label, logshape, k, used in shapes(fq, logS, var_log, max_degree, edge):
        rss = float(np.sum((logS - logshape(fq))[used] ** 2)) / var_log
        bic = rss + k * math.log(max(int(used.sum()), 2))
        if best is None or bic < best[0]:
            best = (bic, label, logshape, k, used)
    assert best is not None
    _, label, logshape, k, used = best
    dev2 = (logS - logshape(fq))[used] ** 2          # type: ignore[operator]
    lack = float(np.sum(dev2)) / var_log
    dof = max(int(used.sum()) - k, 1)
    excess = math.sqrt(max(float(np.mean(dev2)) - var_log, 0.0))      # misfit beyond the sampling scatter
    if (stats.chi2.sf(lack, dof) < 1e-3 and excess > _SHAPE_TOLERANCE) or used.sum() < 0.8 * used.size:
        # the quiet bins do not follow one of the shapes (a shelf, an edge the record's other sensors do not
        # share): a shape the model cannot carry across the band — no colour is claimed
        raise ShapeError("the noise spectrum outside the excited band is not one of the modelled shapes")
    # E[log of a chi-square with ν dof over ν] = ψ(ν/2) − log(ν/2): the log-periodogram's bias
    bias = float(digamma(nu / 2.0) - math.log(nu / 2.0))
    f_min = float(f[1])             # below the estimate's resolution the shape is held
    grid = np.fft.rfftfreq(2 * 4096, dt)
    with np.errstate(over="ignore", under="ignore"):
        shape = np.exp(logshape(np.maximum(grid, f_min)) - bias)      # type: ignore[operator]
    if not np.all(np.isfinite(shape) & (shape > 0.0)):
        # a shape fitted on the quiet bins that overflows or underflows elsewhere on the grid (a steep polynomial
        # in log f carried down across the band: a cantilever's correct 2 s record under noise to 0.2 fs, at the
        # truth, ended in NaN autocovariances and a ValueError) cannot be carried across the band either
        raise ShapeError("the noise spectrum's shape does not stay finite across the band")
    n_used = max(int(used.sum()), 1)
    rel_err = math.sqrt(var_log / n_used)
    if label == "white":
        variance = float(shape[0]) / (2.0 * dt)
        return NoiseSpectrum(math.sqrt(variance), np.array([1.0]), variance, rel_err)
    variance = float(np.trapezoid(shape, grid))
    judged = grid >= 4.0 * f_min           # the lowest few bins of a 1/f shape matter little and cost many orders
    misfit = math.inf
    for p in range(1, max_order + 1):
        try:
            a, _ = _yule_walker(shape, p)
        except np.linalg.LinAlgError:      # the shape's autocovariance numerically singular at this order: so is
            break                          # every higher order's (it holds this one as its leading block)
        sp = NoiseSpectrum(1.0, a, 0.0, 0.0)
        g = sp.psd(grid[judged], dt)
        level = float(np.exp(np.mean(np.log(shape[judged] / g))))
        misfit = float(np.sqrt(np.mean(np.log(level * g / shape[judged]) ** 2)))
        if misfit < 0.05:
            return NoiseSpectrum(math.sqrt(level), a, variance, rel_err)
    raise ShapeError(f"no whitening filter of order <= {max_order} realises the noise's shape "
                     f"(log misfit {misfit:.2f})")


def quiet_bins(f: np.ndarray, u: np.ndarray, dt: float, *, margin: float = 1.5) -> np.ndarray:
    """The bins outside this record's excited band (:func:`ebb_model.space.adequacy.excited_band` of its inputs)
    widened by ``margin`` either way: where the record carries noise, not signal."""
    from ebb_model.space.adequacy import excited_band

    lo, hi = excited_band([u], dt)
    return (f < lo / margin) | (f > hi * margin)


def estimate_noise_model(inputs: Sequence[np.ndarray], residuals: Sequence[np.ndarray], dt: float, *,
                         max_order: int = MAX_ORDER) -> NoiseModel:
    """The noise model of every record: each sensor's residual conditioned on the record's inputs
    (:func:`conditioned_spectrum`) and fitted by an AR spectrum (:func:`fit_spectrum`).

    Parameters
    ----------
    inputs, residuals
        Per record: the measured inputs ``(n, m)`` and the residuals of the best fit ``(n, n_out)`` (or the
        measured outputs, before any fit).
    dt
        Sample time [s].
    max_order
        Largest AR order.

    Raises
    ------
    DataError
        A record whose residual carries no power.
    """
    fitted: list[tuple[NoiseSpectrum, ...] | None] = []
    for u, r in zip(inputs, residuals):
        f, S, nu = conditioned_spectrum(r, u, dt)
        quiet = quiet_bins(f, as_matrix(u, "u"), dt)
        if np.count_nonzero(quiet[1:] & (f[1:] <= TOP * f[-1])) < 2 * MIN_QUIET:
            fitted.append(None)       # no quiet range: the shape comes from another record (below)
            continue
        edge = common_edge(f, S, nu, quiet)
        fitted.append(tuple(_spectrum_or_floor(f, S[:, s], nu, dt, quiet, max_order, r[:, s], u, edge)
                            for s in range(S.shape[1])))
    donor = next((row for row in fitted if row is not None), None)
    out = [row if row is not None else _borrowed(donor, as_matrix(r, "r"), dt)
           for row, r in zip(fitted, residuals)]
    return NoiseModel(tuple(out))


def _spectrum_or_floor(f: np.ndarray, S: np.ndarray, nu: float, dt: float, quiet: np.ndarray, max_order: int,
                       r: np.ndarray, u: np.ndarray, edge: tuple[float, int] | None) -> NoiseSpectrum:
    """:func:`fit_spectrum`, or — when the quiet bins follow no smooth shape it can carry across the band — white
    noise at the Welch floor above the excited band (:func:`identification.noise.noise_std`: the estimate used
    before there was a noise model)."""
    from ebb_model.space.adequacy import excited_band

    from .noise import noise_std

    try:
        return fit_spectrum(f, S, nu, dt, quiet, max_order=max_order, edge=edge)
    except ShapeError:
        v = float(noise_std(r[:, None], dt, band=(0.0, excited_band([u], dt)[1]))[0])
        return NoiseSpectrum(v, np.array([1.0]), v * v, math.sqrt(2.0 / nu))


def _borrowed(donor: tuple[NoiseSpectrum, ...] | None, r: np.ndarray, dt: float) -> tuple[NoiseSpectrum, ...]:
    """The noise of a record whose inputs excite (nearly) every frequency (an impact, a chirp to Nyquist), which
    has no quiet range to see the noise's colour in: each sensor's shape from another record's model
    (``donor``: the same sensors, the same measurement chain; white without one), levelled on this record by
    the floor of its residual's spectrum over that shape — signal only adds power, so the quietest blocks of
    ``P_rr(f) / shape(f)`` are the noise's level."""
    n = r.shape[0]
    nperseg = welch_nperseg(n)
    f, P = signal.welch(r, fs=1.0 / dt, window="hann", nperseg=nperseg, noverlap=nperseg // 2,
                        detrend="constant", scaling="density", axis=0)
    band = (f >= 0.02 * f[-1]) & (f <= TOP * f[-1])
    nu = welch_dof(n, nperseg)
    m = max(8, int(np.count_nonzero(band)) // 32)
    row = []
    for s in range(r.shape[1]):
        shape = NoiseSpectrum.of_std(1.0) if donor is None else donor[s]
        ratio = P[band, s] / shape.psd(f[band], dt)
        if len(ratio) // m < 2:
            raise DataError("noise: the record is too short to estimate its noise level")
        floor, rel_block = psd_floor(ratio, m, nu)          # σ² of the shape
        row.append(NoiseSpectrum(shape.std * math.sqrt(floor), shape.ar, shape.variance * floor, rel_block))
    return tuple(row)
