r"""Time discretisation: the three-level θ-scheme as a discrete state-space system.

For ``M q'' + C q' + K q = F f`` and sub-step ``τ = dt / m`` (``m`` integer
sub-steps per sample), the scheme (Newmark-equivalent for ``θ = β``) is

.. math::

    M\frac{q^{j+1} - 2q^j + q^{j-1}}{\tau^2}
    + C\frac{q^{j+1} - q^{j-1}}{2\tau}
    + K\left[\theta q^{j+1} + (1-2\theta) q^j + \theta q^{j-1}\right] = F f^j ,

unconditionally stable for ``θ ≥ 1/4`` (with non-negative damping), and for
``θ < 1/4`` stable when ``τ² ω_max² (1 - 4θ) ≤ 4``.

Input between samples
---------------------
The scheme collocates the force at the levels ``t_j``.  At a sample instant
(``j = mk``) it is the sample ``u[k]``; at the sub-step levels in between it is
either the straight line between ``u[k]`` and ``u[k+1]`` (first-order hold,
``input_hold="foh"``, the default: measured forces are samples of continuous
signals) or ``u[k]`` held (zero-order hold, ``"zoh"``: a force commanded
through a hold device).  With one sub-step both coincide.  For the
first-order hold the per-sample recursion ``x[k+1] = Φ x[k] + Γ₀ u[k] + Γ₁ u[k+1]``
is made causal with the state ``ξ[k] = x[k] − Γ₁ u[k]`` (the standard FOH
realisation): ``ξ[k+1] = Φ ξ[k] + (Γ₀ + ΦΓ₁) u[k]``, ``y = C ξ + (D + CΓ₁) u``.

State
-----
The textbook state ``(q^j, q^{j-1})`` stores a low mode's dynamics in the
``O(ω²τ²)`` deviation of the update matrices from ``2I`` and ``-I`` (≈1e-7 for
a beam's first mode at 10 kHz), which costs ~9 digits.  The *same scheme* is
therefore written for the better conditioned state
``x = (q^j, v^{j-1/2})`` with ``v^{j-1/2} = (q^j - q^{j-1})/τ``:

.. math::

    L' = \tfrac{M}{\tau} + \tfrac{C}{2} + \theta\tau K,\quad
    \tilde K = L'^{-1}K,\; \tilde C = L'^{-1}C,\; \tilde B = L'^{-1}F,

    v^{j+1/2} = (I - \tilde C)\,v^{j-1/2} - \tilde K q^j + \tilde B f^j,\qquad
    q^{j+1} = q^j + \tau v^{j+1/2},

i.e. the one-step map
:math:`S = \begin{bmatrix} I - \tau\tilde K & \tau(I - \tilde C)\\ -\tilde K & I - \tilde C\end{bmatrix}`,
``G = [τ B̃; B̃]``, and per sample :math:`\Phi = S^m`, :math:`\Gamma = \sum_{l<m} S^l G`.
It is algebraically identical to the three-level form (same growth factors).

Outputs at ``t_k`` use the scheme's own central differences, so velocity and
acceleration sensors have direct feedthrough (``D ≠ 0``):

* displacement  ``y = P q^j``
* velocity      ``y = P (q^{j+1} - q^{j-1}) / (2τ) = P (v^{j+1/2} + v^{j-1/2}) / 2``
* acceleration  ``y = P (q^{j+1} - 2q^j + q^{j-1}) / τ² = P (v^{j+1/2} - v^{j-1/2}) / τ``

where ``P`` holds the sensors' interpolation weights and ``j = mk``.

References
----------
Talic, Schirrer, Kozek, Jakubek: identification of an Euler–Bernoulli beam
under axial load with a stabilising objective (TU Wien).
"""
from __future__ import annotations

import numpy as np

from ..space.discretisation import SemiDiscreteBeam
from ..statespace import DiscreteStateSpace

__all__ = ["ThetaCoefficients", "theta_coefficients", "discretise_time", "output_matrices", "one_step",
           "hold_matrices", "causal_hold"]


class ThetaCoefficients:
    """The per-sub-step matrices ``K̃ = L'^{-1}K``, ``C̃ = L'^{-1}C``, ``B̃ = L'^{-1}F`` and ``τ``."""

    def __init__(self, Kt: np.ndarray, Ct: np.ndarray, Bt: np.ndarray, tau: float):
        self.Kt, self.Ct, self.Bt, self.tau = Kt, Ct, Bt, tau


def theta_coefficients(beam: SemiDiscreteBeam, dt: float, theta: float, substeps: int = 1) -> ThetaCoefficients:
    """Factorise the θ-scheme's implicit matrix ``L'`` once and return ``K̃, C̃, B̃, τ``."""
    import scipy.linalg as sla     # here: an FMU whose model needs none of scipy starts without it
    tau = dt / substeps
    M, C, K = beam.M, beam.C, beam.K
    L = M / tau + C / 2 + (theta * tau) * K
    sol = sla.solve(L, np.hstack([K, C, beam.F]), assume_a="sym")
    n = M.shape[0]
    return ThetaCoefficients(sol[:, :n], sol[:, n:2 * n], sol[:, 2 * n:], tau)


def one_step(Kt: np.ndarray, Ct: np.ndarray, Bt: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sub-step map ``S`` and input matrix ``G`` on the state ``(q^j, v^{j-1/2})``."""
    n = Kt.shape[0]
    eye = np.eye(n)
    S = np.block([[eye - tau * Kt, tau * (eye - Ct)], [-Kt, eye - Ct]])
    G = np.vstack([tau * Bt, Bt])
    return S, G


def output_matrices(P: np.ndarray, kinds: tuple[str, ...], Kt: np.ndarray, Ct: np.ndarray,
                    Bt: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Output matrices ``(C, D)`` on the state ``(q^j, v^{j-1/2})``.

    ``P`` has one row of interpolation weights per sensor; ``K̃, C̃, B̃`` are
    expressed in the same coordinates as the state (nodal unknowns or modal
    coordinates).
    """
    n = Kt.shape[0]
    p = P.shape[0]
    C = np.zeros((p, 2 * n))
    D = np.zeros((p, Bt.shape[1]))
    for i, kind in enumerate(kinds):
        row = P[i]
        if kind == "displacement":
            C[i, :n] = row
        elif kind == "velocity":      # (v+ + v-)/2 with v+ = v- - C~ v- - K~ q + B~ f
            C[i, :n] = -(row @ Kt) / 2
            C[i, n:] = row - (row @ Ct) / 2
            D[i] = (row @ Bt) / 2
        elif kind == "acceleration":  # (v+ - v-)/tau
            C[i, :n] = -(row @ Kt) / tau
            C[i, n:] = -(row @ Ct) / tau
            D[i] = (row @ Bt) / tau
        else:  # pragma: no cover - kinds are validated in the config
            raise ValueError(f"unknown sensor kind {kind!r}")
    return C, D


def hold_matrices(S: np.ndarray, G: np.ndarray, substeps: int, hold: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample ``Φ = S^m``, ``Γ₀``, ``Γ₁`` of ``x[k+1] = Φ x[k] + Γ₀ u[k] + Γ₁ u[k+1]``.

    Works on dense matrices (``S`` (n, n), ``G`` (n, p)) and on stacks of 2×2
    modal blocks (``S`` (b, 2, 2), ``G`` (b, 2, p)).  Sub-step ``i`` of a sample
    carries the force ``(1 − i/m) u[k] + (i/m) u[k+1]`` (``hold="foh"``) or
    ``u[k]`` (``"zoh"``, then ``Γ₁ = 0``).
    """
    if hold not in ("foh", "zoh"):
        raise ValueError(f"input hold must be 'foh' or 'zoh', got {hold!r}")
    mul = np.matmul
    Phi, G0, G1 = S.copy(), G.copy(), np.zeros_like(G)
    for i in range(1, substeps):
        w = i / substeps if hold == "foh" else 0.0
        G0 = mul(S, G0) + (1.0 - w) * G
        G1 = mul(S, G1) + w * G
        Phi = mul(S, Phi)
    return Phi, G0, G1


def causal_hold(Phi: np.ndarray, G0: np.ndarray, G1: np.ndarray, C: np.ndarray, D: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(B, D)`` of the causal realisation on ``ξ = x − Γ₁ u``: ``B = Γ₀ + ΦΓ₁``, ``D' = D + CΓ₁`` (dense)."""
    return G0 + Phi @ G1, D + C @ G1


def discretise_time(beam: SemiDiscreteBeam, dt: float, theta: float = 0.25,
                    substeps: int = 1, input_hold: str = "foh") -> DiscreteStateSpace:
    """The θ-scheme of ``beam`` as a dense discrete state-space system (Φ, Γ, C, D, dt).

    The state is ``x[k] = (q^{mk}, v^{mk-1/2})`` of nodal unknowns, with
    ``v^{j-1/2} = (q^j - q^{j-1})/τ`` (shifted by ``−Γ₁ u[k]`` for the
    first-order hold with sub-steps, see the module docstring); state names
    are ``w(x=…)`` and ``v(x=…)``.
    """
    co = theta_coefficients(beam, dt, theta, substeps)
    S, G = one_step(co.Kt, co.Ct, co.Bt, co.tau)
    Phi, G0, G1 = hold_matrices(S, G, substeps, input_hold)
    C, D = output_matrices(beam.S, beam.sensor_kinds, co.Kt, co.Ct, co.Bt, co.tau)
    B, D = causal_hold(Phi, G0, G1, C, D)
    xs = beam.x[beam.unknown]
    names = tuple(f"w(x={v:.6g})" for v in xs) + tuple(f"v(x={v:.6g})" for v in xs)
    hold = G1 if substeps > 1 and input_hold == "foh" else None
    return DiscreteStateSpace(Phi, B, C, D, dt, beam.input_names, beam.output_names, names, hold)
