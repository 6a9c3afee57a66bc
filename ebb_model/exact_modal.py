r"""The accurate realisation: Richardson-extrapolated FD modes, integrated exactly in time.

The seed's FD + θ-scheme model has two discretisation errors that grow with the mode number: the
central differences' O((κh)²) dispersion (a mode ``0.7 %`` low at 60 nodes) and the θ-scheme's period
error (``ω τ``-dependent).  On lightly damped accelerometer records either is hundreds of noise variances
(a mode 0.2 % off is half a half-power bandwidth off).  This realisation removes both, keeping the
seed's spatial discretisation (same grid, ghost nodes, matrices):

1. **Space, Richardson over two grids.**  The FD beam is discretised on the config's grid (``h``) and on
   a grid with half the spacing (:func:`companion_config`; twice the spacing for configs above 100 nodes,
   whose refined grid would be too ill-conditioned).  The eigenvalues ``ω_i²`` of the undamped problems
   converge as ``h²``, so ``(4 ω_i²(h/2) − ω_i²(h)) / 3`` is ``O(h⁴)``; the mode shapes (at the sensors and
   actuators) and the modal damping come from the finer grid.  The model keeps as many modes as the config's grid has unknowns (the state dimension of the
   seed's model).
2. **Time, exact.**  The modal system ``q̈ + C_m q̇ + Λ q = Ψᵀ F u`` (``C_m = Ψᵀ C Ψ``: non-proportional
   damping is kept) is diagonalised in continuous time and each pole ``s`` is integrated exactly over a
   sample under the input of :attr:`~ebb_model.config.TimeSettings.input_hold` (straight line between
   samples, or held): ``x⁺ = e^{sT} x + φ₀ u_k + φ₁ u_{k+1}``, with ``φ`` in closed form (Taylor series
   for small ``|sT|``; checked against the matrix exponential of the 3×3 augmented matrix per pole).  Outputs are exact too: acceleration ``= Ψ(−Λ q − C_m q̇ + Ψᵀ F u)``.

The result is a :class:`~ebb_model.modal_form.ModalStateSpace`, simulated by the same compiled kernel
as the seed's modal form, at the same cost per sample.  Stable whenever the beam is (no time-step limit);
the θ-scheme's Bistritz analysis does not apply to it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np
import scipy.linalg as sla

from .config import BeamConfig
from .discretisation import SemiDiscreteBeam, discretise
from .modal_form import ModalStateSpace, is_proportional
from .statespace import DiscreteStateSpace

__all__ = ["exact_modal", "exact_statespace", "continuous_modes", "ContinuousModes", "richardson_modes",
           "refined_config", "companion_config", "pole_integrals"]

#: Largest refined grid: the eigen-solver's round-off grows with the stiffness matrix's condition number
#: (``∝ n⁴``: 4e7 at 199 nodes), and beyond this it shows as noise in the identification's difference
#: Jacobians; larger configs pair their grid with a coarsened one instead.
_MAX_REFINED_NODES = 201


def companion_config(config: BeamConfig) -> BeamConfig:
    """The second grid of the Richardson pair: half the spacing (``2n + 1`` nodes) while that grid has at most
    :data:`_MAX_REFINED_NODES` nodes, else twice the spacing (``(n − 1)//2`` nodes)."""
    n = config.beam.nodes
    nodes = 2 * n + 1 if 2 * n + 1 <= _MAX_REFINED_NODES else (n - 1) // 2
    return replace(config, beam=replace(config.beam, nodes=nodes))


def refined_config(config: BeamConfig) -> BeamConfig:
    """The finer grid of the Richardson pair, which gives the mode shapes and the damping."""
    other = companion_config(config)
    return other if other.beam.nodes > config.beam.nodes else config


def _lowest_modes(beam: SemiDiscreteBeam, n_modes: int, *, vectors: bool = True):
    """The ``n_modes`` lowest ``ω²`` (and mass-normalised modes) of ``K ψ = ω² M ψ``, to relative accuracy.

    ``eigh(K, M)`` resolves ``ω²`` only to ``eps·‖K‖`` absolutely, i.e. ``eps·κ(K)`` relatively for the
    lowest modes (``κ ≈ 6e8`` on a 399-node grid: jitter that spoils difference Jacobians).  When ``K`` is
    positive definite the inverted problem ``M ψ = μ K ψ`` (``μ = 1/ω²``, largest first) resolves each
    ``ω²`` to a few ``eps`` relatively; otherwise (compression, free ends) the direct problem is used.
    """
    n = beam.n_unknowns
    try:
        mu, psi = sla.eigh(beam.M, beam.K, subset_by_index=(n - n_modes, n - 1))
    except np.linalg.LinAlgError:     # K not positive definite
        mu = None
    if mu is None or np.any(mu <= 0):
        return sla.eigh(beam.K, beam.M, eigvals_only=not vectors, subset_by_index=(0, n_modes - 1))
    w2 = 1.0 / mu[::-1]
    if not vectors:
        return w2
    psi = psi[:, ::-1]
    psi /= np.sqrt(np.einsum("ij,ij->j", psi, beam.M @ psi))[None, :]   # mass-normalised (eigh gave K-normalised)
    return w2, psi


def richardson_modes(coarse: SemiDiscreteBeam, fine: SemiDiscreteBeam, n_modes: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Extrapolated eigenvalues ``ω²`` and fine-grid mass-normalised modes ``Ψ`` (n_fine × n_modes).

    With spacings ``h_f < h_c`` and ``ω²(h) = ω² + a h² + O(h⁴)``:
    ``ω²_R = ω²_f + (ω²_f − ω²_c) / ((h_c/h_f)² − 1)``.  The coarse grid has fewer modes; the upper half of
    them is faded out of the extrapolation by mode index (continuous in the parameters), and modes beyond
    keep the fine grid's values — they lie far above any band the grids resolve.

    Parameters
    ----------
    coarse, fine
        The FD beam on the two grids.
    n_modes
        How many of the lowest modes to return (at most the fine grid's unknowns).
    """
    w2_f, psi = _lowest_modes(fine, n_modes)
    m = min(coarse.n_unknowns, n_modes)
    w2_c = _lowest_modes(coarse, m, vectors=False)
    h_f, h_c = np.diff(fine.x[:2])[0], np.diff(coarse.x[:2])[0]
    weight = np.clip(2.0 * (1.0 - np.arange(m) / m), 0.0, 1.0)   # 1 for the lower half, fading to 0
    w2 = w2_f.copy()
    w2[:m] += weight * (w2_f[:m] - w2_c) / ((h_c / h_f) ** 2 - 1.0)
    return w2, psi


def pole_integrals(s: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e^{sT}``, ``φ₀ = ∫₀ᵀ e^{s(T−τ)} dτ`` and ``φ₁ = ∫₀ᵀ e^{s(T−τ)} τ/T dτ`` for each pole, to round-off.

    With ``z = sT``: ``φ₀ = T (e^z − 1)/z`` and ``φ₁ = T (e^z − 1 − z)/z²``; for ``|z| < 1/2`` their Taylor
    series (``Σ zᵏ/(k+1)!`` and ``Σ zᵏ/(k+2)!``, 20 terms) avoid the cancellation.
    """
    z = np.asarray(s, dtype=complex) * T
    small = np.abs(z) < 0.5
    zs = np.where(small, 1.0, z)
    with np.errstate(over="ignore", invalid="ignore"):  # an unstable pole overflows: caught by the stability check
        E = np.exp(z)
        f0 = np.expm1(zs) / zs
        f1 = (np.expm1(zs) - zs) / (zs * zs)
    if small.any():
        zz = z[small]
        term0 = np.ones_like(zz)          # z^k/(k+1)! at k = 0
        term1 = np.full_like(zz, 0.5)     # z^k/(k+2)! at k = 0
        s0, s1 = term0.copy(), term1.copy()
        for k in range(1, 20):
            term0 = term0 * zz / (k + 1)
            term1 = term1 * zz / (k + 2)
            s0 += term0
            s1 += term1
        f0[small], f1[small] = s0, s1
    return E, T * f0, T * f1


def _mode_poles(w2: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poles, eigenvectors and input weights of decoupled modes ``q̈ + d q̇ + ω² q = f`` (proportional damping).

    Mode ``i`` has poles ``s = −d/2 ± √(d²/4 − ω²)`` and eigenvectors ``(1, s)`` on ``(q_i, q̇_i)``; its unit
    input enters the pole coordinates as ``(−1, 1)/(s₂ − s₁)``.  Returned in the layout of the coupled route:
    poles (2k,), ``V`` (2k, 2k) on the state ``(q, q̇)``, and the rows of ``V⁻¹ [0; I]`` (2k, k).
    """
    k = w2.size
    root = np.sqrt((d * d / 4 - w2).astype(complex))
    s1, s2 = -d / 2 + root, -d / 2 - root
    if np.any(s1 == s2):
        raise np.linalg.LinAlgError("a critically damped mode has a double pole")
    idx = np.arange(k)
    lam = np.concatenate([s1, s2])
    V = np.zeros((2 * k, 2 * k), dtype=complex)
    V[idx, idx] = 1.0
    V[idx, k + idx] = 1.0
    V[k + idx, idx] = s1
    V[k + idx, k + idx] = s2
    W = np.zeros((2 * k, k), dtype=complex)
    W[idx, idx] = -1.0 / (s2 - s1)
    W[k + idx, idx] = 1.0 / (s2 - s1)
    return lam, V, W


def _output_rows(beam: SemiDiscreteBeam, psi: np.ndarray, w2: np.ndarray, Cm: np.ndarray, Fm: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(C, D)`` on the continuous modal state ``(q, q̇)``: exact displacement, velocity, acceleration."""
    P = beam.S @ psi
    k = psi.shape[1]
    C = np.zeros((P.shape[0], 2 * k))
    D = np.zeros((P.shape[0], Fm.shape[1]))
    for i, kind in enumerate(beam.sensor_kinds):
        if kind == "displacement":
            C[i, :k] = P[i]
        elif kind == "velocity":
            C[i, k:] = P[i]
        else:  # acceleration: q̈ = −Λ q − C_m q̇ + F_m u
            C[i, :k] = -P[i] * w2
            C[i, k:] = -(P[i] @ Cm)
            D[i] = P[i] @ Fm
    return C, D


def _real_blocks(lam: np.ndarray, V: np.ndarray, B0: np.ndarray, B1: np.ndarray, C: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Real 2×2 blocks ``(T, Γ₀, Γ₁, C)`` of the complex-diagonal discrete system ``z⁺ = λ z + …``, ``x = V z``.

    A conjugate pair ``(z, z̄)`` becomes ``(r, m) = (Re z, Im z)``: ``x = 2 Re(v z) = 2 Re v · r − 2 Im v · m``
    and ``[r; m]⁺ = [[Re λ, −Im λ], [Im λ, Re λ]] [r; m] + [Re b; Im b] u``.  Real poles go in pairs.
    """
    upper = [i for i in range(lam.size) if lam[i].imag > 0]
    reals = [i for i in range(lam.size) if lam[i].imag == 0]
    if len(reals) % 2:
        raise np.linalg.LinAlgError("odd number of real poles")
    CV = C @ V
    T = np.empty((len(upper) + len(reals) // 2, 2, 2))
    G0 = np.empty((T.shape[0], 2, B0.shape[1]))
    G1 = np.empty_like(G0)
    Cb = np.empty((C.shape[0], T.shape[0], 2))
    for b, i in enumerate(upper):
        e = lam[i]
        T[b] = [[e.real, -e.imag], [e.imag, e.real]]
        G0[b] = [B0[i].real, B0[i].imag]
        G1[b] = [B1[i].real, B1[i].imag]
        Cb[:, b] = np.column_stack([2 * CV[:, i].real, -2 * CV[:, i].imag])
    for b, (i, j) in enumerate(zip(reals[0::2], reals[1::2]), start=len(upper)):
        T[b] = [[lam[i].real, 0.0], [0.0, lam[j].real]]
        G0[b] = [B0[i].real, B0[j].real]
        G1[b] = [B1[i].real, B1[j].real]
        Cb[:, b] = np.column_stack([CV[:, i].real, CV[:, j].real])
    return T, G0, G1, Cb


@dataclass(frozen=True, eq=False)
class ContinuousModes:
    """The beam's continuous-time modal system, diagonalised: ``ẋ = diag(poles) z``, ``x = V z``.

    ``x = (q, q̇)`` in the (Richardson-corrected) undamped modal coordinates; ``inputs`` (2k, m) are the
    input weights in pole coordinates; ``C``, ``D`` give the sensors' outputs from ``x`` and ``u``;
    ``shapes`` (n_u of the refined grid × k) are the mass-normalised modes on the refined grid
    (:func:`refined_config`) and ``frequencies2`` the extrapolated ``ω²``.
    """

    poles: np.ndarray
    V: np.ndarray
    inputs: np.ndarray
    C: np.ndarray
    D: np.ndarray
    shapes: np.ndarray
    frequencies2: np.ndarray


def continuous_modes(config: BeamConfig, params: Mapping[str, float]) -> ContinuousModes:
    """Two-grid Richardson modes of the FD beam with their damping, diagonalised in continuous time.

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    """
    grids = (discretise(config, params), discretise(companion_config(config), params))
    coarse, fine = sorted(grids, key=lambda b: b.n_unknowns)
    k = grids[0].n_unknowns                               # as many modes as the config's grid has unknowns
    w2, psi = richardson_modes(coarse, fine, k)
    proportional, d = is_proportional(psi, fine.C)
    if proportional:
        Cm = np.diag(d)
    else:
        Cm = psi.T @ fine.C @ psi
        Cm = 0.5 * (Cm + Cm.T)
    Fm = psi.T @ fine.F
    C, D = _output_rows(fine, psi, w2, Cm, Fm)
    if proportional:                                      # decoupled modes: poles in closed form
        s, V, Win = _mode_poles(w2, d)
        B_modal = Win @ Fm                                # (2k, m) pole coordinates
    else:                                                 # coupled by the damping: eigen-decomposition
        A = np.block([[np.zeros((k, k)), np.eye(k)], [-np.diag(w2), -Cm]])
        s, V = np.linalg.eig(A)
        B_modal = np.linalg.solve(V, np.vstack([np.zeros_like(Fm), Fm]))
    return ContinuousModes(s, V, B_modal, C, D, psi, w2)


def exact_modal(config: BeamConfig, params: Mapping[str, float]) -> ModalStateSpace:
    """The accurate realisation of the beam for ``params`` (see the module docstring).

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    """
    cm = continuous_modes(config, params)
    T_s = config.time.dt
    E, phi0, phi1 = pole_integrals(cm.poles, T_s)
    if config.time.input_hold == "foh":                   # u linear between samples
        b0, b1 = (phi0 - phi1)[:, None] * cm.inputs, phi1[:, None] * cm.inputs
    else:                                                 # u held over the sample
        b0, b1 = phi0[:, None] * cm.inputs, np.zeros_like(cm.inputs)
    with np.errstate(over="ignore", invalid="ignore"):   # an unstable candidate: caught by the stability check
        T, G0, G1, Cb = _real_blocks(E, cm.V, b0, b1, cm.C)
        # causal first-order hold on ξ = z − Γ₁ u (as the seed's modal form)
        G = G0 + np.matmul(T, G1)
        D = cm.D + np.einsum("pbi,bim->pm", Cb, G1)
    hold = G1 if config.time.input_hold == "foh" else None
    return ModalStateSpace(T, G, Cb, D, T_s, config.input_names, config.output_names, None, hold)


def exact_statespace(config: BeamConfig, params: Mapping[str, float]) -> DiscreteStateSpace:
    """:func:`exact_modal` as a dense :class:`DiscreteStateSpace` (block-diagonal ``A``)."""
    return exact_modal(config, params).to_statespace()
