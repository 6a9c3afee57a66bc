r"""Exact-in-time response of the Hermite finite-element beam: the truth for lightly damped records.

Newmark accelerations (and forces taken as linear between *samples*) are not converged enough to judge a
model on a lightly damped accelerometer record: there a mode 0.2 % off in frequency is hundreds of noise
variances.  This integrator has no time-step error of its own:

* the force between samples is a cubic interpolating spline through the samples (a smooth band-limited
  force has no kinks; see :mod:`ebb_model.reference.synthetic`), evaluated on a sub-grid of ``substeps``
  points per sample and taken as linear on each sub-interval (error ``O((dt/substeps)²)`` in the force only);
* the first-order system ``ẋ = A x + B f`` of :class:`~ebb_model.reference.hermite_fe.HermiteBeam`
  (``x = (q, q̇)``, any damping) is advanced over a sub-interval by the matrix exponential of the augmented
  matrix ``[[A τ, B τ, 0], [0, 0, I], [0, 0, 0]]`` (:func:`scipy.linalg.expm`), i.e. exactly for a force
  linear on the sub-interval;
* that one-sub-step map is diagonalised once and each eigen-coordinate is run through
  :func:`scipy.signal.lfilter` (a first-order recursion), so a record costs little more than its modes.

Outputs at the samples: displacement ``φ(x)ᵀ q``, velocity ``φ(x)ᵀ q̇``, acceleration
``φ(x)ᵀ M⁻¹ (F f − C q̇ − K q)`` — exact for the finite-element model.  It shares no code with the
identifying finite-difference model (nor with :mod:`ebb_model.exact_modal`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss
from scipy.interpolate import CubicSpline

from ..errors import DataError
from .hermite_fe import SENSOR_KINDS, HermiteBeam

__all__ = ["exact_fe_response", "force_on_subgrid"]


def force_on_subgrid(inputs: np.ndarray, substeps: int, interpolation: str = "cubic") -> np.ndarray:
    """The measured force samples (n, m) reconstructed at ``substeps`` points per sample: ``(n − 1)·s + 1`` rows.

    ``interpolation``: ``"cubic"`` (not-a-knot cubic spline through the samples) or ``"linear"``.
    """
    u = np.asarray(inputs, dtype=float)
    n = u.shape[0]
    t = np.arange(n, dtype=float)
    tt = np.arange((n - 1) * substeps + 1, dtype=float) / substeps
    if interpolation == "linear" or n < 4:
        return np.column_stack([np.interp(tt, t, u[:, j]) for j in range(u.shape[1])])
    if interpolation != "cubic":
        raise DataError(f"interpolation must be 'cubic' or 'linear', got {interpolation!r}")
    return CubicSpline(t, u, axis=0)(tt)


def exact_fe_response(beam: HermiteBeam, inputs: np.ndarray, dt: float, actuators: Sequence[float],
                      sensors: Sequence[tuple[float, str]], *, substeps: int = 16,
                      interpolation: str = "cubic") -> np.ndarray:
    """Outputs (n_samples, n_sensors) of ``beam`` at ``t_k = k dt``, starting at rest.

    Parameters
    ----------
    beam
        The finite-element beam (free DOFs).
    inputs
        Force samples (n_samples, n_actuators) [N]; the record should start at zero force.
    dt
        Sample interval [s].
    actuators
        Position of each force [m].
    sensors
        ``(position, kind)`` of each output, kind in displacement, velocity, acceleration.
    substeps
        Sub-intervals per sample on which the reconstructed force is linear.
    interpolation
        Force between samples: ``"cubic"`` spline (default) or ``"linear"``.
    """
    u = np.atleast_2d(np.asarray(inputs, dtype=float).T).T
    n, m = u.shape
    if m != len(actuators):
        raise DataError(f"inputs have {m} columns, expected one per actuator ({len(actuators)})")
    nf = beam.M.shape[0]
    F = np.column_stack([beam.load_vector(a) for a in actuators])
    Minv_K = np.linalg.solve(beam.M, beam.K)
    Minv_C = np.linalg.solve(beam.M, beam.C)
    Minv_F = np.linalg.solve(beam.M, F)
    A = np.block([[np.zeros((nf, nf)), np.eye(nf)], [-Minv_K, -Minv_C]])
    B = np.vstack([np.zeros((nf, m)), Minv_F])
    tau = dt / substeps
    ns = 2 * nf
    aug = np.zeros((ns + 2 * m, ns + 2 * m))
    aug[:ns, :ns] = A * tau
    aug[:ns, ns:ns + m] = B * tau
    aug[ns:ns + m, ns + m:] = np.eye(m)
    E = sla.expm(aug)
    Phi = E[:ns, :ns]
    g_delta = E[:ns, ns + m:]                   # coefficient of f(t_{j+1}) − f(t_j)
    g0, g1 = E[:ns, ns:ns + m] - g_delta, g_delta
    lam, V = np.linalg.eig(Phi)
    W0 = np.linalg.solve(V, g0)
    W1 = np.linalg.solve(V, g1)
    f = force_on_subgrid(u, substeps, interpolation)
    f = np.vstack([np.zeros((1, m)), f])        # at rest before the first sample
    idx = np.arange(n) * substeps + 1           # sample k sits at sub-grid row k·s + 1
    Z = np.empty((lam.size, n), dtype=complex)
    for i in range(lam.size):                   # z_{j+1} = λ z_j + W0 f_j + W1 f_{j+1}
        drive = f @ W1[i] + np.concatenate([[0.0], f[:-1] @ W0[i]])
        Z[i] = ss.lfilter([1.0], [1.0, -lam[i]], drive)[idx]
    X = (V @ Z).real                            # states (q, q̇) at the samples, (2 nf, n)
    rows = np.array([beam.displacement_row(x) for x, _ in sensors])
    y = np.empty((n, len(sensors)))
    for j, (_, kind) in enumerate(sensors):
        if kind not in SENSOR_KINDS:
            raise DataError(f"unknown sensor kind {kind!r}; allowed: {', '.join(SENSOR_KINDS)}")
        if kind == "displacement":
            y[:, j] = rows[j] @ X[:nf]
        elif kind == "velocity":
            y[:, j] = rows[j] @ X[nf:]
        else:
            acc = -Minv_K @ X[:nf] - Minv_C @ X[nf:] + Minv_F @ u.T
            y[:, j] = rows[j] @ acc
    return y
