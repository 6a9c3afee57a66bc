r"""The accurate realisation: Richardson-extrapolated FD modes, integrated exactly in time.

The seed's FD + θ-scheme model has two discretisation errors that grow with the mode number: the
central differences' O((κh)²) dispersion (a mode ``0.7 %`` low at 60 nodes) and the θ-scheme's period
error (``ω τ``-dependent).  On lightly damped accelerometer records either is hundreds of noise variances
(a mode 0.2 % off is half a half-power bandwidth off).  This realisation removes both, keeping the
seed's spatial discretisation (same grid, ghost nodes, matrices):

1. **Space, Richardson over two grids.**  The FD beam is discretised on the config's grid (``h``) and on
   a grid with half the spacing (:func:`~ebb_model.space.richardson_pair.companion_config`; twice the spacing for
   configs above 100 nodes, whose refined grid would be too ill-conditioned).  The eigenvalues ``ω_i²`` of the
   undamped problems converge as ``h²``, so ``(4 ω_i²(h/2) − ω_i²(h)) / 3`` is ``O(h⁴)``; the mode shapes (at
   the sensors and actuators) and the modal damping come from the finer grid.  The model keeps as many modes
   as the config's grid has unknowns (the state dimension of the seed's model).  The undamped modes depend on
   the parameters through ratios only: one eigen-decomposition serves every parameter set with the same
   ratios (:mod:`ebb_model.modal.mode_family`).
2. **Time, exact.**  The modal system ``q̈ + C_m q̇ + Λ q = Ψᵀ F u`` (``C_m = Ψᵀ C Ψ``: non-proportional
   damping is kept) is diagonalised in continuous time and each pole ``s`` is integrated exactly over a
   sample under the input of :attr:`~ebb_model.config.TimeSettings.input_hold`: the cubic through the
   samples ``k−2 … k+1`` (default; a band-limited force is smooth, and the straight line is 2 % off in
   amplitude at fs/13 — on a lightly damped record that alone is several noise variances), the straight line
   between samples, or the sample held: ``x⁺ = e^{sT} x + Σ_j W_j u_{k+j}`` with ``W_j`` in closed form
   (:func:`~ebb_model.exact.sample_integrals.polynomial_integrals`, series for small ``|sT|``; checked against the
   matrix exponential).
   The lookahead ``u_{k+1}`` is made causal by the state shift ``ξ = x − W_1 u``, the past samples are
   extra input columns (delay states in the dense form).  Outputs are exact too: acceleration
   ``= Ψ(−Λ q − C_m q̇ + Ψᵀ F u)``.

The result is a :class:`~ebb_model.theta.modal_form.ModalStateSpace`, simulated by the same compiled kernel
as the seed's modal form.  Stable whenever the beam is (no time-step limit);
the θ-scheme's Bistritz analysis does not apply to it.
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Mapping

import numba
import numpy as np

from ..acquisition.antialias import effective_filters, filtered_poles, series_statespace
from ..acquisition.channel_delay import effective_delays
from ..config import BeamConfig
from ..modal.coupled_modes import LowRankDamping, coupled_modes
from ..modal.parameter_modes import FamilyModes, family_modes
from ..theta.modal_form import MAX_BASIS_CONDITION, ModalStateSpace, basis_condition
from ..parameter_values import resolve_parameters
from ..acquisition.bandlimited import dense_weights
from .sample_integrals import ADVANCE, INPUT_TAPS, LAGRANGE, modal_blocks
from ..statespace import DiscreteStateSpace, with_input_delays

__all__ = ["exact_model", "exact_modal", "exact_statespace", "continuous_modes", "ContinuousModes", "modal_matrices",
           "modal_system", "ModalMatrices", "modal_state_matrix"]

def _mode_poles(w2: np.ndarray, d: np.ndarray, Fm: np.ndarray, C: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poles, input weights and output rows of decoupled modes ``q̈ + d q̇ + ω² q = F_m u``, ``y = C (q, q̇)``
    (proportional damping).

    Mode ``i`` has poles ``s = −d/2 ± √(d²/4 − ω²)`` and eigenvectors ``(1, s)`` on ``(q_i, q̇_i)``; its unit
    input enters the pole coordinates as ``(−1, 1)/(s₂ − s₁)``.  Returned in the layout of the coupled route:
    poles (2k,) — every ``s₁``, then every ``s₂`` —, the input weights ``V⁻¹ [0; F_m]`` (2k, m) and the output
    rows ``C V`` (p, 2k).  One compiled pass (its NumPy form spent most of its time in small array operations).
    """
    k, m = w2.size, Fm.shape[1]
    s = np.empty(2 * k, dtype=complex)
    B = np.empty((2 * k, m), dtype=complex)
    CV = np.empty((C.shape[0], 2 * k), dtype=complex)
    if _decoupled_poles(np.ascontiguousarray(w2, dtype=float), np.ascontiguousarray(d, dtype=float),
                        np.ascontiguousarray(Fm, dtype=float), np.ascontiguousarray(C, dtype=float), s, B, CV):
        raise np.linalg.LinAlgError("a critically damped mode has a double pole")
    return s, B, CV


@numba.njit(cache=True, nogil=True)
def _decoupled_poles(w2, d, Fm, C, s, B, CV):  # pragma: no cover - compiled
    k = w2.size
    for i in range(k):
        root = cmath.sqrt(complex(d[i] * d[i] / 4 - w2[i]))
        s1, s2 = -d[i] / 2 + root, -d[i] / 2 - root
        if s1 == s2:
            return True
        s[i], s[k + i] = s1, s2
        g = -1.0 / (s2 - s1)
        for l in range(Fm.shape[1]):
            B[i, l] = g * Fm[i, l]
            B[k + i, l] = -B[i, l]
        for o in range(C.shape[0]):             # V's columns (1, s₁) and (1, s₂) on (q_i, q̇_i)
            CV[o, i] = C[o, i] + C[o, k + i] * s1
            CV[o, k + i] = C[o, i] + C[o, k + i] * s2
    return False


def _output_rows(P: np.ndarray, kinds: tuple[str, ...], w2: np.ndarray, Cm: np.ndarray, Fm: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(C, D)`` on the continuous modal state ``(q, q̇)`` of the sensors whose modal rows are ``P = S Ψ``:
    exact displacement, velocity, acceleration."""
    k = P.shape[1]
    C = np.zeros((P.shape[0], 2 * k))
    D = np.zeros((P.shape[0], Fm.shape[1]))
    for i, kind in enumerate(kinds):
        if kind == "displacement":
            C[i, :k] = P[i]
        elif kind == "velocity":
            C[i, k:] = P[i]
        else:  # acceleration: q̈ = −Λ q − C_m q̇ + F_m u
            C[i, :k] = -P[i] * w2
            C[i, k:] = -(P[i] @ Cm)
            D[i] = P[i] @ Fm
    return C, D


@dataclass(frozen=True, eq=False)
class ContinuousModes:
    """The beam's continuous-time modal system, diagonalised: ``ẋ = diag(poles) z``, ``x = V z``.

    ``x = (q, q̇)`` in the (Richardson-corrected) undamped modal coordinates; ``inputs`` (2k, m) are the
    input weights in pole coordinates; ``C``, ``D`` give the sensors' outputs from ``x`` and ``u``;
    ``frequencies2`` are the extrapolated ``ω²`` of the undamped ``modes``.  ``basis`` is ``V`` when the damping
    couples the modes, ``None`` for decoupled modes, whose ``V = [[I, I], [diag(s₁), diag(s₂)]]`` (poles
    ``s₁`` then ``s₂``) is formed only when read.
    """

    poles: np.ndarray
    inputs: np.ndarray
    C: np.ndarray
    D: np.ndarray
    modes: FamilyModes
    frequencies2: np.ndarray
    basis: np.ndarray | None
    #: ``C V`` when formed with the poles (decoupled modes), else ``None`` (:meth:`output_rows` forms it)
    rows: np.ndarray | None = None

    @property
    def shapes(self) -> np.ndarray:
        """The mass-normalised modes on the finer grid of the Richardson pair (n_u × k)."""
        return self.modes.shapes

    @property
    def V(self) -> np.ndarray:
        """The eigenvector basis ``V`` (2k, 2k) of the state ``(q, q̇)``."""
        if self.basis is not None:
            return self.basis
        k = self.frequencies2.size
        idx = np.arange(k)
        V = np.zeros((2 * k, 2 * k), dtype=complex)
        V[idx, idx] = V[idx, k + idx] = 1.0
        V[k + idx, idx], V[k + idx, k + idx] = self.poles[:k], self.poles[k:]
        return V

    def output_rows(self) -> np.ndarray:
        """``C V``: the outputs from the pole coordinates (``O(p k)`` for decoupled modes)."""
        if self.rows is not None:
            return self.rows
        if self.basis is not None:
            return self.C @ self.basis
        k = self.frequencies2.size
        Cq, Cv = self.C[:, :k], self.C[:, k:]
        return np.hstack([Cq + Cv * self.poles[:k], Cq + Cv * self.poles[k:]])


@dataclass(frozen=True, eq=False)
class ModalMatrices:
    """The beam's modal system ``q̈ + C_m q̇ + Λ q = F_m u`` on the Richardson modes, with its sensor rows.

    ``C``, ``D`` give the outputs from ``x = (q, q̇)`` and ``u``; ``damping`` is the diagonal of ``C_m`` when
    the damping is proportional (``C_m`` diagonal), else ``None``; ``low_rank`` is ``C_m``'s structure when
    it is the identity times a rate plus a low-rank part (point masses on a viscously damped beam:
    :mod:`ebb_model.modal.coupled_modes`), else ``None``.
    """

    frequencies2: np.ndarray
    modes: FamilyModes
    Cm: np.ndarray
    Fm: np.ndarray
    C: np.ndarray
    D: np.ndarray
    damping: np.ndarray | None
    low_rank: LowRankDamping | None = None

    @property
    def shapes(self) -> np.ndarray:
        """The mass-normalised modes ``Ψ`` on the finer grid of the Richardson pair (n_u × k)."""
        return self.modes.shapes


def modal_matrices(config: BeamConfig, params: Mapping[str, float]) -> ModalMatrices:
    """Two-grid Richardson modes of the FD beam (:func:`ebb_model.modal.parameter_modes.family_modes`: one
    eigen-decomposition per family of parameter sets) with their damping, forcing and sensor rows.

    Raises
    ------
    ParameterError
        Invalid parameter values.
    """
    return modal_system(family_modes(config, resolve_parameters(config, params)))


def modal_system(modes: FamilyModes) -> ModalMatrices:
    """:func:`modal_matrices` of the undamped ``modes``: the modal damping's structure (diagonal, low-rank or
    full), the forcing and the sensor rows."""
    w2 = modes.frequencies2
    low_rank = modes.low_rank_damping()
    if low_rank is None:
        d = modes.diagonal_damping()
    elif low_rank.rank == 0:
        # C = α M + β K: decoupled, whatever the modes' orthogonality round-off in Ψᵀ C Ψ (near buckling)
        d, low_rank = low_rank.diagonal, None
    else:
        d = None
    if d is not None:
        Cm = np.diag(d)
    elif low_rank is not None:
        Cm = low_rank.matrix()
    else:
        Cm = 0.5 * (modes.damping + modes.damping.T)
    F, S, J = modes.loads
    psi = modes.shape_rows(J)          # the shapes where the loads and sensors are: all the outputs read
    Fm = psi.T @ F[J]
    C, D = _output_rows(S[:, J] @ psi, tuple(s.kind for s in modes.config.sensors), w2, Cm, Fm)
    return ModalMatrices(w2, modes, Cm, Fm, C, D, d, low_rank)


def continuous_modes(config: BeamConfig, params: Mapping[str, float]) -> ContinuousModes:
    """:func:`modal_matrices`, diagonalised in continuous time.

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    numpy.linalg.LinAlgError
        The damping couples the modes and the eigenvector basis is ill-conditioned (condition above
        :data:`~ebb_model.theta.modal_form.MAX_BASIS_CONDITION`, e.g. a pole pair near critical damping), or a
        proportionally damped mode is exactly critically damped: there is no reliable diagonal form
        (:func:`exact_model` then integrates the modal system densely).
    """
    mm = modal_matrices(config, params)
    w2, Fm = mm.frequencies2, mm.Fm
    coupled = None if mm.low_rank is None else coupled_modes(w2, mm.low_rank, Fm)
    V: np.ndarray | None = None
    rows: np.ndarray | None = None
    if mm.damping is not None:                            # decoupled modes: poles in closed form
        s, B_modal, rows = _mode_poles(w2, mm.damping, Fm, mm.C)      # (2k, m) pole coordinates
    elif coupled is not None:                             # coupled by a low-rank part: Newton, mode by mode
        s, V, B_modal = coupled
    else:                                                 # coupled by the damping: eigen-decomposition
        s, V = np.linalg.eig(modal_state_matrix(w2, mm.Cm))
        if basis_condition(V) > MAX_BASIS_CONDITION:
            raise np.linalg.LinAlgError("the modes' eigenvector basis is ill-conditioned")
        B_modal = np.linalg.solve(V, np.vstack([np.zeros_like(Fm), Fm]))
    return ContinuousModes(s, B_modal, mm.C, mm.D, mm.modes, w2, V, rows)


def modal_state_matrix(w2: np.ndarray, Cm: np.ndarray) -> np.ndarray:
    """``A`` of ``ẋ = A x`` for ``x = (q, q̇)``: ``[[0, I], [−Λ, −C_m]]``."""
    k = w2.size
    return np.block([[np.zeros((k, k)), np.eye(k)], [-np.diag(w2), -Cm]])


def exact_modal(config: BeamConfig, params: Mapping[str, float]) -> ModalStateSpace:
    """The accurate realisation of the beam for ``params`` (see the module docstring).

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    numpy.linalg.LinAlgError
        No reliable diagonal form (see :func:`continuous_modes`; :func:`exact_model` falls back).
    """
    cm = continuous_modes(config, params)
    T_s = config.time.dt
    taps = INPUT_TAPS[config.time.input_hold]
    filters = effective_filters(config)
    poles, inputs, CV, D, added = cm.poles, cm.inputs, cm.output_rows(), cm.D, 0
    if any(f is not None for f in filters):               # the acquisition's filters in series, still diagonal
        poles, inputs, CV, D, added = filtered_poles(poles, inputs, CV, D, filters)
    bl = modal_blocks(poles, T_s, config.time.input_hold, inputs, CV, poles.size - added if added else None)
    D = np.array(D.real, dtype=float)
    advance = ADVANCE[config.time.input_hold]
    if advance:                                           # the record's own sample read at tap `advance`
        D_record: np.ndarray | None = D if np.any(D) else None
        D = bl.D_hold
    else:
        D_record, D = None, D + bl.D_hold
    return ModalStateSpace(bl.T, bl.G, bl.C, D, T_s, config.input_names, config.output_names, None, bl.hold,
                           -min(taps), bl.frequencies / (2 * math.pi), bl.filters, advance, D_record,
                           effective_delays(config))


def exact_statespace(config: BeamConfig, params: Mapping[str, float]) -> DiscreteStateSpace:
    """The same realisation as :func:`exact_modal` without diagonalising: dense, on the state ``(q, q̇)``.

    One matrix exponential per parameter set (Van Loan): the modal system augmented with the chain of
    derivatives of the input polynomial between samples (``f → f' → …``, the highest constant) gives
    ``Φ = e^{AT}`` and the response ``P_q`` to each derivative, so ``x⁺ = Φ x + Σ_j P_j u[k + j]`` with the
    taps of :data:`INPUT_TAPS` and ``P_j = Σ_q q! c_{jq} P_q``.  ``O(k²)`` work per sample instead of
    ``O(k)``: the fallback of :func:`exact_model`, and an independent check of the pole integrals.

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    """
    import scipy.linalg as sla     # here: an FMU whose model needs none of scipy starts without it
    mm = modal_matrices(config, params)
    A = modal_state_matrix(mm.frequencies2, mm.Cm)
    B = np.vstack([np.zeros_like(mm.Fm), mm.Fm])
    C, D = mm.C, mm.D
    filters = effective_filters(config)
    if any(f is not None for f in filters):               # the acquisition's filters in series: their own states
        A, B, C, D = series_statespace(A, B, C, D, filters)
    n, m = B.shape
    T_s = config.time.dt
    taps = INPUT_TAPS[config.time.input_hold]
    k = mm.frequencies2.size
    names = (tuple(f"q{i}" for i in range(k)) + tuple(f"dq{i}" for i in range(k))
             + tuple(f"filter{i}" for i in range(n - 2 * k)))
    advance = ADVANCE[config.time.input_hold]
    if advance:                                           # the band-limited force: by quadrature, not Van Loan
        Phi, Pm = dense_weights(A, B, T_s)
        P = dict(zip(taps, Pm))
        hold = P.pop(1)
        P[0] = P[0] + Phi @ hold
        D_taps = np.zeros((D.shape[0], m * -min(taps)))
        D_taps[:, (advance - 1) * m:advance * m] = D      # the record's own sample, `advance` taps behind
        return with_input_delays(Phi, [P[-j] for j in range(-min(taps) + 1)], C, C @ hold, T_s,
                                 config.input_names, config.output_names, names, hold, D_taps=D_taps,
                                 advance=advance, output_delays=effective_delays(config))
    deg = len(taps) - 1
    aug = np.zeros((n + (deg + 1) * m, n + (deg + 1) * m))
    aug[:n, :n] = A * T_s
    aug[:n, n:n + m] = B * T_s
    for q in range(deg):                                  # d/dσ of the q-th derivative is the next one
        aug[n + q * m:n + (q + 1) * m, n + (q + 1) * m:n + (q + 2) * m] = np.eye(m)
    # an unstable candidate overflows (inf/nan in Φ and what is made of it): caught by the stability check
    with np.errstate(over="ignore", invalid="ignore"):
        E = sla.expm(aug)
        Phi = E[:n, :n]
        Pq = [E[:n, n + q * m:n + (q + 1) * m] * math.factorial(q) for q in range(deg + 1)]
        coef = LAGRANGE[config.time.input_hold]
        P = {t: sum(coef[j, q] * Pq[q] for q in range(deg + 1)) for j, t in enumerate(taps)}
        hold = P.pop(1, None)
        if hold is not None:                              # the lookahead, causal on ξ = x − Γ₁ u
            P[0] = P[0] + Phi @ hold
            D = D + C @ hold
    return with_input_delays(Phi, [P[-j] for j in range(-min(taps) + 1)], C, D, T_s, config.input_names,
                             config.output_names, names, hold, output_delays=effective_delays(config))


def exact_model(config: BeamConfig, params: Mapping[str, float]) -> ModalStateSpace | DiscreteStateSpace:
    """:func:`exact_modal`, or :func:`exact_statespace` when the modes cannot be diagonalised reliably.

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    """
    try:
        return exact_modal(config, params)
    except np.linalg.LinAlgError:
        return exact_statespace(config, params)
