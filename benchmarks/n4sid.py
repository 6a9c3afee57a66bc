"""N4SID, the black box a control engineer fits instead of a beam model (the benchmark's yardstick).

Van Overschee and De Moor's combined deterministic–stochastic subspace identification ("Subspace Identification
for Linear Systems", 1996, algorithm 1 of chapter 4), the textbook steps:

1. block Hankel matrices of ``i`` block rows of the inputs and outputs, past ``p`` and future ``f``;
2. the oblique projections ``O_i = Y_f /_{U_f} W_p`` and ``O_{i−1} = Y_f⁻ /_{U_f⁻} W_p⁺`` (``W_p = [U_p; Y_p]``),
   as the ``W_p`` part of the least-squares regression of the future outputs on the past and the future inputs;
3. the SVD of ``O_i``: the extended observability matrix ``Γ_i = U₁ S₁^½`` of order ``n``, the states
   ``X_i = Γ_i^† O_i`` and ``X_{i+1} = Γ_{i−1}^† O_{i−1}``;
4. ``[A B; C D]`` by least squares from ``[X_{i+1}; Y_{i|i}] = [A B; C D] [X_i; U_{i|i}]``.

The model is simulated from the state its own regression estimated at sample ``i`` (:func:`simulate`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BlackBox", "n4sid", "simulate"]


@dataclass(frozen=True)
class BlackBox:
    """A discrete state-space model ``x⁺ = A x + B u``, ``y = C x + D u`` and its state at sample ``start``."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    x_start: np.ndarray
    start: int


def _hankel(w: np.ndarray, rows: int, cols: int, first: int = 0) -> np.ndarray:
    """Block Hankel matrix of ``rows`` block rows of ``w`` (samples × channels) from sample ``first``."""
    k = w.shape[1]
    H = np.empty((rows * k, cols))
    for r in range(rows):
        H[r * k:(r + 1) * k] = w[first + r:first + r + cols].T
    return H


def _oblique(Yf: np.ndarray, Uf: np.ndarray, Wp: np.ndarray) -> np.ndarray:
    """``Y_f /_{U_f} W_p``: the ``W_p`` part of the least-squares regression of ``Y_f`` on ``[W_p; U_f]``."""
    R = np.vstack([Wp, Uf])
    theta = np.linalg.lstsq(R.T, Yf.T, rcond=None)[0].T
    return theta[:, :Wp.shape[0]] @ Wp


def n4sid(u: np.ndarray, y: np.ndarray, order: int, block_rows: int) -> BlackBox:
    """The N4SID model of ``order`` from inputs ``u`` (samples × m) and outputs ``y`` (samples × l) with
    ``block_rows`` block rows (module docstring)."""
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    m, l, i = u.shape[1], y.shape[1], block_rows
    j = len(u) - 2 * i + 1
    U = _hankel(u, 2 * i, j)
    Y = _hankel(y, 2 * i, j)
    Up, Uf, Yp, Yf = U[:i * m], U[i * m:], Y[:i * l], Y[i * l:]
    # the shifted split: one block row more in the past
    Up1, Uf1, Yp1, Yf1 = U[:(i + 1) * m], U[(i + 1) * m:], Y[:(i + 1) * l], Y[(i + 1) * l:]
    Oi = _oblique(Yf, Uf, np.vstack([Up, Yp]))
    Oi1 = _oblique(Yf1, Uf1, np.vstack([Up1, Yp1]))
    Us, s, _ = np.linalg.svd(Oi, full_matrices=False)
    gamma = Us[:, :order] * np.sqrt(s[:order])
    Xi = np.linalg.pinv(gamma) @ Oi
    Xi1 = np.linalg.pinv(gamma[:-l]) @ Oi1
    lhs = np.vstack([Xi1, Yf[:l]])
    rhs = np.vstack([Xi, Uf[:m]])
    theta = np.linalg.lstsq(rhs.T, lhs.T, rcond=None)[0].T
    A, B = theta[:order, :order], theta[:order, order:]
    C, D = theta[order:, :order], theta[order:, order:]
    return BlackBox(A, B, C, D, Xi[:, 0], i)


def simulate(model: BlackBox, u: np.ndarray) -> np.ndarray:
    """Outputs for inputs ``u`` (samples × m) from the model's state at its ``start`` sample (the samples
    before it are returned as NaN)."""
    u = np.asarray(u, float).reshape(len(u), -1)
    x = model.x_start.copy()
    out = np.full((len(u), model.C.shape[0]), np.nan)
    for k in range(model.start, len(u)):
        out[k] = model.C @ x + model.D @ u[k]
        x = model.A @ x + model.B @ u[k]
    return out
