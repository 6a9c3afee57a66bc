"""A record that changes during acquisition, cut where a declared channel says the set-up stood still.

A test bed whose support a motor moves (DROPBEAR's roller), a load stepped between dwells, a temperature held in
stages: the structure is a different one in each dwell, and one model of the whole record fits none.  A channel
that follows the change (the roller's position sensor) tells where the set-up stood still.
:func:`stationary_segments` finds those stretches: the channel's running median (robust to its noise and to
the structure's vibration picked up on it) compared with itself a moment earlier — a change beyond
:data:`JUMP_NOISE` of the channel's own noise is motion — and every still stretch at least ``min_seconds`` long
is a segment, with the channel's level over it.  :func:`segment_modes` reads each segment's modes as the free decay
the step before it left (:mod:`identification.output_modes`) or as an ambient record
(:mod:`identification.ambient_modes`), and :func:`track` follows one mode through the segments.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import ndimage

from ebb_model.errors import DataError

from .output_modes import OutputModes

__all__ = ["Segment", "companions", "stationary_segments", "segment_modes", "track", "COMPANION_DAMPING",
           "JUMP_NOISE", "TRACK_RANGE"]

#: A change of the channel's running median beyond this many of its noise's standard deviations is motion.
JUMP_NOISE = 10.0
#: A tracked mode moves by less than this factor from one segment to the next.
TRACK_RANGE = 1.5
#: A mode damped at least this many times as heavily as a better-shown mode within :data:`TRACK_RANGE` of it is a
#: candidate companion of that mode (:func:`companions`).  On DROPBEAR's dwells the companions measured 1.5–30
#: times their neighbour's damping (1.1 % beside 0.73 %, 2.1 % beside 0.07 %).
COMPANION_DAMPING = 1.25


@dataclass(frozen=True)
class Segment:
    """A still stretch of the record: samples ``[start, stop)``, the declared channel's median level over it and
    that level's standard uncertainty (the channel's scatter over the segment's independent samples)."""

    start: int
    stop: int
    level: float
    level_std: float

    def seconds(self, dt: float) -> tuple[float, float]:
        """The segment's start and end [s]."""
        return self.start * dt, self.stop * dt


def _noise_std(x: np.ndarray) -> float:
    """The channel's white-noise standard deviation from its first differences (median absolute deviation)."""
    d = np.diff(x)
    return float(np.median(np.abs(d - np.median(d)))) / 0.6745 / math.sqrt(2.0)


def stationary_segments(channel: np.ndarray, dt: float, *, min_seconds: float = 0.3,
                        smooth_seconds: float = 0.025) -> list[Segment]:
    """The stretches where ``channel`` stands still (module docstring).

    Parameters
    ----------
    channel : array_like
        ``(n,)`` the declared channel (a position sensor's volts, say).
    dt : float
        Sample interval [s].
    min_seconds : float, optional
        The shortest still stretch that is a segment.
    smooth_seconds : float, optional
        Width of the running median, and the lag over which it is compared with itself.

    Returns
    -------
    list of Segment
        In time order; empty when the channel never stands still that long.

    Raises
    ------
    DataError
        A channel that is not a finite 1-D record, or a bad ``dt``.
    """
    x = np.asarray(channel, dtype=float)
    if x.ndim != 1 or x.size < 16 or not np.all(np.isfinite(x)):
        raise DataError("the declared channel must be a finite 1-D record of at least 16 samples")
    if not (math.isfinite(dt) and dt > 0):
        raise DataError(f"the sample interval must be a positive number, got {dt!r}")
    width = max(3, int(round(smooth_seconds / dt)) | 1)
    med = ndimage.median_filter(x, width, mode="nearest")
    change = np.zeros(x.size)
    change[width:] = np.abs(med[width:] - med[:-width])
    noise = _noise_std(x)
    moving = change > JUMP_NOISE * max(noise, 1e-12 * max(float(np.ptp(x)), 1e-300))
    # a move is one: gaps shorter than the median's width inside it closed; its edges widened by that width
    moving = ndimage.binary_dilation(ndimage.binary_closing(moving, np.ones(width, bool)), np.ones(2 * width, bool))
    labels, count = ndimage.label(~moving)
    out = []
    for i in range(1, count + 1):
        idx = np.flatnonzero(labels == i)
        if idx.size * dt < min_seconds:
            continue
        seg = x[idx[0]:idx[-1] + 1]
        out.append(Segment(int(idx[0]), int(idx[-1]) + 1, float(np.median(seg)),
                           float(np.std(seg)) / math.sqrt(max(seg.size / width, 1.0))))
    return out


def segment_modes(outputs: np.ndarray, dt: float, segments: Sequence[Segment], *, kind: str = "decay",
                  skip_seconds: float = 0.1) -> list[OutputModes]:
    """Each segment's modes from the ``outputs`` ``(n, n_sensors)`` — as the free decay the step before it left
    (``kind = "decay"``, :func:`identification.output_modes.free_decay_modes`) or as a stationary record under an
    unmeasured force (``"ambient"``, :func:`identification.ambient_modes.ambient_modes`) — from ``skip_seconds``
    after the segment's start (the motion's last jolt and the support settling) to its end; a segment too short
    for that has no modes.

    Raises
    ------
    DataError
        An unknown ``kind``.
    """
    from .output_record import KINDS

    if kind not in KINDS:
        raise DataError(f"a record without a force is a 'decay' or 'ambient', got {kind!r}")
    y = np.asarray(outputs, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    skip = int(round(skip_seconds / dt))
    out = []
    for s in segments:
        part = y[s.start + skip:s.stop]
        try:
            out.append(KINDS[kind](part - part.mean(axis=0), dt))
        except DataError:                       # too short for the estimator: no modes
            noise = np.std(y[s.start:s.stop], axis=0)
            out.append(OutputModes.none(y.shape[1], noise, kind="ambient" if kind == "ambient" else "free decay"))
    return out


def companions(modes: OutputModes) -> np.ndarray:
    """Which of a segment's modes may be a companion rather than a mode of the structure (``(m,)`` mask): damped
    at least :data:`COMPANION_DAMPING` times as heavily as a mode within :data:`TRACK_RANGE` of it that the records
    show better (its significance).  A support that rattles while the beam rings hard adds such a component
    beside a mode (DROPBEAR's 24–25 Hz at 1.1–2 % beside a first mode of 26–34 Hz at 0.1–0.7 %, at every place of
    the roller; 37.4 Hz at 2.1 % beside 37.6 Hz at 0.07 %).  A candidate only: the fit leaves it out only when
    the model cannot reproduce the modes with it and matches the rest better (:func:`identification.tracking.track`)."""
    f, z, sig = modes.frequencies_hz, modes.damping, modes.significance
    out = np.zeros(f.size, dtype=bool)
    for i in range(f.size):
        near = (np.abs(np.log(f / f[i])) <= math.log(TRACK_RANGE)) & (sig > sig[i])
        out[i] = bool(np.any(near & (z[i] >= COMPANION_DAMPING * z)))
    return out


def track(modes: Sequence[OutputModes], start_hz: float) -> list[int | None]:
    """One mode followed through the segments: in each, among the modes within :data:`TRACK_RANGE` (in ratio)
    of the one before it — ``start_hz`` before the first —, the one the records show best (its significance);
    ``None`` where a segment has none (the next is compared with the last one found).  Returns each segment's
    index into its modes.  The best-shown, not the nearest: a support that rattles while the beam rings hard
    adds a heavily damped companion beside a mode (DROPBEAR's first mode, 24.6 Hz at 1.4 % beside 28.2 Hz at
    0.19 %), which a step of the support can bring nearer than the mode itself."""
    out: list[int | None] = []
    last = start_hz
    for m in modes:
        f = m.frequencies_hz
        ratio = np.abs(np.log(f / last)) if f.size else np.zeros(0)
        near = np.flatnonzero(ratio <= math.log(TRACK_RANGE))
        if near.size == 0:
            out.append(None)
            continue
        k = int(near[np.argmax(m.significance[near])])
        out.append(k)
        last = float(f[k])
    return out
