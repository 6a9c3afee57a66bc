r"""Compiled Newmark integrator on banded matrices, with lags, drift and stiffening.

Integrates the finite-element equations of motion

.. math::

    M\ddot q + C\dot q + \bigl(K + \Delta N(t, q)\, G\bigr) q = \Phi\, g(t),
    \qquad
    \Delta N(t, q) = r\,t + \tfrac{EA}{2L}\, q^T G q,

from rest, where :math:`G = \int N'^T N'\,dx` (so :math:`q^T G q = \int w_x^2`),
:math:`r` is the axial-load drift rate and :math:`EA` the axial stiffness of
mid-plane stretching (both zero: a linear time-invariant system).

Input.  The measured force :math:`u` is given at the sub-step nodes
:math:`t_j = j h`, :math:`h = \Delta t/\text{substeps}` (the caller
interpolates the samples), and taken linear between them.  The force the
beam feels is :math:`g = u` or, with an actuator lag :math:`\tau_a > 0`, the
solution of :math:`\tau_a \dot g + g = u`, :math:`g(0) = 0`, integrated
*exactly* for the piecewise-linear :math:`u` over each sub-step:

.. math::

    g_{n+1} = E g_n + (1 - E - c_1) u_n + c_1 u_{n+1},\quad
    E = e^{-h/\tau},\quad c_1 = 1 - \tfrac{\tau}{h}(1 - E).

Time stepping.  ``substeps`` Newmark steps (:math:`\beta = 1/4`,
:math:`\gamma = 1/2` by default: average acceleration, second order, no
numerical damping) per sample interval, written in the *acceleration form*
(well conditioned: no :math:`1/h^2` cancellation, so slow modes keep all
their digits even with many sub-steps): with the predictors
:math:`\tilde q = q_n + h\dot q_n + h^2(\tfrac12-\beta)\ddot q_n`,
:math:`\tilde v = \dot q_n + h(1-\gamma)\ddot q_n`, each step solves

.. math::

    \bigl(M + \gamma h C + \beta h^2 (K + \Delta N\, G)\bigr)\,\ddot q_{n+1}
    = \Phi g_{n+1} - C\tilde v - (K + \Delta N\, G)\,\tilde q,

    q_{n+1} = \tilde q + \beta h^2 \ddot q_{n+1},\qquad
    \dot q_{n+1} = \tilde v + \gamma h\, \ddot q_{n+1},

with a banded Cholesky factorisation (half-bandwidth 3 for cubic Hermite
elements): factorised once when :math:`\Delta N \equiv 0`, once per step for
the drift (:math:`\Delta N = r\,t_{n+1}`).  The stiffening is solved by a
Newton-type iteration whose tangent
:math:`M + \gamma h C + \beta h^2\bigl(K + \Delta N_0 G + \tfrac{EA}{L} (Gq)(Gq)^T\bigr)`
uses the banded factorisation at the predicted :math:`\Delta N_0` (once per
step) and the exact rank-one part through the Sherman–Morrison formula (two
banded solves per iteration); the residual is exact, so the iteration
converges to the exact Newmark solution (linearly, at the tiny rate
:math:`\beta h^2 |\Delta N - \Delta N_0|\,\|S^{-1}G\|`).  It stops when the
displacement correction :math:`\beta h^2 \|\delta\ddot q\|_\infty` is below
``tol`` times :math:`\|q_{n+1}\|_\infty`.

Sensor lag.  One sensor's true quantity (displacement, velocity or
acceleration at its position) is evaluated at every sub-step and passed
through :math:`1/(\tau_s s + 1)` with the same exact formula (the quantity
taken piecewise linear between sub-steps), starting from 0.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from ..errors import StabilityError

__all__ = ["to_band", "lag_coefficients", "newmark_banded"]

#: Half-bandwidth of the cubic-Hermite matrices (two DOFs per node, one element couples 4).
HALF_BANDWIDTH = 3


def to_band(A: np.ndarray, kd: int = HALF_BANDWIDTH) -> np.ndarray:
    """Lower band storage ``B[d, j] = A[j + d, j]`` of a symmetric banded matrix.

    Raises
    ------
    ValueError
        If ``A`` has non-zero entries outside the band or is not symmetric.
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    outside = np.abs(np.triu(A, kd + 1)).max(initial=0.0) + np.abs(np.tril(A, -kd - 1)).max(initial=0.0)
    if outside != 0.0:
        raise ValueError("matrix has entries outside the band")
    if not np.allclose(A, A.T, rtol=1e-13, atol=0.0):
        raise ValueError("matrix is not symmetric")
    B = np.zeros((kd + 1, n))
    for d in range(kd + 1):
        B[d, : n - d] = np.diagonal(A, -d)
    return B


def lag_coefficients(h: float, tau: float) -> tuple[float, float, float]:
    r"""Exact one-step coefficients ``(E, p, c1)`` of :math:`\tau\dot g + g = u` for piecewise-linear ``u``.

    ``g_{n+1} = E g_n + p u_n + c1 u_{n+1}``; ``tau = 0`` gives ``(0, 0, 1)``
    (no lag).
    """
    if tau == 0.0:
        return 0.0, 0.0, 1.0
    x = h / tau
    E = math.exp(-x)
    one_minus_E = -math.expm1(-x)
    if x < 1e-2:  # c1 = (x - 1 + e^{-x}) / x by its series, free of cancellation
        c1 = x / 2 - x * x / 6 + x**3 / 24 - x**4 / 120 + x**5 / 720
    else:
        c1 = 1.0 - one_minus_E / x
    return E, one_minus_E - c1, c1


# --------------------------------------------------------------------------
# compiled banded kernels
# --------------------------------------------------------------------------
@numba.njit(cache=True, nogil=True)
def _sym_band_matvec(B, x, y):  # pragma: no cover - compiled
    kd = B.shape[0] - 1
    n = x.shape[0]
    for i in range(n):
        y[i] = B[0, i] * x[i]
    for d in range(1, kd + 1):
        for j in range(n - d):
            b = B[d, j]
            y[j + d] += b * x[j]
            y[j] += b * x[j + d]


@numba.njit(cache=True, nogil=True)
def _band_cholesky(B, L):  # pragma: no cover - compiled
    """``L`` (lower band storage) with ``L L^T = A``; returns False if ``A`` is not positive definite."""
    kd = B.shape[0] - 1
    n = B.shape[1]
    for j in range(n):
        s = B[0, j]
        for d in range(1, min(kd, j) + 1):
            s -= L[d, j - d] * L[d, j - d]
        if not s > 0.0:
            return False
        ljj = math.sqrt(s)
        L[0, j] = ljj
        for d in range(1, kd + 1):
            i = j + d
            if i >= n:
                L[d, j] = 0.0
                continue
            s = B[d, j]
            for k in range(max(0, i - kd), j):
                s -= L[i - k, k] * L[j - k, k]
            L[d, j] = s / ljj
    return True


@numba.njit(cache=True, nogil=True)
def _band_cholesky_solve(L, b, x):  # pragma: no cover - compiled
    kd = L.shape[0] - 1
    n = b.shape[0]
    for j in range(n):
        s = b[j]
        for k in range(max(0, j - kd), j):
            s -= L[j - k, k] * x[k]
        x[j] = s / L[0, j]
    for j in range(n - 1, -1, -1):
        s = x[j]
        for i in range(j + 1, min(n, j + kd + 1)):
            s -= L[i - j, j] * x[i]
        x[j] = s / L[0, j]


@numba.njit(cache=True, nogil=True)
def _rank_one_correction(acc, z1, z, coef, qp, bh2, tol):  # pragma: no cover - compiled
    """Newton correction ``acc -= z1 - coef z`` (Sherman–Morrison solve of a rank-one tangent); True when the
    displacement correction ``bh2 |da|`` is below ``tol`` times the new displacement."""
    dmax = 0.0
    qmax = 0.0
    for r in range(acc.shape[0]):
        da = z1[r] - coef * z[r]
        acc[r] -= da
        dmax = max(dmax, abs(da))
        qmax = max(qmax, abs(qp[r] + bh2 * acc[r]))
    return bh2 * dmax <= tol * qmax


@numba.njit(cache=True, nogil=True)
def _kernel(Mb, Cb, Kb, Gb, Phi, rows, kinds, F, dt, m, beta, gamma, rate, ea_over_l,
            act_E, act_p, act_c1, lag_sensor, sen_E, sen_p, sen_c1, rloc, k3, fc, v0, kc, gap, tol, maxit,
            y):  # pragma: no cover
    n = Mb.shape[1]
    ni = F.shape[1]
    ns = (F.shape[0] - 1) // m + 1
    no = rows.shape[0]
    kdp1 = Mb.shape[0]
    h = dt / m
    bh2 = beta * h * h
    gh = gamma * h
    hb = h * h * (0.5 - beta)
    hg1 = h * (1.0 - gamma)
    lagged_force = act_E != 0.0 or act_p != 0.0 or act_c1 != 1.0
    nonlinear = ea_over_l != 0.0
    local = k3 != 0.0 or fc != 0.0 or kc != 0.0
    varying = nonlinear or rate != 0.0

    Sbase = Mb + gh * Cb + bh2 * Kb
    S = Sbase.copy()
    L = np.zeros((kdp1, n))
    q = np.zeros(n)
    v = np.zeros(n)
    acc = np.zeros(n)
    qp = np.zeros(n)
    vp = np.zeros(n)
    qt = np.zeros(n)
    rhs = np.zeros(n)
    res = np.zeros(n)
    tmp = np.zeros(n)
    w = np.zeros(n)
    z1 = np.zeros(n)
    z2 = np.zeros(n)
    g = np.zeros(ni)
    u0 = np.zeros(ni)
    u1 = np.zeros(ni)

    # initial state: at rest, force g(0) (0 with an actuator lag); M a = Phi g
    if not lagged_force:
        for i in range(ni):
            g[i] = F[0, i]
    for r in range(n):
        sacc = 0.0
        for i in range(ni):
            sacc += Phi[r, i] * g[i]
        rhs[r] = sacc
    if not _band_cholesky(Mb, L):
        return 1, 0, 0
    _band_cholesky_solve(L, rhs, acc)
    if not varying and not _band_cholesky(Sbase, L):
        return 2, 0, 0
    zr = np.zeros(n)     # S^-1 r of the local element (constant: S is)
    rzr = 0.0
    if local:
        _band_cholesky_solve(L, rloc, zr)
        for r in range(n):
            rzr += rloc[r] * zr[r]

    def sensor_value(o):
        sv = 0.0
        if kinds[o] == 0:
            for r in range(n):
                sv += rows[o, r] * q[r]
        elif kinds[o] == 1:
            for r in range(n):
                sv += rows[o, r] * v[r]
        else:
            for r in range(n):
                sv += rows[o, r] * acc[r]
        return sv

    n_iter = 0
    lag_state = 0.0
    lag_prev = 0.0
    if lag_sensor >= 0:
        lag_prev = sensor_value(lag_sensor)
    for o in range(no):
        y[0, o] = lag_state if o == lag_sensor else sensor_value(o)

    for k in range(ns - 1):
        for sub in range(m):
            s1 = (sub + 1) / m
            j = k * m + sub
            for i in range(ni):
                u0[i] = F[j, i]
                u1[i] = F[j + 1, i]
                if lagged_force:
                    g[i] = act_E * g[i] + act_p * u0[i] + act_c1 * u1[i]
                else:
                    g[i] = u1[i]
            # predictors
            for r in range(n):
                qp[r] = q[r] + h * v[r] + hb * acc[r]
                vp[r] = v[r] + hg1 * acc[r]
            # rhs = Phi g - C vp - K qp   (the axial part is added below)
            _sym_band_matvec(Cb, vp, rhs)
            _sym_band_matvec(Kb, qp, tmp)
            for r in range(n):
                sf = 0.0
                for i in range(ni):
                    sf += Phi[r, i] * g[i]
                rhs[r] = sf - rhs[r] - tmp[r]
            t1 = (k + s1) * dt
            if local:
                # Newton on a with the local element's force r f(xi, xi'), xi = r^T q, xi' = r^T v
                # (the stop's force is piecewise linear and monotone: Newton ends in a finite number of steps):
                # -R(a) = S a + r f - rhs; tangent S + (bh2 df/dxi + gh df/dxi') r r^T (Sherman-Morrison)
                converged = False
                for it in range(maxit):
                    xi = 0.0
                    xd = 0.0
                    for r in range(n):
                        xi += rloc[r] * (qp[r] + bh2 * acc[r])
                        xd += rloc[r] * (vp[r] + gh * acc[r])
                    th = math.tanh(xd / v0) if fc != 0.0 else 0.0
                    f = k3 * xi * xi * xi + fc * th
                    ct = bh2 * 3.0 * k3 * xi * xi + (gh * fc / v0 * (1.0 - th * th) if fc != 0.0 else 0.0)
                    if kc != 0.0 and xi > gap:
                        f += kc * (xi - gap)
                        ct += bh2 * kc
                    _sym_band_matvec(Sbase, acc, tmp)
                    for r in range(n):
                        res[r] = tmp[r] + f * rloc[r] - rhs[r]  # -R
                    _band_cholesky_solve(L, res, z1)
                    rz1 = 0.0
                    for r in range(n):
                        rz1 += rloc[r] * z1[r]
                    if _rank_one_correction(acc, z1, zr, ct * rz1 / (1.0 + ct * rzr), qp, bh2, tol):
                        converged = True
                        n_iter += it + 1
                        break
                if not converged:
                    return 5, k, n_iter
            elif not varying:
                _band_cholesky_solve(L, rhs, acc)
            elif not nonlinear:
                dn = rate * t1
                for d in range(kdp1):
                    for r in range(n):
                        S[d, r] = Sbase[d, r] + (bh2 * dn) * Gb[d, r]
                if not _band_cholesky(S, L):
                    return 3, k, n_iter
                _sym_band_matvec(Gb, qp, tmp)
                for r in range(n):
                    rhs[r] -= dn * tmp[r]
                _band_cholesky_solve(L, rhs, acc)
            else:
                # Newton-type iteration on the new acceleration a, q = qp + beta h^2 a:
                # -R(a) = (M + gh C + bh2 K) a + dN(q) G q - rhs,
                # dN(q) = rate t + EA/(2L) q^T G q.  The banded part of the
                # tangent is factorised once per step at the predicted dN; the
                # rank-one part bh2 EA/L (Gq)(Gq)^T is exact (Sherman-Morrison),
                # so the iteration contracts at the rate bh2 |dN - dN0| ||S^-1 G||.
                for r in range(n):
                    qt[r] = qp[r] + bh2 * acc[r]
                _sym_band_matvec(Gb, qt, w)
                quad = 0.0
                for r in range(n):
                    quad += qt[r] * w[r]
                dn0 = rate * t1 + 0.5 * ea_over_l * quad
                for d in range(kdp1):
                    for r in range(n):
                        S[d, r] = Sbase[d, r] + (bh2 * dn0) * Gb[d, r]
                if not _band_cholesky(S, L):
                    return 3, k, n_iter
                cb = bh2 * ea_over_l
                converged = False
                for it in range(maxit):
                    if it > 0:
                        for r in range(n):
                            qt[r] = qp[r] + bh2 * acc[r]
                        _sym_band_matvec(Gb, qt, w)
                        quad = 0.0
                        for r in range(n):
                            quad += qt[r] * w[r]
                    dn = rate * t1 + 0.5 * ea_over_l * quad
                    _sym_band_matvec(Sbase, acc, tmp)
                    for r in range(n):
                        res[r] = tmp[r] + dn * w[r] - rhs[r]  # -R
                    _band_cholesky_solve(L, res, z1)
                    _band_cholesky_solve(L, w, z2)
                    wz1 = 0.0
                    wz2 = 0.0
                    for r in range(n):
                        wz1 += w[r] * z1[r]
                        wz2 += w[r] * z2[r]
                    if _rank_one_correction(acc, z1, z2, cb * wz1 / (1.0 + cb * wz2), qp, bh2, tol):
                        converged = True
                        n_iter += it + 1
                        break
                if not converged:
                    return 4, k, n_iter
            for r in range(n):
                q[r] = qp[r] + bh2 * acc[r]
                v[r] = vp[r] + gh * acc[r]
            if lag_sensor >= 0:
                cur = sensor_value(lag_sensor)
                lag_state = sen_E * lag_state + sen_p * lag_prev + sen_c1 * cur
                lag_prev = cur
        for o in range(no):
            y[k + 1, o] = lag_state if o == lag_sensor else sensor_value(o)
    return 0, 0, n_iter


def newmark_banded(
    M: np.ndarray,
    C: np.ndarray,
    K: np.ndarray,
    G: np.ndarray,
    Phi: np.ndarray,
    rows: np.ndarray,
    kinds: np.ndarray,
    F: np.ndarray,
    dt: float,
    substeps: int,
    *,
    rate: float = 0.0,
    ea_over_l: float = 0.0,
    actuator_tau: float = 0.0,
    lag_sensor: int = -1,
    sensor_tau: float = 0.0,
    local_row: np.ndarray | None = None,
    k3: float = 0.0,
    friction: float = 0.0,
    slip_velocity: float = 1.0,
    stop_k: float = 0.0,
    stop_gap: float = 0.0,
    beta: float = 0.25,
    gamma: float = 0.5,
    tol: float = 1e-12,
    maxit: int = 50,
) -> np.ndarray:
    r"""Run the compiled integrator (see the module docstring); inputs are assumed validated.

    Parameters
    ----------
    M, C, K, G
        Symmetric banded ``n x n`` matrices: mass, damping, stiffness (with
        the constant axial force), ``∂K/∂N``.
    Phi
        ``n x n_inputs`` load vectors of the actuators.
    rows, kinds
        Output rows ``n_out x n`` and sensor kinds (0 displacement,
        1 velocity, 2 acceleration).
    F
        Measured force at the sub-step nodes :math:`t_j = j\,\Delta t/\text{substeps}`,
        shape ``((n_samples - 1) * substeps + 1, n_inputs)``.
    dt, substeps
        Sample interval and Newmark steps per interval.
    rate, ea_over_l
        Axial-load drift rate [N/s] and :math:`EA/L` [N/m] of the stiffening.
    actuator_tau, lag_sensor, sensor_tau
        Actuator lag [s]; index of the lagged sensor (-1: none) and its lag [s].
    local_row, k3, friction, slip_velocity, stop_k, stop_gap
        A local nonlinear element on the coordinate :math:`\xi = r^T q` (``local_row`` ``r``, e.g. the
        displacement at a point): force :math:`r\,(k_3 \xi^3 + F_c \tanh(\dot\xi / v_0) + k\max(\xi - g, 0))` —
        a grounded cubic spring, a (regularised) dry-friction contact and a one-sided stop of stiffness ``k``
        a gap ``g`` away.  Not combined with drift or stiffening.
    beta, gamma
        Newmark parameters.
    tol, maxit
        Newton tolerance and iteration limit (stiffening and the local element).

    Returns
    -------
    numpy.ndarray
        Outputs ``n_samples x n_out`` at the sample instants.

    Raises
    ------
    StabilityError
        Mass or effective matrix not positive definite (e.g. beam buckled by
        a compressive drift), or Newton not converged.
    """
    h = dt / substeps
    aE, ap, ac = lag_coefficients(h, actuator_tau)
    sE, sp, sc = lag_coefficients(h, sensor_tau) if lag_sensor >= 0 else (0.0, 0.0, 1.0)
    F = np.ascontiguousarray(F, dtype=float)
    if (F.shape[0] - 1) % substeps != 0:
        raise ValueError("F must have (n_samples - 1) * substeps + 1 rows")
    y = np.empty(((F.shape[0] - 1) // substeps + 1, rows.shape[0]))
    rloc = np.zeros(M.shape[0]) if local_row is None else np.ascontiguousarray(local_row, dtype=float)
    if (k3 != 0.0 or friction != 0.0 or stop_k != 0.0) and (rate != 0.0 or ea_over_l != 0.0):
        raise ValueError("the local nonlinear element is not combined with drift or stiffening")
    if not slip_velocity > 0.0:
        raise ValueError("slip_velocity must be > 0")
    status, k, _n_iter = _kernel(
        to_band(M), to_band(C), to_band(K), to_band(G),
        np.ascontiguousarray(Phi, dtype=float), np.ascontiguousarray(rows, dtype=float),
        np.ascontiguousarray(kinds, dtype=np.int64), F, float(dt), int(substeps), float(beta), float(gamma),
        float(rate), float(ea_over_l), aE, ap, ac, int(lag_sensor), sE, sp, sc, rloc, float(k3), float(friction),
        float(slip_velocity), float(stop_k), float(stop_gap), float(tol), int(maxit), y,
    )
    if status == 1:
        raise StabilityError("mass matrix is not positive definite")
    if status == 2:
        raise StabilityError("Newmark effective matrix is not positive definite (buckled beam?)")
    if status == 3:
        raise StabilityError(
            f"Newmark effective matrix lost positive definiteness at t = {k * dt:.6g} s "
            "(axial load beyond buckling?)"
        )
    if status == 4:
        raise StabilityError(
            f"geometric stiffening: Newton iteration did not converge at t = {k * dt:.6g} s "
            "(response too large for the time step; increase substeps)"
        )
    if status == 5:
        raise StabilityError(
            f"local nonlinear element: Newton iteration did not converge at t = {k * dt:.6g} s "
            "(increase substeps or the slip velocity)"
        )
    return y
