"""The records' modes as a modal analyst reads them: averaged FRFs, a stabilised pole estimator, a stability chart.

Peak-picking a mode indicator takes the noise of a broadband record's FRF for resonances (a white force over a
10 s record gave 145 "peaks" on a beam with 13 modes in the band).  What modal testing does instead, and what
this module does:

1. **FRFs** — H1 = S_yu S_uu⁻¹ from Welch's averaged spectra (:func:`frequency_response_estimate`), per sensor and
   force.
2. **Poles** — the least-squares complex-frequency estimator (LSCF; sdypy-EMA's implementation) on every force's
   FRFs over overlapping sub-bands (:data:`BAND_RATIO` wide, each :data:`BAND_STEP` above the last), at model
   orders ``2 … 2·ORDER``: a band of its own gives a mode 40 dB below its neighbours (the first mode through an
   accelerometer) its own share of the least squares.
3. **Stability chart** — a pole is stable at an order when the order before has one within
   :data:`FREQUENCY_TOLERANCE` in frequency and :data:`DAMPING_TOLERANCE` in damping (relative), with a damping
   ratio in ``(0, MAX_DAMPING)``; stable poles of all bands are clustered by frequency, and a cluster is a mode
   when it is stable in at least :data:`MIN_SUPPORT` of one band's orders (its *support*).  Noise gives poles that
   wander from order to order and never stabilise; modes at a sensor's node or weakly excited are absent, which
   the start allows (:mod:`identification.data_start`).

Bands inside ``2/duration … (1 − EDGE)·Nyquist`` and where the forces carry power; each band's outer
:data:`BAND_MARGIN` (in log frequency) is left to its neighbours (the estimator's poles near a band's edges
fit the truncated neighbours, not modes).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import signal

from ebb_model.space.adequacy import is_transient
from ebb_model.acquisition.channel_delay import delay_outputs

__all__ = ["RecordModes", "record_modes", "frequency_response_estimate", "EDGE"]

#: Share of the Nyquist frequency kept free at the top of the band (aliases of the modes above it).
EDGE = 0.08
#: The band where the inputs carry power: each input's auto-spectrum within this share of its largest value.
EXCITED = 1e-2
#: Time constant of the exponential window of a transient record, as a share of its length.
EXP_WINDOW = 0.2
#: Ratio of a sub-band's upper to its lower edge, and of one band's lower edge to the next one's.
BAND_RATIO = 6.0
BAND_STEP = 3.0
#: Share of a band's width (log frequency) at either end left to the neighbouring bands.
BAND_MARGIN = 0.1
#: Highest LSCF model order per band is ``2·ORDER``.
ORDER = 24
#: Stability between consecutive orders: relative change of frequency and of damping ratio.
FREQUENCY_TOLERANCE = 0.005
DAMPING_TOLERANCE = 0.3
#: A physical mode's damping ratio lies in (0, MAX_DAMPING).
MAX_DAMPING = 0.2
#: A cluster of stable poles is a mode when it is stable at CLEAR_SUPPORT of a band's orders, or at MIN_SUPPORT of
#: one band's and CORROBORATION of every other band's (of either estimate; at least one other) whose inner range
#: holds it: noise stabilises for a while in one band, a mode in every band that sees it.
CLEAR_SUPPORT = 0.5
MIN_SUPPORT = 0.3
CORROBORATION = 0.15


@dataclass(frozen=True)
class RecordModes:
    """The records' modes: frequencies [Hz] (ascending), damping ratios and support (share of a band's orders at
    which each is stable, 0.3 … 1), and the band searched [Hz]."""

    frequencies_hz: np.ndarray
    damping: np.ndarray
    support: np.ndarray
    band_hz: tuple[float, float]



def frequency_response_estimate(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], dt: float,
                                whole: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The records' H1 frequency response ``Y(f)/U(f)`` (the ``e^{iωt}`` convention), averaged over the experiments.

    Welch's averaged periodograms (Hann, half overlap, segments of a quarter of the record) for a persistent
    excitation; for a transient one (a hammer blow) the whole record as one segment under impact testing's
    exponential window (the blow itself untouched).

    Returns
    -------
    f, H, excited
        Frequencies [Hz] ``(F,)``, the response ``(F, n_out, n_in)`` and where the inputs carry power (every
        input's auto-spectrum within :data:`EXCITED` of its largest value).
    """
    n_min = min(u.shape[0] for u in inputs)
    transient = True if whole else any(is_transient(u) for u in inputs)
    nper = n_min if transient else max(16, n_min // 4)
    window = "boxcar" if transient else "hann"
    n_in, n_out = inputs[0].shape[1], outputs[0].shape[1]
    f = np.fft.rfftfreq(nper, dt)
    Suu = np.zeros((f.size, n_in, n_in), complex)
    Suy = np.zeros((f.size, n_in, n_out), complex)
    for u, y in zip(inputs, outputs):
        if transient:
            w = np.exp(-np.arange(u.shape[0]) / (EXP_WINDOW * n_min))[:, None]
            u, y = u * w, y * w
        for a in range(n_in):
            def csd(x: np.ndarray, z: np.ndarray) -> np.ndarray:
                return signal.csd(x, z, fs=1 / dt, window=window, nperseg=nper,
                                  noverlap=0 if transient else nper // 2, detrend=False)[1]
            for b in range(n_in):
                Suu[:, a, b] += csd(u[:, a], u[:, b])
            for o in range(n_out):
                Suy[:, a, o] += csd(u[:, a], y[:, o])     # conj(U) Y: the FRF's own phase
    if whole and not any(is_transient(u) for u in inputs):
        # where a persistent excitation carries power: from its averaged spectrum, not one periodogram's scatter
        fw, pw = signal.welch(np.vstack(inputs), fs=1 / dt, nperseg=max(16, n_min // 4), axis=0, detrend=False)
        power = np.column_stack([np.interp(f, fw, pw[:, a]) for a in range(n_in)])
    else:
        power = np.real(np.einsum("fii->fi", Suu))
    excited = np.all(power > EXCITED * power.max(axis=0, initial=0.0), axis=1)
    H = np.zeros((f.size, n_out, n_in), complex)
    if np.any(excited):
        # H Suu = Suyᵀ per frequency, Suu Hermitian: H = (Suu⁻¹ Suy)ᵀ (pinv: correlated inputs stay finite)
        H[excited] = np.swapaxes(np.linalg.pinv(np.swapaxes(Suu[excited], 1, 2)) @ Suy[excited], 1, 2)
    return f, H, excited


def _band_poles(f: np.ndarray, H: np.ndarray, lo: float, hi: float, order: int
                ) -> list[tuple[np.ndarray, np.ndarray]]:
    """LSCF's poles (frequencies [Hz], damping ratios) per order ``2 … 2·order`` on the FRFs ``H`` (F, channels)
    within ``[lo, hi]``."""
    from sdypy import EMA

    sel = f <= hi
    frf = H[sel].T
    scale = np.max(np.abs(frf[:, f[sel] >= lo]), axis=1, initial=0.0)
    frf = frf[scale > 0] / scale[scale > 0, None]          # each channel at its own level
    if frf.shape[0] == 0:
        return []
    model = EMA.Model(frf=frf, freq=f[sel], lower=lo, upper=float(f[sel][-1]), pol_order_high=order,
                      frf_form="receptance")
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        model.get_poles(show_progress=False)
    return [(np.asarray(fr, float), np.asarray(xi, float)) for fr, xi in zip(model.pole_freq, model.pole_xi)]


def _stable(orders: list[tuple[np.ndarray, np.ndarray]], lo: float, hi: float) -> list[tuple[int, float, float]]:
    """``(order index, frequency, damping)`` of the poles stable from one order to the next inside ``[lo, hi]``."""
    out = []
    prev: tuple[np.ndarray, np.ndarray] | None = None
    for j, (fr, xi) in enumerate(orders):
        ok = (fr > lo) & (fr < hi) & (xi > 0) & (xi < MAX_DAMPING)
        fr, xi = fr[ok], xi[ok]
        if prev is not None and prev[0].size:
            for a, z in zip(fr, xi):
                i = int(np.argmin(np.abs(prev[0] - a)))
                if abs(prev[0][i] - a) <= FREQUENCY_TOLERANCE * a and abs(prev[1][i] - z) <= DAMPING_TOLERANCE * z:
                    out.append((j, float(a), float(z)))
        prev = (fr, xi)
    return out


def record_modes(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], dt: float,
                 delays: Sequence[float] = ()) -> RecordModes:
    """The records' modes (module docstring); empty when none is stable (a record excited only below its first
    mode, say).  ``delays``: each output channel's delay after the force's in samples
    (:func:`ebb_model.acquisition.channel_delay.effective_delays`), taken out of the records first (a delay is a phase
    that grows with frequency, which no pole describes)."""
    outputs = [delay_outputs(y, [-d for d in delays]) for y in outputs] if any(delays) else outputs
    stable: list[tuple[int, int, float, float]] = []           # (band, order, frequency, damping)
    bands: list[tuple[float, float, int]] = []                  # each band's inner range [Hz] and orders
    band_hz = (0.0, 0.0)
    grid = 0.0
    transient = any(is_transient(u) for u in inputs)
    for whole in ((False,) if transient else (False, True)):   # a blow's two estimates are one
        found, band_hz_est, df = _stable_poles(inputs, outputs, dt, whole, bands)
        stable += found
        if band_hz_est[1] > band_hz_est[0]:
            band_hz = (min(band_hz[0] or band_hz_est[0], band_hz_est[0]), max(band_hz[1], band_hz_est[1]))
            grid = max(grid, df)
    if not stable:
        return RecordModes(np.zeros(0), np.zeros(0), np.zeros(0), band_hz)
    stable.sort(key=lambda s: s[2])
    clusters: list[list[tuple[int, int, float, float]]] = [[stable[0]]]
    for s in stable[1:]:
        centre = float(np.median([c[2] for c in clusters[-1]]))
        # one mode: within the stability tolerance, or two bins (a lightly damped mode on a coarse grid)
        if s[2] - centre <= max(2 * FREQUENCY_TOLERANCE * centre, 2 * grid):
            clusters[-1].append(s)
        else:
            clusters.append([s])
    freqs, damping, support = [], [], []
    for c in clusters:
        per_band: dict[int, set[int]] = {}
        for b, j, _, _ in c:
            per_band.setdefault(b, set()).add(j)
        centre = float(np.median([s[2] for s in c]))
        # its share of the orders in every band (of either estimate) whose inner range holds it
        shares = [len(per_band.get(b, ())) / n for b, (lo, hi, n) in enumerate(bands) if lo <= centre <= hi]
        share = max(len(v) / bands[b][2] for b, v in per_band.items())
        if share >= CLEAR_SUPPORT or (share >= MIN_SUPPORT and len(shares) > 1 and min(shares) >= CORROBORATION):
            freqs.append(float(np.median([s[2] for s in c])))
            damping.append(float(np.median([s[3] for s in c])))
            support.append(min(share, 1.0))
    return RecordModes(np.array(freqs), np.array(damping), np.array(support), band_hz)


def _stable_poles(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], dt: float, whole: bool,
                  bands: list[tuple[float, float, int]]
                  ) -> tuple[list[tuple[int, int, float, float]], tuple[float, float], float]:
    """The stable poles ``(band, order, frequency, damping)`` of every sub-band on one FRF estimate (Welch's, or
    the whole record's), the excited band [Hz] and the estimate's bin width [Hz]; each band's inner range and
    order count appended to ``bands``."""
    f, H, excited = frequency_response_estimate(inputs, outputs, dt, whole=whole)
    duration = min(u.shape[0] for u in inputs) * dt
    usable = excited & (f > 2.0 / duration) & (f < (1.0 - EDGE) * 0.5 / dt)
    df = float(f[1] - f[0])
    if np.count_nonzero(usable) < 8:
        return [], (0.0, 0.0), df
    # the contiguous excited band from the lowest usable bin (a hammer's spectrum beyond its first zero is noise)
    first = int(np.argmax(usable))
    run = usable[first:]
    last = first + (int(np.argmin(run)) - 1 if not np.all(run) else run.size - 1)
    if last - first < 8:
        return [], (0.0, 0.0), df
    f_lo, f_hi = float(f[first]), float(f[last])
    stable: list[tuple[int, int, float, float]] = []
    upper = f_hi
    while True:
        lo = max(upper / BAND_RATIO, f_lo)
        if upper - lo > 16 * df:
            margin = BAND_MARGIN * math.log(upper / lo)
            inner_lo = lo if lo <= f_lo else lo * math.exp(margin)
            inner_hi = upper if upper >= f_hi else upper * math.exp(-margin)
            # no more poles than a quarter of the band's bins: an over-fitted band stabilises its noise
            order = min(ORDER, int((upper - lo) / df) // 4)
            for i in range(H.shape[2] if order >= 4 else 0):
                orders = _band_poles(f, H[:, :, i], lo, upper, order)
                stable += [(len(bands), j, a, z) for j, a, z in _stable(orders, inner_lo, inner_hi)]
                bands.append((inner_lo, inner_hi, order - 1))
        if lo <= f_lo:
            break
        upper /= BAND_STEP
    return stable, (f_lo, f_hi), df
