r"""Analytic natural frequencies of an axially loaded Euler–Bernoulli beam.

This module is an *independent truth* for the project's finite-difference
model: it never discretises the beam, it solves the exact characteristic
equations of the continuous problem.

Model
-----
Free vibration of the undamped beam

.. math::

    \rho A\, w_{tt} + EI\, w_{xxxx} - N\, w_{xx} = 0, \qquad 0 \le x \le L,

with a constant axial force :math:`N` (:math:`N > 0` tension, :math:`N < 0`
compression).  With :math:`w = W(\xi) e^{i\omega t}`, :math:`\xi = x/L`,

.. math::

    W'''' - U\, W'' - \Omega^2 W = 0, \qquad
    U = \frac{N L^2}{EI}, \qquad
    \Omega = \omega L^2 \sqrt{\rho A / EI}.

The characteristic roots :math:`s` satisfy :math:`s^4 - U s^2 - \Omega^2 = 0`,
i.e. :math:`s = \pm\alpha` and :math:`s = \pm i\beta` with

.. math::

    \alpha^2 - \beta^2 = U, \qquad \alpha\beta = \Omega, \qquad
    \alpha^2 = \tfrac12\bigl(U + \sqrt{U^2 + 4\Omega^2}\bigr), \qquad
    \beta^2 = \tfrac12\bigl(-U + \sqrt{U^2 + 4\Omega^2}\bigr),

both real for any real :math:`U` and :math:`\Omega > 0`, so that
:math:`W = A\cosh\alpha\xi + B\sinh\alpha\xi + C\cos\beta\xi + D\sin\beta\xi`.
The boundary conditions are

* clamped: :math:`W = W' = 0`,
* pinned:  :math:`W = W'' = 0`,
* free:    :math:`W'' = 0,\; W''' - U W' = 0` (zero bending moment and zero
  transverse shear force for an axial force of fixed direction).

The characteristic equations of the four pairs of ends and their scaling (pole-free, no overflow)
are :mod:`ebb_model.reference.characteristic`'s.

Numerical strategy
------------------
The roots are searched in the variable :math:`\beta` rather than
:math:`\Omega`.  Along the branch :math:`\beta \ge \beta_0 = \sqrt{\max(-U, 0)}`,
:math:`\alpha = \sqrt{\beta^2 + U}` and :math:`\Omega = \alpha\beta` grows
monotonically from 0, and consecutive eigenvalues are separated by roughly
:math:`\pi` in :math:`\beta` for *every* :math:`U` (string-like and beam-like
regimes alike), so a uniform grid of step :math:`\pi/128` cannot step over
a root.

The scaled functions (:mod:`~ebb_model.reference.characteristic`) are smooth and pole-free; sign changes on the grid are
refined with :func:`scipy.optimize.brentq`, and any bracket whose refined
residual is not small compared with the bracketing values (the signature of
a pole) is rejected.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from ..checks import finite_scalar
from ..errors import ParameterError
from .characteristic import CHARACTERISTIC, CharFun, alpha_from_beta, canonical_pair

__all__ = [
    "analytic_omegas",
    "analytic_frequencies_hz",
    "critical_buckling_U",
    "solve_characteristic",
    "U_MAX",
]

#: Largest nondimensional tension ``U = N L^2 / EI`` accepted.
U_MAX: float = 1.0e4


# Root scan step in beta (eigenvalues are ~pi apart in beta).
_BETA_STEP: float = math.pi / 128.0


# --------------------------------------------------------------------------
# root finding
# --------------------------------------------------------------------------
def _validate_U(U: float, U_cr: float) -> float:
    U = finite_scalar("U", U)
    if U <= -U_cr:
        raise ParameterError(
            f"U = {U:g} is at or beyond the critical buckling load -U_cr = {-U_cr:g}; "
            "the straight beam is unstable and has no real natural frequencies"
        )
    if U > U_MAX:
        raise ParameterError(f"U = {U:g} exceeds the supported maximum {U_MAX:g}")
    return U


def _validate_n_modes(n_modes: int) -> int:
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ParameterError(f"n_modes must be an integer >= 1, got {n_modes!r}")
    return int(n_modes)


def _roots_in_beta(g: CharFun, U: float, n_modes: int) -> np.ndarray:
    r"""First ``n_modes`` roots :math:`\beta_k > \beta_0` of ``g`` along the branch.

    Scans :math:`\beta \in [\beta_0, \infty)` on a grid of step
    :math:`\pi/128` in chunks, brackets sign changes, refines each with
    :func:`~scipy.optimize.brentq` and rejects brackets where the refined
    residual is not small compared with the end values (a pole, not a root).
    """
    beta0 = math.sqrt(max(-U, 0.0))
    step = _BETA_STEP
    per_chunk = 128 * (n_modes + 2)
    roots: list[float] = []

    def gs(b: float) -> float:
        return float(g(alpha_from_beta(np.float64(b), U), np.float64(b), U))

    # At U = 0 the point beta0 = 0 is a (double) trivial zero; for |U| tiny
    # its computed sign is round-off, so begin one step further: no
    # eigenvalue can lie that close to zero unless U is near -U_cr.
    start_index = 1 if abs(U) < 1e-6 else 0
    chunk = 0
    while len(roots) < n_modes:
        if chunk > 64:  # pragma: no cover - defensive
            raise RuntimeError("analytic root scan did not find enough roots")
        first = chunk * per_chunk + (start_index if chunk == 0 else 0)
        b = beta0 + step * np.arange(first, (chunk + 1) * per_chunk + 1)
        vals = g(alpha_from_beta(b, U), b, U)
        # brackets: strict sign changes, plus exact zeros on grid points
        candidates = np.flatnonzero((vals[:-1] == 0.0) | (vals[:-1] * vals[1:] < 0.0))
        for i in candidates:
            fa, fb = vals[i], vals[i + 1]
            if fa == 0.0:
                r = float(b[i])
            else:
                r = brentq(gs, b[i], b[i + 1], xtol=1e-15,
                           rtol=4.0 * np.finfo(float).eps, maxiter=200)
                if abs(gs(r)) > 1e-6 * max(abs(fa), abs(fb)) + 1e-13:
                    continue  # sign change through a pole, not a root
            if r <= beta0 or (roots and r <= roots[-1]):
                continue
            roots.append(r)
            if len(roots) >= n_modes:
                break
        chunk += 1
    return np.asarray(roots[:n_modes])


def solve_characteristic(left: str, right: str, U: float, n_modes: int) -> np.ndarray:
    r"""Solve the (scaled) characteristic equation numerically.

    Unlike :func:`analytic_omegas`, this uses root finding for *every*
    supported pair, including pinned–pinned (from its determinant
    :math:`\sinh\alpha\sin\beta = 0`), which makes it possible to validate the
    root finder against the closed form.

    Parameters
    ----------
    left, right
        Boundary conditions.
    U
        Nondimensional axial force, :math:`-U_{cr} < U \le 10^4`.
    n_modes
        Number of modes.

    Returns
    -------
    numpy.ndarray
        :math:`\Omega_1 < \dots < \Omega_n`.
    """
    pair = canonical_pair(left, right)
    U = _validate_U(U, critical_buckling_U(*pair))
    n_modes = _validate_n_modes(n_modes)
    beta = _roots_in_beta(CHARACTERISTIC[pair], U, n_modes)
    alpha = alpha_from_beta(beta, U)
    return alpha * beta


def analytic_omegas(left: str, right: str, U: float, n_modes: int) -> np.ndarray:
    r"""Nondimensional natural frequencies :math:`\Omega_1, \dots, \Omega_n`.

    Parameters
    ----------
    left, right
        Boundary conditions, ``"clamped"``, ``"pinned"`` or ``"free"``, in
        either order.  Supported pairs: pinned–pinned, clamped–clamped,
        clamped–pinned, clamped–free.
    U
        Nondimensional axial force :math:`U = N L^2/EI` (tension positive),
        :math:`-U_{cr} < U \le 10^4`.
    n_modes
        Number of modes wanted (>= 1).

    Returns
    -------
    numpy.ndarray
        Ascending :math:`\Omega_n = \omega_n L^2 \sqrt{\rho A / EI}`.

    Raises
    ------
    ValueError
        (:class:`~ebb_model.errors.ConfigError` /
        :class:`~ebb_model.errors.ParameterError`) for unknown or unsupported
        boundary conditions, ``U`` out of range, or bad ``n_modes``.

    Notes
    -----
    Pinned–pinned uses the closed form
    :math:`\Omega_n = n\pi\sqrt{n^2\pi^2 + U}`; the other pairs use
    :func:`solve_characteristic`.
    """
    pair = canonical_pair(left, right)
    U = _validate_U(U, critical_buckling_U(*pair))
    n_modes = _validate_n_modes(n_modes)
    if pair == ("pinned", "pinned"):
        npi = np.pi * np.arange(1, n_modes + 1)
        return npi * np.sqrt(npi * npi + U)
    return solve_characteristic(pair[0], pair[1], U, n_modes)


def analytic_frequencies_hz(
    left: str,
    right: str,
    *,
    length: float,
    EI: float,
    rhoA: float,
    N: float,
    n_modes: int,
) -> np.ndarray:
    r"""Natural frequencies in Hz of the dimensional beam.

    .. math::

        U = \frac{N L^2}{EI}, \qquad
        f_n = \frac{\Omega_n(U)}{2\pi L^2}\sqrt{\frac{EI}{\rho A}} .

    Parameters
    ----------
    left, right
        Boundary conditions (see :func:`analytic_omegas`).
    length
        Beam length :math:`L > 0` [m].
    EI
        Bending stiffness [N m^2], > 0.
    rhoA
        Mass per unit length [kg/m], > 0.
    N
        Axial force [N], tension positive.
    n_modes
        Number of modes.

    Returns
    -------
    numpy.ndarray
        Ascending frequencies in Hz.
    """
    for name, val in (("length", length), ("EI", EI), ("rhoA", rhoA)):
        finite_scalar(name, val, minimum=0.0, strict=True, numbers_only=True)
    finite_scalar("N", N)
    U = N * length**2 / EI
    Om = analytic_omegas(left, right, U, n_modes)
    return Om / (2.0 * np.pi * length**2) * math.sqrt(EI / rhoA)


def critical_buckling_U(left: str, right: str) -> float:
    r"""Critical nondimensional compression :math:`U_{cr} > 0`.

    The straight beam buckles at :math:`U = -U_{cr}` (i.e.
    :math:`N = -U_{cr} EI / L^2`), where :math:`\Omega_1 \to 0`.

    ============== =========================================
    pair           :math:`U_{cr}`
    ============== =========================================
    pinned–pinned  :math:`\pi^2`
    clamped–clamped :math:`4\pi^2`
    clamped–pinned :math:`\beta^2` with :math:`\tan\beta = \beta`,
                   :math:`\beta \approx 4.4934`, so :math:`\approx 20.19`
    clamped–free   :math:`\pi^2/4`
    ============== =========================================

    Raises
    ------
    ValueError
        For unknown/unsupported boundary conditions.
    """
    pair = canonical_pair(left, right)
    if pair == ("pinned", "pinned"):
        return math.pi**2
    if pair == ("clamped", "clamped"):
        return 4.0 * math.pi**2
    if pair == ("clamped", "free"):
        return math.pi**2 / 4.0
    # clamped-pinned: sin(b) - b cos(b) = 0 (pole-free tan b = b), first root > 0
    b = brentq(lambda t: math.sin(t) - t * math.cos(t), math.pi + 0.1, 1.5 * math.pi - 1e-9,
               xtol=1e-15, rtol=4.0 * np.finfo(float).eps)
    return b * b
