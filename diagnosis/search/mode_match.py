"""The measured modes matched to the model's: which model mode each measured one is, and the χ² of the match.

A measured set need not be the model's lowest modes in a row: a mode weakly excited or at a sensor's node is
missing from it.  Measured mode ``i`` is compared with model mode ``j(i)``, the increasing assignment of least
cost (:func:`matched`, by dynamic programming), and the match's χ² sums the normalised differences of frequency
and damping ratio (:func:`mode_cost`).  Both take one model mode set or a stack of them (the aligned starts of a
pattern fit cost 400 scalings of one set at once, :func:`diagnosis.search.pattern_starts.aligned`), each set of a
stack matched and costed exactly as alone.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .modal_estimate import MeasuredModes

__all__ = ["ModalEvidence", "compared", "matched", "mode_cost"]


@dataclass(frozen=True)
class ModalEvidence:
    """Measured modes and the uncertainty each comparison with the model allows
    (:func:`diagnosis.search.modal_pattern.modal_evidence`)."""

    measured: MeasuredModes
    freq_sigma: np.ndarray
    damping_sigma: np.ndarray

    @property
    def n_modes(self) -> int:
        """Number of compared modes."""
        return int(self.measured.freq_hz.size)


def matched(cost: np.ndarray) -> np.ndarray:
    """The model mode matched to each measured one: the increasing assignment (measured mode ``i`` to model mode
    ``j[..., i]``, ``j`` strictly increasing, model modes passed over allowed) of least total ``cost[..., i, j]``, by
    dynamic programming over the ``(measured, model)`` table — for one table or a stack of them at once."""
    m, n = cost.shape[-2:]
    total = np.full(cost.shape, np.inf)
    total[..., 0, :] = cost[..., 0, :]
    for i in range(1, m):
        before = np.minimum.accumulate(total[..., i - 1, :], axis=-1)      # best over model modes up to j
        total[..., i, 1:] = cost[..., i, 1:] + before[..., :-1]
    j = np.empty(cost.shape[:-1], dtype=int)
    if cost.ndim == 2:     # one table (a fit's every evaluation): scalar steps back are the faster
        j[-1] = int(np.argmin(total[-1]))
        for i in range(m - 1, 0, -1):
            j[i - 1] = int(np.argmin(total[i - 1, :j[i]]))
        return j
    j[..., -1] = np.argmin(total[..., -1, :], axis=-1)
    columns = np.arange(n)
    for i in range(m - 1, 0, -1):   # the least of the row over the model modes below the next one's match
        row = np.where(columns < j[..., i, None], total[..., i - 1, :], np.inf)
        j[..., i - 1] = np.argmin(row, axis=-1)
    return j


def compared(ev: ModalEvidence, f: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The model's modes ``(f, zeta)`` (more than measured; ``f`` one set or a stack of them, ``(..., n)``)
    matched to the measured ones (:func:`matched` on the squared normalised differences of frequency and
    damping)."""
    meas = ev.measured
    f = np.asarray(f)
    zeta = zeta if f.ndim == 1 else np.broadcast_to(zeta, f.shape)
    cost = (((f[..., None, :] - meas.freq_hz[:, None]) / ev.freq_sigma[:, None]) ** 2
            + ((zeta[..., None, :] - meas.damping[:, None]) / ev.damping_sigma[:, None]) ** 2)
    j = matched(cost)
    return (f[j], zeta[j]) if f.ndim == 1 else (np.take_along_axis(f, j, axis=-1), np.take_along_axis(zeta, j, axis=-1))


def mode_cost(ev: ModalEvidence, f: np.ndarray, zeta: np.ndarray) -> float | np.ndarray:
    """χ² of the model's modes ``(f, zeta)`` matched to the measured ones (:func:`compared`; for a stack of
    frequency sets ``f`` ``(k, n)``, the ``k`` values)."""
    fr, zr = compared(ev, f, zeta)
    chi2 = np.sum(((fr - ev.measured.freq_hz) / ev.freq_sigma) ** 2
                  + ((zr - ev.measured.damping) / ev.damping_sigma) ** 2, axis=-1)
    return float(chi2) if chi2.ndim == 0 else chi2
