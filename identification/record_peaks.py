"""What the records say before any model is fitted: their frequency response and its resonance peaks.

The measured frequency response of every sensor to every actuator, ``H = S_yu S_uu⁻¹`` (H1, averaged over the
experiments), is read where the inputs carry power; its resonances are the peaks of the mode indicator

.. math::  m(f) = \\sum_{o, i} |H_{oi}(f)|^2 / \\operatorname{median}_f |H_{oi}|^2,

each channel weighted by its own level so that no sensor kind (an accelerometer's rising response, a
displacement sensor's falling one) drowns the others.  A peak counts when it stands :data:`PROMINENCE_DB` above
the indicator's surroundings (:func:`scipy.signal.find_peaks`' prominence over a window of :data:`WINDOW_OCTAVES`
octaves: a weak mode between two strong ones is still a peak of its own).

Estimate: Welch's averaged periodograms (Hann, half overlap, segments of a quarter of the record) for a
persistent excitation; for a transient one — a hammer blow, most of the input's energy in a short part of the
record — the whole record as one rectangular segment (a window would cut the blow away).  Frequencies within
:data:`EDGE` of the Nyquist frequency are left out: an unfiltered acquisition folds the modes above Nyquist there
(aliases are not modes of the band), and the first bins (below two cycles per record) carry the leakage of the
record's start.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy import signal

__all__ = ["EDGE", "PROMINENCE_DB", "WINDOW_OCTAVES", "frequency_response_estimate", "resonance_peaks"]

#: A resonance stands at least this far above its surroundings in the mode indicator [dB].
PROMINENCE_DB = 6.0
#: Width of the surroundings a peak's prominence is measured in [octaves either side].
WINDOW_OCTAVES = 0.5
#: Share of the Nyquist frequency kept free at the top of the band (aliases of the modes above it).
EDGE = 0.08
#: The band where the inputs carry power: each input's auto-spectrum within this share of its largest value
#: (20 dB; below it the estimate is the noise's, and a hammer's spectrum beyond its first zero is mostly noise).
EXCITED = 1e-2
#: Time constant of the exponential window of a transient record, as a share of its length.
EXP_WINDOW = 0.2
#: An input whose energy lies for this share within a tenth of the record is a transient (a hammer blow).
TRANSIENT_SHARE = 0.9


def _is_transient(u: np.ndarray) -> bool:
    """Whether most of the input's energy lies in a tenth of the record (a blow, not a persistent excitation)."""
    e = np.sum(u * u, axis=1)
    total = float(e.sum())
    if total <= 0.0:
        return False
    w = max(1, e.size // 10)
    run = np.convolve(e, np.ones(w), mode="valid")
    return float(run.max()) >= TRANSIENT_SHARE * total


def frequency_response_estimate(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], dt: float
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The records' H1 frequency response, averaged over the experiments.

    Parameters
    ----------
    inputs, outputs
        Per experiment: inputs ``(n, n_in)`` and outputs ``(n, n_out)``, all with the same sample time ``dt``.

    Returns
    -------
    f, H, excited
        Frequencies [Hz] ``(F,)``, the response ``(F, n_out, n_in)`` and where the inputs carry power (a
        boolean mask: every input's auto-spectrum within :data:`EXCITED` of its largest value).
    """
    n_min = min(u.shape[0] for u in inputs)
    transient = any(_is_transient(u) for u in inputs)
    nper = n_min if transient else max(16, n_min // 4)
    window = "boxcar" if transient else "hann"
    n_in, n_out = inputs[0].shape[1], outputs[0].shape[1]
    f = np.fft.rfftfreq(nper, dt)
    Suu = np.zeros((f.size, n_in, n_in), complex)
    Syu = np.zeros((f.size, n_out, n_in), complex)
    for u, y in zip(inputs, outputs):
        if transient:
            # impact testing's exponential window: the response decays within the record (no leakage
            # sidelobes around each resonance), the blow itself untouched
            w = np.exp(-np.arange(u.shape[0]) / (EXP_WINDOW * n_min))[:, None]
            u, y = u * w, y * w
        for a in range(n_in):
            for b in range(n_in):
                Suu[:, a, b] += signal.csd(u[:, a], u[:, b], fs=1 / dt, window=window, nperseg=nper,
                                           noverlap=0 if transient else nper // 2, detrend=False)[1]
            for o in range(n_out):
                Syu[:, o, a] += signal.csd(y[:, o], u[:, a], fs=1 / dt, window=window, nperseg=nper,
                                           noverlap=0 if transient else nper // 2, detrend=False)[1]
    power = np.real(np.einsum("fii->fi", Suu))
    excited = np.all(power > EXCITED * power.max(axis=0, initial=0.0), axis=1)
    H = np.zeros((f.size, n_out, n_in), complex)
    if np.any(excited):
        # S_yu S_uu^-1 per frequency (pinv: inputs correlated at some frequencies stay finite)
        H[excited] = Syu[excited] @ np.linalg.pinv(Suu[excited])
    return f, H, excited


def resonance_peaks(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], dt: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies [Hz] of the records' resonance peaks, ascending, and their prominence [dB] (module
    docstring); empty when none stands out (a record excited only below its first mode, say)."""
    f, H, excited = frequency_response_estimate(inputs, outputs, dt)
    duration = min(u.shape[0] for u in inputs) * dt
    usable = excited & (f > 2.0 / duration) & (f < (1.0 - EDGE) * 0.5 / dt)
    if np.count_nonzero(usable) < 5:
        return np.zeros(0), np.zeros(0)
    mag2 = np.abs(H[usable]) ** 2
    level = np.median(mag2, axis=0)
    level = np.where(level > 0, level, 1.0)
    mif = np.sum(mag2 / level, axis=(1, 2))
    fu = f[usable]
    db = 10.0 * np.log10(np.maximum(mif, 1e-300))
    # the prominence's surroundings: WINDOW_OCTAVES either side, in bins of the (even) frequency grid
    df = float(f[1] - f[0])
    found = []
    for j in signal.find_peaks(db)[0]:
        lo, hi = fu[j] * 2.0 ** -WINDOW_OCTAVES, fu[j] * 2.0 ** WINDOW_OCTAVES
        wlen = int(2 * max(3, (hi - lo) / df / 2)) + 1
        prom = signal.peak_prominences(db, [j], wlen=wlen)[0][0]
        if prom >= PROMINENCE_DB:
            found.append((_vertex(fu, db, j), float(prom)))
    found.sort()
    return np.array([p[0] for p in found]), np.array([p[1] for p in found])


def _vertex(f: np.ndarray, db: np.ndarray, j: int) -> float:
    """The peak's frequency: vertex of the parabola through its bin and the two beside it (the bin itself
    when they do not bracket a maximum)."""
    if j == 0 or j == f.size - 1:
        return float(f[j])
    a, b, c = db[j - 1], db[j], db[j + 1]
    den = a - 2 * b + c
    if den >= 0:
        return float(f[j])
    return float(f[j] + 0.5 * (a - c) / den * (f[j + 1] - f[j]))
