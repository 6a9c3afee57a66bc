"""Time discretisation: the three-level θ-scheme as a discrete state-space system.

For ``M q'' + C q' + K q = F f`` and sub-step ``τ = dt / m`` (``m`` integer
sub-steps per sample), the scheme (Newmark-equivalent for ``θ = β``) is

.. math::

    M\\frac{q^{j+1} - 2q^j + q^{j-1}}{\\tau^2}
    + C\\frac{q^{j+1} - q^{j-1}}{2\\tau}
    + K\\left[\\theta q^{j+1} + (1-2\\theta) q^j + \\theta q^{j-1}\\right] = F f^j ,

unconditionally stable for ``θ ≥ 1/4`` (with non-negative damping), and for
``θ < 1/4`` stable when ``τ² ω_max² (1 - 4θ) ≤ 4``.  The force ``f^j`` is the
sample ``u[k]`` held (zero-order hold) over ``[t_k, t_{k+1})``.  Solving for
``q^{j+1}``:

.. math::

    q^{j+1} = A_1 q^j + A_2 q^{j-1} + B_1 f^j,\\quad
    L = \\tfrac{M}{\\tau^2} + \\tfrac{C}{2\\tau} + \\theta K,\\;
    A_1 = L^{-1}(\\tfrac{2M}{\\tau^2} - (1-2\\theta)K),\\;
    A_2 = L^{-1}(-\\tfrac{M}{\\tau^2} + \\tfrac{C}{2\\tau} - \\theta K),\\;
    B_1 = L^{-1}F .

With the state :math:`x[k] = (q^{mk}, q^{mk-1})` the one-step map is
:math:`S = \\begin{bmatrix}A_1 & A_2\\\\ I & 0\\end{bmatrix}`, ``G = [B_1; 0]``
and per sample :math:`\\Phi = S^m`, :math:`\\Gamma = \\sum_{l<m} S^l G`.

Outputs at ``t_k`` use the scheme's own central differences, so velocity and
acceleration sensors have direct feedthrough (``D ≠ 0``):

* displacement  ``y = P q^{mk}``
* velocity      ``y = P (q^{mk+1} - q^{mk-1}) / (2τ)``
* acceleration  ``y = P (q^{mk+1} - 2q^{mk} + q^{mk-1}) / τ²``

where ``P`` holds the sensors' interpolation weights and ``q^{mk+1}`` is
eliminated with the update formula.

References
----------
Talic, Schirrer, Kozek, Jakubek: identification of an Euler–Bernoulli beam
under axial load with a stabilising objective (TU Wien).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .discretisation import SemiDiscreteBeam
from .statespace import DiscreteStateSpace

__all__ = ["ThetaCoefficients", "theta_coefficients", "discretise_time", "output_matrices"]


class ThetaCoefficients:
    """The per-sub-step update ``q^{j+1} = A1 q^j + A2 q^{j-1} + B1 f^j``."""

    def __init__(self, A1: np.ndarray, A2: np.ndarray, B1: np.ndarray, tau: float):
        self.A1, self.A2, self.B1, self.tau = A1, A2, B1, tau


def theta_coefficients(beam: SemiDiscreteBeam, dt: float, theta: float, substeps: int = 1) -> ThetaCoefficients:
    """Solve the θ-scheme's implicit matrix once: returns ``A1, A2, B1`` and ``τ``."""
    tau = dt / substeps
    M, C, K = beam.M, beam.C, beam.K
    L = M / tau ** 2 + C / (2 * tau) + theta * K
    rhs = np.hstack([2 * M / tau ** 2 - (1 - 2 * theta) * K,
                     -M / tau ** 2 + C / (2 * tau) - theta * K,
                     beam.F])
    sol = sla.solve(L, rhs, assume_a="sym")
    n = M.shape[0]
    return ThetaCoefficients(sol[:, :n], sol[:, n:2 * n], sol[:, 2 * n:], tau)


def output_matrices(P: np.ndarray, kinds: tuple[str, ...], A1: np.ndarray, A2: np.ndarray,
                    B1: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Output matrices ``(C, D)`` on the state ``(q^j, q^{j-1})``.

    ``P`` has one row of interpolation weights per sensor; ``A1, A2, B1`` are
    the update matrices expressed in the same coordinates as the state
    (nodal unknowns or modal coordinates).
    """
    n = A1.shape[0]
    p = P.shape[0]
    C = np.zeros((p, 2 * n))
    D = np.zeros((p, B1.shape[1]))
    eye = np.eye(n)
    for i, kind in enumerate(kinds):
        row = P[i]
        if kind == "displacement":
            C[i, :n] = row
        elif kind == "velocity":
            C[i, :n] = row @ A1 / (2 * tau)
            C[i, n:] = row @ (A2 - eye) / (2 * tau)
            D[i] = row @ B1 / (2 * tau)
        elif kind == "acceleration":
            C[i, :n] = row @ (A1 - 2 * eye) / tau ** 2
            C[i, n:] = row @ (A2 + eye) / tau ** 2
            D[i] = row @ B1 / tau ** 2
        else:  # pragma: no cover - kinds are validated in the config
            raise ValueError(f"unknown sensor kind {kind!r}")
    return C, D


def discretise_time(beam: SemiDiscreteBeam, dt: float, theta: float = 0.25,
                    substeps: int = 1) -> DiscreteStateSpace:
    """The θ-scheme of ``beam`` as a dense discrete state-space system (Φ, Γ, C, D, dt).

    The state is ``x[k] = (q^{mk}, q^{mk-1})`` with nodal unknowns ``q``;
    state names are ``w(x=…)`` and ``w_prev(x=…)``.
    """
    co = theta_coefficients(beam, dt, theta, substeps)
    n = beam.n_unknowns
    S = np.zeros((2 * n, 2 * n))
    S[:n, :n] = co.A1
    S[:n, n:] = co.A2
    S[n:, :n] = np.eye(n)
    G = np.zeros((2 * n, beam.F.shape[1]))
    G[:n] = co.B1
    Phi, Gam = S, G
    for _ in range(substeps - 1):
        Gam = S @ Gam + G
        Phi = S @ Phi
    C, D = output_matrices(beam.S, beam.sensor_kinds, co.A1, co.A2, co.B1, co.tau)
    xs = beam.x[beam.unknown]
    names = tuple(f"w(x={v:.6g})" for v in xs) + tuple(f"w_prev(x={v:.6g})" for v in xs)
    return DiscreteStateSpace(Phi, Gam, C, D, dt, beam.input_names, beam.output_names, names)
