r"""Exact-in-time response of the Hermite finite-element beam: the truth for lightly damped records.

Newmark accelerations (and forces taken as linear between *samples*) are not converged enough to judge a
model on a lightly damped accelerometer record: there a mode 0.2 % off in frequency is hundreds of noise
variances.  This integrator has no time-step error of its own:

* the force between samples is a cubic interpolating spline through the samples (a smooth band-limited
  force has no kinks; see :mod:`ebb_model.reference.synthetic`): a cubic polynomial on each sample interval,
  continuous with its first two derivatives at the samples;
* the first-order system ``ẋ = A x + B f`` of :class:`~ebb_model.reference.hermite_fe.HermiteBeam`
  (``x = (q, q̇)``, any damping, optional lag states) is diagonalised once in continuous time and each
  eigen-coordinate advanced over a sample interval by the exponential of its eigenvalue augmented with the
  force's chain of derivatives (the third derivative constant on the interval), i.e. exactly for the spline.
  Taking the force as linear on a sub-grid instead leaves kinks that ring the mesh's lightly damped top modes:
  the accelerations then change with the mesh;
* each eigen-coordinate is then a first-order recursion run through :func:`scipy.signal.lfilter`, so a record
  costs little more than its modes.

Outputs at the samples: displacement ``φ(x)ᵀ q``, velocity ``φ(x)ᵀ q̇``, acceleration
``φ(x)ᵀ M⁻¹ (F f − C q̇ − K q)`` — exact for the finite-element model.  It shares no code with the
identifying finite-difference model (nor with :mod:`ebb_model.exact.exact_modal`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss
from scipy.interpolate import CubicSpline

from ..arrays import as_matrix
from ..errors import DataError
from .hermite_fe import SENSOR_KINDS, HermiteBeam

__all__ = ["exact_fe_response", "force_polynomials", "periodic_fe_response"]


def force_polynomials(inputs: np.ndarray, interpolation: str = "cubic") -> np.ndarray:
    """The force between samples as one polynomial per sample interval: ``(n − 1, 4, m)``.

    Row ``k`` holds the force and its first three derivatives at the start of interval ``k``, derivatives
    taken per *sample* (``d/dk``): ``interpolation="cubic"`` is the not-a-knot cubic spline through the
    samples (continuous with its first two derivatives), ``"linear"`` the straight lines between them.
    """
    u = np.asarray(inputs, dtype=float)
    n, m = u.shape
    d = np.zeros((n - 1, 4, m))
    d[:, 0] = u[:-1]
    if interpolation == "linear" or n < 4:
        d[:, 1] = np.diff(u, axis=0)
        return d
    if interpolation != "cubic":
        raise DataError(f"interpolation must be 'cubic' or 'linear', got {interpolation!r}")
    c = CubicSpline(np.arange(n, dtype=float), u, axis=0).c      # (4, n − 1, m), highest power first
    d[:, 1], d[:, 2], d[:, 3] = c[2], 2.0 * c[1], 6.0 * c[0]
    return d


def exact_fe_response(beam: HermiteBeam, inputs: np.ndarray, dt: float, actuators: Sequence[float],
                      sensors: Sequence[tuple[float, str]], *,
                      interpolation: str = "cubic", actuator_tau: float = 0.0, lag_sensor: int = -1,
                      sensor_tau: float = 0.0, filters: Sequence[tuple[int, float] | None] = ()) -> np.ndarray:
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
    interpolation
        Force between samples: ``"cubic"`` spline (default) or ``"linear"``.
    actuator_tau
        Time constant [s] of a first-order lag between the measured and the applied forces (0: none);
        the lagged forces are extra states, integrated exactly with the beam.
    lag_sensor, sensor_tau
        Index of a sensor whose quantity reaches the output through a first-order lag of time constant
        ``sensor_tau`` [s] (``-1``: none); one extra state.
    filters
        Per sensor, ``(order, corner [Hz])`` of the acquisition's analog Butterworth low-pass on its channel, or
        ``None`` (missing entries: none): scipy's realisation in series after the sensor's quantity, its states
        integrated exactly with the beam.
    """
    u = as_matrix(inputs, "inputs", shape=(None, len(actuators)), finite=False, column="actuator")
    n, m = u.shape
    nf = beam.M.shape[0]
    F = np.column_stack([beam.load_vector(a) for a in actuators])
    Minv_K = np.linalg.solve(beam.M, beam.K)
    Minv_C = np.linalg.solve(beam.M, beam.C)
    Minv_F = np.linalg.solve(beam.M, F)
    # beam state (q, q̇), then the lagged forces
    n_act = m if actuator_tau > 0 else 0
    ns = 2 * nf + n_act
    A = np.zeros((ns, ns))
    B = np.zeros((ns, m))
    A[:nf, nf:2 * nf] = np.eye(nf)
    A[nf:2 * nf, :nf], A[nf:2 * nf, nf:2 * nf] = -Minv_K, -Minv_C
    if n_act:                                   # ḟ_a = (f − f_a)/τ_a, the beam feels f_a
        A[nf:2 * nf, 2 * nf:] = Minv_F
        A[2 * nf:, 2 * nf:] = -np.eye(m) / actuator_tau
        B[2 * nf:] = np.eye(m) / actuator_tau
    else:
        B[nf:2 * nf] = Minv_F
    rows = np.array([beam.displacement_row(x) for x, _ in sensors])
    C = np.zeros((len(sensors), ns))
    D = np.zeros((len(sensors), m))
    for j, (_, kind) in enumerate(sensors):
        if kind not in SENSOR_KINDS:
            raise DataError(f"unknown sensor kind {kind!r}; allowed: {', '.join(SENSOR_KINDS)}")
        if kind == "displacement":
            C[j, :nf] = rows[j]
        elif kind == "velocity":
            C[j, nf:2 * nf] = rows[j]
        else:                                   # q̈ = A[nf:2nf] x + B[nf:2nf] f
            C[j] = rows[j] @ A[nf:2 * nf]
            D[j] = rows[j] @ B[nf:2 * nf]
    d = force_polynomials(u, interpolation)
    y = _integrate_exact(A, B, d, dt).T @ C.T + u @ D.T
    if lag_sensor >= 0 and sensor_tau > 0:     # one more state ẏ_l = (C_j x + D_j f − y_l)/τ_s, in its own run
        j = lag_sensor                          # (so that the other sensors stay bit-identical)
        Al = np.zeros((ns + 1, ns + 1))
        Al[:ns, :ns] = A
        Al[ns, :ns], Al[ns, ns] = C[j] / sensor_tau, -1.0 / sensor_tau
        Bl = np.vstack([B, D[j][None, :] / sensor_tau])
        y[:, j] = _integrate_exact(Al, Bl, d, dt)[ns]
    for j, spec in enumerate(filters):          # the channel's anti-alias filter after everything else
        if spec is None:
            continue
        order, corner = spec
        Af, Bf, Cf = _butterworth(int(order), float(corner))
        Cj, Dj = C[j], D[j]
        if j == lag_sensor and sensor_tau > 0:  # the lag's state first, then the filter
            Cj, Dj = np.append(np.zeros(ns), 1.0), np.zeros(m)
            Ab = np.zeros((ns + 1, ns + 1))
            Ab[:ns, :ns] = A
            Ab[ns, :ns], Ab[ns, ns] = C[j] / sensor_tau, -1.0 / sensor_tau
            Bb = np.vstack([B, D[j][None, :] / sensor_tau])
        else:
            Ab, Bb = A, B
        nb, nf_ = Ab.shape[0], Af.shape[0]
        Aa = np.zeros((nb + nf_, nb + nf_))
        Aa[:nb, :nb], Aa[nb:, nb:], Aa[nb:, :nb] = Ab, Af, Bf @ Cj[None, :]
        Ba = np.vstack([Bb, Bf @ Dj[None, :]])
        y[:, j] = (Cf @ _integrate_exact(Aa, Ba, d, dt)[nb:]).ravel()
    return y


def periodic_fe_response(beam: HermiteBeam, inputs: np.ndarray, dt: float, actuator: float,
                         sensors: Sequence[tuple[float, str]]) -> np.ndarray:
    """The periodic steady state (n, n_sensors) of ``beam`` under a force periodic over the record, bin by bin.

    ``inputs`` (n,) are the samples of one period of a force band-limited below the Nyquist frequency (a
    random-phase multisine on the record's DFT grid, :func:`~ebb_model.reference.excitation.band_limited_input`
    with ``fade = 0``): it is then that one continuous signal, and each DFT bin's response is the finite-element
    beam's frequency response there, ``(K + iωC − ω²M) q = F U`` — no time stepping, so no time-step error and
    no assumption about the force between samples (the truth for :mod:`ebb_model.acquisition.bandlimited`).
    """
    u = np.asarray(inputs, dtype=float).reshape(-1)
    U = np.fft.rfft(u)
    w = 2.0 * np.pi * np.fft.rfftfreq(u.size, dt)
    F = beam.load_vector(actuator)
    rows = np.array([beam.displacement_row(x) for x, _ in sensors])
    factor = {"displacement": lambda wi: 1.0, "velocity": lambda wi: 1j * wi, "acceleration": lambda wi: -wi * wi}
    for _, kind in sensors:
        if kind not in SENSOR_KINDS:
            raise DataError(f"unknown sensor kind {kind!r}; allowed: {', '.join(SENSOR_KINDS)}")
    Y = np.zeros((w.size, rows.shape[0]), dtype=complex)
    for i in np.flatnonzero(np.abs(U) > 0):
        q = np.linalg.solve(beam.K + 1j * w[i] * beam.C - w[i] ** 2 * beam.M, F) * U[i]
        Y[i] = np.array([factor[kind](w[i]) for _, kind in sensors]) * (rows @ q)
    return np.fft.irfft(Y, u.size, axis=0)


def _butterworth(order: int, corner: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C)`` of the analog Butterworth low-pass (scipy's poles and gain), as a cascade of unit-DC-gain
    sections on scaled states: ``ω²/(s² + 2σs + ω²)`` on ``(y, ẏ/ω)``, ``a/(s + a)`` on ``y``."""
    _, poles, _ = ss.butter(order, 2.0 * np.pi * corner, analog=True, output="zpk")
    sections = []
    for p in poles[np.imag(poles) >= 0]:
        if p.imag > 0:
            w, sig = abs(p), -p.real
            sections.append((np.array([[0.0, w], [-w, -2.0 * sig]]), np.array([0.0, w]), np.array([1.0, 0.0])))
        else:
            sections.append((np.array([[p.real]]), np.array([-p.real]), np.array([1.0])))
    n = order
    A, B, C = np.zeros((n, n)), np.zeros((n, 1)), np.zeros((1, n))
    at, prev = 0, None
    for As, bs, cs in sections:                 # each section driven by the previous one's output
        k = As.shape[0]
        A[at:at + k, at:at + k] = As
        if prev is None:
            B[at:at + k, 0] = bs
        else:
            A[at:at + k, prev[0]:prev[0] + prev[1].size] = np.outer(bs, prev[1])
        prev = (at, cs)
        at += k
    assert prev is not None
    C[0, prev[0]:prev[0] + prev[1].size] = prev[1]
    return A, B, C


def _sample_weights(z: np.ndarray) -> np.ndarray:
    """``(e^z, φ₁(z), …, φ₄(z))`` for each ``z`` (``(k, 5)``): the top row of the exponential of ``z`` augmented
    with the chain of a cubic's derivatives, ``φ_j(z) = ∫₀¹ e^{(1−τ) z} τ^{j−1}/(j−1)! dτ`` — the response of
    ``ż = z z + f`` over one unit interval to ``f = τ^{j−1}/(j−1)!``."""
    aug = np.zeros((z.size, 5, 5), dtype=complex)
    aug[:, 0, 0] = z
    for j in range(4):
        aug[:, j, j + 1] = 1.0
    return sla.expm(aug)[:, 0, :]


def _integrate_exact(A: np.ndarray, B: np.ndarray, d: np.ndarray, dt: float) -> np.ndarray:
    """States (n_states, n) at the samples of ``ẋ = A x + B f`` from rest, ``f`` a cubic per sample interval.

    ``d`` (n − 1, 4, m) holds the force and its derivatives (per sample) at the start of each interval
    (:func:`force_polynomials`).  ``A`` (balanced) is diagonalised in continuous time and each eigen-coordinate
    advanced over a sample exactly (:func:`_sample_weights`) as a first-order recursion
    (:func:`scipy.signal.lfilter`).  Diagonalising the one-sample map ``e^{A dt}`` instead loses the truth as the
    mesh is refined: the modes above the Nyquist frequency fold its eigenvalues onto the unit circle ever more
    densely, and the eigenvectors of that non-normal map grow ill-conditioned (a lightly damped cantilever's
    accelerometer record: 64→128 elements 0.003 noise variances apart, 128→256 7–15, 256→512 130–290 on the
    one-sample map; 3e-4, 1e-5 and 0.03 here, the last the stiffness matrix's round-off, condition ∝ n⁴).
    """
    ns, m = B.shape
    Ab, (scale, _) = sla.matrix_balance(A, permute=False, separate=True)
    lam, Vb = np.linalg.eig(Ab)
    weights = _sample_weights(lam * dt)
    Wb = np.linalg.solve(Vb, B / scale[:, None])          # the force's entry into each eigen-coordinate
    Wg = (dt * weights[:, 1:, None] * Wb[:, None, :]).reshape(ns, 4 * m)
    n = d.shape[0] + 1
    Z = np.zeros((ns, n), dtype=complex)                  # sample 0: at rest
    drive = d.reshape(n - 1, 4 * m) @ Wg.T                # (n − 1, ns)
    for i in range(ns):                                   # z_{k+1} = e^{λ dt} z_k + W d_k
        Z[i, 1:] = ss.lfilter([1.0], [1.0, -weights[i, 0]], drive[:, i])
    return ((Vb * scale[:, None]) @ Z).real
