"""Natural frequencies picked from a measured spectrum (an impact hammer's FFT, a sweep's FRF magnitude).

Labs keep such tests as a spectrum file: frequency in the first column, a magnitude in the second (``.lvm`` as
LabVIEW writes an FFT, or ``.csv``).  :func:`spectrum_modes` picks its resonance peaks and returns them as
:class:`~identification.modal_data.ModalData`, the same evidence as an ``[identification.modes]`` table
(``ebb diagnose … --modes FILE``, ``ebb identify … --modes FILE``).

The rule, stated so a user can check it by eye:

- the magnitude is taken in dB (a column with a negative value is read as dB already, one without as a linear
  magnitude, 20 log10, zeros floored at its smallest positive value; the transform is monotone, so a dB column
  misread as linear keeps its peaks where they are);
- it is smoothed by a running mean over ``smooth_hz`` (an impulse test's spectrum is noisy bin to bin);
- a peak counts when it stands ``prominence_db`` above its surroundings (:func:`scipy.signal.find_peaks`'
  prominence) and within ``within_db`` of the largest peak within :data:`LEVEL_OCTAVES` octaves of it — a much
  weaker peak beside a strong one is a fixture's or torsional mode a beam model does not have; the comparison is
  local because a sensor's response rises or falls by tens of dB across the band (an accelerometer's lowest modes
  stand 30–40 dB below its highest: measured on a tip accelerance, mode 2 of a cantilever 36 dB under mode 7) —,
  peaks closer than ``separation_hz`` merged;
- the peaks are read as the beam's lowest modes in order, so without ``count`` the list stops at the first peak
  that breaks a beam's widening mode spacing: a uniform beam's modes grow further apart with frequency (any
  supports, any axial load short of buckling; a taut string's stay evenly spaced), so a peak closer to its
  predecessor than :data:`SPACING_SHRINK` times the spacing before means one of the two is not the beam's next
  mode — an alias of a mode above Nyquist (an acquisition without an anti-alias filter folds them into the band),
  a torsional or a fixture's mode —; which one a magnitude cannot tell (an alias can sit where the next mode
  would, and the true mode then looks like the intruder), so neither of the pair nor anything above is taken;
  likewise a spacing that grows by more than :data:`GAP_GROWTH` over the one before means a mode between is
  missing from the list (too weak, or at a sensor's node), and the peaks above would be numbered wrong: the list
  ends below the gap (give ``count`` to take peaks beyond).  These catch an image that breaks the pattern, not
  one that happens to fall where the next mode could be: an acquisition without an anti-alias filter can fold
  images anywhere, and only the filter removes them;
- its frequency is the vertex of a parabola fitted by least squares to the unsmoothed dB within 3 dB of the
  peak's top (its half-power band), within ``smooth_hz`` of the smoothed peak — smoothing locates a peak, it
  does not place it (a running mean wider than a peak's half-power band pulls it towards the slope of its
  neighbours);
- its standard uncertainty combines the vertex's standard error (the fit's residual scatter, the delta method), the
  bin's quantisation (``Δf/√12``), the parabola's own bias (:data:`PEAK_BIAS` × f) and ``model_error`` × f, the
  share of the frequency a bare Euler–Bernoulli beam is expected to miss (clamp compliance, the transducers' mass:
  the user's judgement, 1 % by default).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ebb_model.errors import DataError

from .modal_data import ModalData

__all__ = ["GAP_GROWTH", "LEVEL_OCTAVES", "PEAK_BIAS", "SPACING_SHRINK", "spectrum_modes"]

#: Relative bias of a parabola in dB over a resonance's half-power band: a resonance's dB is not a parabola there,
#: and its neighbours tilt it — measured up to 2.7e-4 f on a noise-free four-mode accelerance at 0.05 Hz bins
#: (tests/test_spectrum_modes.py); kept in every pick's uncertainty.
PEAK_BIAS = 3e-4
#: Octaves either side of a peak among which the strongest peak sets its level reference (``within_db``).
LEVEL_OCTAVES = 1.0
#: A peak's spacing to its predecessor below this share of the spacing before ends the list of the beam's modes
#: (module docstring).  A uniform beam's spacing never shrinks; 0.8 leaves a fifth for a peak's uncertainty and for
#: attachments that shift single modes (a tip mass of the beam's own mass: spacings 14.7, 34.6, 54.3 in units of
#: its first frequency, still widening).
SPACING_SHRINK = 0.8
#: Largest growth of one mode spacing over the one before that a beam's list without a missing mode shows: for
#: the second spacing over the first 3.0 (uniform beams up to 2.14, a cantilever's; with a mode missing at least
#: 3.5, a clamped–clamped beam's), beyond it 1.8 (uniform beams up to 1.5; with a mode missing at least 2).
GAP_GROWTH = (3.0, 1.8)


def spectrum_modes(path: str | Path, *, count: int | None = None, band_hz: tuple[float, float] = (1.0, math.inf),
                   smooth_hz: float = 1.0, prominence_db: float = 20.0, within_db: float = 30.0,
                   separation_hz: float = 5.0, model_error: float = 0.01) -> ModalData:
    """The lowest ``count`` resonance peaks (all, when ``None``) of the spectrum file ``path`` in ``band_hz``,
    with their uncertainties (module docstring).

    Raises
    ------
    DataError
        Unreadable file, fewer than two columns, a frequency column that does not increase in even steps,
        non-finite values, no peak found, or fewer than ``count``.
    ValueError
        Options out of range (``count`` < 1, ``smooth_hz``/``separation_hz`` < 0, ``model_error`` < 0).
    """
    from scipy.signal import find_peaks

    if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 1):
        raise ValueError(f"count: must be a whole number >= 1, got {count!r}")
    if min(smooth_hz, separation_hz, model_error, prominence_db, within_db) < 0:
        raise ValueError("smooth_hz, separation_hz, prominence_db, within_db and model_error must be >= 0")
    f, mag = _read(Path(path))
    src = str(path)
    df = float(np.median(np.diff(f)))
    if df <= 0 or np.any(np.abs(np.diff(f) - df) > 1e-3 * df):
        raise DataError(f"{src}: the first column (frequency, Hz) must increase in even steps")
    if np.any(mag < 0):
        db = mag
    elif np.any(mag > 0):
        db = 20.0 * np.log10(np.maximum(mag, mag[mag > 0].min()))
    else:
        raise DataError(f"{src}: the magnitude column is zero throughout")
    keep = (f > band_hz[0]) & (f < band_hz[1])
    f, db = f[keep], db[keep]
    width = max(1, int(round(smooth_hz / df)) | 1)                  # odd: centred
    smooth = np.convolve(db, np.ones(width) / width, mode="same")
    peaks, _ = find_peaks(smooth, prominence=prominence_db, distance=max(1, int(separation_hz / df)))
    peaks = np.array([i for i in peaks
                      if 0 < i < f.size - 1 and smooth[i] >= _local_top(f, smooth, peaks, i) - within_db], dtype=int)
    if count is None:
        peaks = peaks[:_widening(f[peaks])]
    if peaks.size == 0 or (count is not None and peaks.size < count):
        raise DataError(f"{src}: {peaks.size} resonance peak(s) stand {prominence_db:g} dB above their "
                        f"surroundings in {band_hz[0]:g}-{band_hz[1]:g} Hz"
                        + ("" if count is None else f"; {count} asked for"))
    fits = [_vertex(f, db, smooth, int(i)) for i in peaks[:count]]
    freq = np.array([v for v, _ in fits])
    std = np.sqrt(np.array([e for _, e in fits]) ** 2 + df ** 2 / 12.0 + ((PEAK_BIAS + model_error) * freq) ** 2)
    return ModalData(freq, std)


def _local_top(f: np.ndarray, smooth: np.ndarray, peaks: np.ndarray, i: int) -> float:
    """Level of the strongest of ``peaks`` within :data:`LEVEL_OCTAVES` octaves of bin ``i``."""
    near = peaks[np.abs(np.log2(f[peaks] / f[i])) <= LEVEL_OCTAVES]
    return float(smooth[near].max())


def _widening(freq: np.ndarray) -> int:
    """How many of the ascending peaks ``freq`` are read as the beam's lowest modes: up to the first pair that
    breaks a beam's widening spacing (:data:`SPACING_SHRINK`; the pair left out) or below the first gap where a
    mode is missing (:data:`GAP_GROWTH`)."""
    gaps = np.diff(freq)
    for k in range(1, gaps.size):
        if gaps[k] < SPACING_SHRINK * gaps[k - 1]:
            return k
        if gaps[k] > GAP_GROWTH[0 if k == 1 else 1] * gaps[k - 1]:
            return k + 1
    return freq.size


def _vertex(f: np.ndarray, db: np.ndarray, smooth: np.ndarray, j: int) -> tuple[float, float]:
    """Vertex of the least-squares parabola through the unsmoothed dB ``db`` over the band where the smoothed
    ``smooth`` stays within 3 dB of its peak at bin ``j``, and its standard error; bin ``j`` and 0 when no
    parabola opens downwards there."""
    a, b = j, j
    while a > 0 and smooth[a - 1] >= smooth[j] - 3.0:
        a -= 1
    while b < f.size - 1 and smooth[b + 1] >= smooth[j] - 3.0:
        b += 1
    a, b = max(0, min(a, j - 1)), min(f.size - 1, max(b, j + 1))
    x, y = f[a:b + 1] - f[j], db[a:b + 1]
    A = np.column_stack([x * x, x, np.ones_like(x)])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    if coef[0] >= 0.0:
        return float(f[j]), 0.0
    v = -coef[1] / (2.0 * coef[0])
    if abs(v) > f[b] - f[a]:
        return float(f[j]), 0.0
    dof = x.size - 3
    if dof < 1:
        return float(f[j] + v), 0.0
    s2 = float(np.sum((y - A @ coef) ** 2)) / dof
    grad = np.array([coef[1] / (2.0 * coef[0] ** 2), -1.0 / (2.0 * coef[0]), 0.0])
    err = math.sqrt(max(0.0, float(grad @ (s2 * np.linalg.inv(A.T @ A)) @ grad)))
    return float(f[j] + v), err


def _read(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Frequency [Hz] and magnitude columns of a spectrum file (``.lvm`` or CSV)."""
    from .data.csv_format import read_csv
    from .data.lvm import read_lvm

    table = read_lvm(path) if path.suffix.lower() == ".lvm" else read_csv(path)
    if len(table.columns) < 2:
        raise DataError(f"{path}: a spectrum file needs two columns, frequency [Hz] and magnitude; got "
                        f"{len(table.columns)}")
    f, mag = (np.asarray(table.columns[j], dtype=float).ravel() for j in (0, 1))
    if f.size < 5 or not (np.all(np.isfinite(f)) and np.all(np.isfinite(mag))):
        raise DataError(f"{path}: the frequency and magnitude columns must hold at least 5 finite values")
    return f, mag
