"""Real block-diagonal (modal) form of the θ-scheme — the fast simulation path.

A discrete system similar to (Φ, Γ, C, D) whose state matrix is block
diagonal with 2×2 real blocks ``T_b``:

.. math::

    z_b[k+1] = T_b z_b[k] + G_b u[k], \\qquad y[k] = \\sum_b C_b z_b[k] + D u[k].

Two routes lead here:

* **Proportional damping** (the damping matrix is diagonal in the undamped
  modes, checked numerically: e.g. no damping, or ``c`` alone with a lumped
  mass matrix — not with rotary inertia ``rhoI > 0`` or point masses, which
  make ``M`` non-diagonal while ``c diag(V)`` stays diagonal): the θ-scheme
  decouples *exactly* in the mass-normalised modes ``q = Ψ ξ`` of
  ``K Ψ = M Ψ Ω²``.  Mode ``i`` obeys the scalar scheme of
  :mod:`ebb_model.theta.theta_scheme` on the state ``(ξ^j, v^{j-1/2})`` with
  ``ℓ_i = 1/τ + d_i/2 + θτω_i²``, ``k̃_i = ω_i²/ℓ_i``, ``c̃_i = d_i/ℓ_i``:
  the block is ``[[1 - τk̃, τ(1 - c̃)], [-k̃, 1 - c̃]]`` raised to the number of
  sub-steps.  Cost: one symmetric generalised eigenproblem of size n.
* **General damping**: the eigen-decomposition of one sub-step ``S`` (:func:`modal_from_theta`);
  complex pairs ``σ ± iω`` become blocks ``[[σ, ω], [-ω, σ]]`` in the real basis
  ``[Re v, Im v]``; real eigenvalues are paired in diagonal blocks.  When that basis is
  ill-conditioned there is no reliable block form and the dense system is simulated instead
  (:func:`ebb_model.simulate.fast_model`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..space.discretisation import SemiDiscreteBeam
from ..statespace import DiscreteStateSpace, with_input_delays
from .theta_scheme import hold_matrices, one_step, output_matrices, theta_coefficients

__all__ = ["ModalStateSpace", "modal_from_beam", "modal_from_statespace", "modal_from_theta",
           "is_proportional", "basis_condition", "MAX_BASIS_CONDITION"]


@dataclass(frozen=True, eq=False)
class ModalStateSpace:
    """Block-diagonal real form: blocks ``T`` (nb, 2, 2), ``G`` (nb, 2, m·(1 + delays)), ``Cm`` (p, nb, 2),
    ``D`` (p, m).

    ``z[k+1] = T z[k] + Σ_j G_j u[k − j]`` with ``G_j = G[:, :, j m:(j+1) m]``, ``j = 0 … delays`` (an input
    reconstruction that reads past samples, e.g. the exact scheme's cubic; ``delays = 0`` otherwise; before
    the record the input is taken as constant, ``u[−j] = u[0]``).  ``to_nodal`` (2n × 2nb), when known, maps
    the block state (flattened block by block) to the nodal state ``(q, v)`` of
    :func:`~ebb_model.theta.theta_scheme.discretise_time`.  ``hold`` (nb, 2, m), when given, is the lookahead
    matrix ``Γ₁`` in block coordinates (a start at rest is ``z[0] = −Γ₁ u[0]``, see
    :class:`DiscreteStateSpace`).  ``frequencies_hz`` (nb,), when known, is the continuous natural frequency of
    each block's mode (:func:`ebb_model.modal.truncation.in_band` keeps the modes in a band by it; the dense form then
    names the states by mode).  The last ``filters`` blocks, when any, are the sensors' anti-alias filters
    (:mod:`ebb_model.acquisition.antialias`); their ``frequencies_hz`` are the filter poles' moduli.  ``advance`` > 0:
    the recursion's input ``u[k]`` is the record's ``u[k + advance]`` (a reconstruction that reads samples ahead,
    :mod:`ebb_model.acquisition.bandlimited`; :func:`ebb_model.simulate` feeds it so), ``D`` the feedthrough of that
    input (the lookahead's fold) and ``D_record`` (p, m) the feedthrough of the record's own sample ``u[k]`` (an
    accelerometer's share of the force), at tap ``advance`` of the recursion.
    """

    T: np.ndarray
    G: np.ndarray
    Cm: np.ndarray
    D: np.ndarray
    dt: float
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    to_nodal: np.ndarray | None = None
    hold: np.ndarray | None = None
    delays: int = 0
    frequencies_hz: np.ndarray | None = None
    #: how many of the last blocks are the acquisition's anti-alias filters (:mod:`ebb_model.acquisition.antialias`),
    #: not modes
    filters: int = 0
    advance: int = 0
    D_record: np.ndarray | None = None
    #: each output's channel delay in samples (:mod:`ebb_model.acquisition.channel_delay`), ``()``: none
    output_delays: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        optional = tuple(k for k in ("to_nodal", "hold", "frequencies_hz", "D_record")
                         if getattr(self, k) is not None)
        for name in ("T", "G", "Cm", "D") + optional:
            a = np.ascontiguousarray(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def nblocks(self) -> int:
        """Number of 2×2 blocks (half the state dimension)."""
        return self.T.shape[0]

    def to_statespace(self) -> DiscreteStateSpace:
        """The equivalent dense :class:`DiscreteStateSpace` (block-diagonal A; past inputs as delay states)."""
        import scipy.linalg as sla     # here: an FMU whose model needs none of scipy starts without it
        nb, m = self.nblocks, self.D.shape[1]
        A = sla.block_diag(*self.T) if nb else np.zeros((0, 0))
        G = [self.G[:, :, j * m:(j + 1) * m].reshape(2 * nb, m) for j in range(self.delays + 1)]
        C = self.Cm.reshape(self.Cm.shape[0], 2 * nb)
        modes = nb - self.filters
        names = (tuple(f"mode{b + 1}_{part}" for b in range(modes) for part in ("re", "im"))
                 + tuple(f"filter{b + 1}_{j}" for b in range(self.filters) for j in range(2))
                 if self.frequencies_hz is not None else tuple(f"z{b}_{j}" for b in range(nb) for j in range(2)))
        hold = self.hold.reshape(2 * nb, -1) if self.hold is not None else None
        D_taps = self.feedthrough_taps()
        return with_input_delays(A, G, C, self.D, self.dt, self.input_names, self.output_names, names, hold,
                                 D_taps=None if D_taps is None else D_taps[:, m:], advance=self.advance,
                                 output_delays=self.output_delays)

    def feedthrough_taps(self) -> np.ndarray | None:
        """``D`` on every tap (p, m·(delays + 1)), column ``j m + l`` input ``l`` at sample ``k − j`` of the
        recursion's input: ``D`` at tap 0, ``D_record`` at tap ``advance``; ``None`` without ``D_record``."""
        if self.D_record is None:
            return None
        p, m = self.D.shape
        taps = np.zeros((p, m * (self.delays + 1)))
        taps[:, :m] = self.D
        taps[:, self.advance * m:(self.advance + 1) * m] += self.D_record
        return taps

    def input_matrix(self, z: complex) -> np.ndarray:
        """``Σ_j G_j z^{−j}`` (nb, 2, m): the input matrix of the transfer function at ``z``."""
        m = self.D.shape[1]
        # j = 0 … delays (delays >= 0): at least one term, so an array, never sum's start 0
        return cast(np.ndarray, sum(self.G[:, :, j * m:(j + 1) * m] * z ** (-j) for j in range(self.delays + 1)))

    def spectral_radius(self) -> float:
        """Largest modulus of the block eigenvalues (closed form for 2×2 blocks)."""
        if self.nblocks == 0:
            return 0.0
        tr = self.T[:, 0, 0] + self.T[:, 1, 1]
        det = self.T[:, 0, 0] * self.T[:, 1, 1] - self.T[:, 0, 1] * self.T[:, 1, 0]
        disc = np.sqrt((tr * tr / 4 - det).astype(complex))
        return float(np.max(np.maximum(np.abs(tr / 2 + disc), np.abs(tr / 2 - disc))))


def is_proportional(Psi: np.ndarray, C: np.ndarray, *, rtol: float = 1e-10) -> tuple[bool, np.ndarray]:
    """Whether ``Ψᵀ C Ψ`` is diagonal (to ``rtol``); returns the flag and its diagonal."""
    return is_diagonal(Psi.T @ C @ Psi, rtol=rtol)


#: how far off its diagonal the modal damping may be, relative to its largest diagonal entry, to count as
#: proportional (decoupled modes)
DIAGONAL_RTOL = 1e-10


def is_diagonal(Cd: np.ndarray, *, rtol: float = DIAGONAL_RTOL) -> tuple[bool, np.ndarray]:
    """Whether the modal damping ``Cd`` (``Ψᵀ C Ψ``) is diagonal (to ``rtol`` of its largest diagonal entry);
    returns the flag and its diagonal."""
    diag = np.diag(Cd).copy()
    scale = max(float(np.max(np.abs(diag))), 1e-300)
    return bool(off_diagonal_magnitude(Cd) <= rtol * scale), diag


def off_diagonal_magnitude(a: np.ndarray) -> float:
    """The largest magnitude of the square matrix ``a`` off its diagonal (0 for a 1×1 or empty one)."""
    return float(np.max(np.abs(a - np.diag(np.diag(a))), initial=0.0))


def modal_from_beam(beam: SemiDiscreteBeam, dt: float, theta: float = 0.25,
                    substeps: int = 1, input_hold: str = "foh") -> ModalStateSpace | None:
    """Exact modal form via the undamped modes, or ``None`` if damping is not proportional."""
    import scipy.linalg as sla     # here: an FMU whose model needs none of scipy starts without it
    w2, Psi = sla.eigh(beam.K, beam.M)
    prop, d = is_proportional(Psi, beam.C)
    if not prop:
        return None
    tau = dt / substeps
    ell = 1.0 / tau + d / 2 + theta * tau * w2
    kt, ct = w2 / ell, d / ell
    bt = (Psi.T @ beam.F) / ell[:, None]  # (nb, m)
    nb, m = bt.shape
    # one-step blocks on (xi^j, v^{j-1/2}) and their powers
    S = np.empty((nb, 2, 2))
    S[:, 0, 0] = 1.0 - tau * kt
    S[:, 0, 1] = tau * (1.0 - ct)
    S[:, 1, 0] = -kt
    S[:, 1, 1] = 1.0 - ct
    g = np.empty((nb, 2, m))
    g[:, 0, :] = tau * bt
    g[:, 1, :] = bt
    T, G0, G1 = hold_matrices(S, g, substeps, input_hold)
    # outputs in modal coordinates: P Ψ, with diagonal scheme matrices
    C2, D = output_matrices(beam.S @ Psi, beam.sensor_kinds, np.diag(kt), np.diag(ct), bt, tau)
    Cm = np.stack([C2[:, :nb], C2[:, nb:]], axis=2)  # (p, nb, 2)
    # causal first-order-hold realisation per block (see ebb_model.theta.theta_scheme)
    G = G0 + np.matmul(T, G1)
    D = D + np.einsum("pbi,bim->pm", Cm, G1)
    n = Psi.shape[0]
    to_nodal = np.zeros((2 * n, 2 * nb))
    to_nodal[:n, 0::2] = Psi
    to_nodal[n:, 1::2] = Psi
    hold = G1 if substeps > 1 and input_hold == "foh" else None
    return ModalStateSpace(T, G, Cm, D, dt, beam.input_names, beam.output_names, to_nodal, hold)


#: Largest condition number of an eigenvector basis the fast path accepts: beyond it the block form would lose
#: more than ~6 of float64's 16 digits, and the dense simulation is used instead.
MAX_BASIS_CONDITION = 1e10


def _real_eigenbasis(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real 2×2 blocks (nb, 2, 2) and basis ``W`` with ``A W = W blockdiag(T)``, from ``eig(A)``.

    LAPACK's ``geev`` returns each complex pair as two adjacent, exactly conjugate eigenvalues: each gives a
    rotation block ``[[a, b], [−b, a]]`` (``a + ib`` the one with positive imaginary part) on the real and imaginary
    parts of its eigenvector, in the order found; then the real eigenvalues (``|Im| ≤ 1e-13`` of the largest
    modulus), two by two in a diagonal block each.

    Raises
    ------
    numpy.linalg.LinAlgError
        If the eigenvalues cannot be paired into real blocks (a complex one without its conjugate beside it, or an
        odd number of real ones).
    """
    lam, V = np.linalg.eig(A)
    n = lam.size
    tol = 1e-13 * max(1.0, float(np.max(np.abs(lam), initial=0.0)))
    real = np.abs(lam.imag) <= tol
    pairs, reals = np.flatnonzero(~real), np.flatnonzero(real)
    first, second = pairs[0::2], pairs[1::2]
    if first.size != second.size or np.any(second != first + 1) or np.any(lam[second] != np.conj(lam[first])):
        raise np.linalg.LinAlgError("complex eigenvalue without conjugate partner")
    if reals.size % 2:
        raise np.linalg.LinAlgError("odd number of real eigenvalues in an even-dimensional system")
    upper = np.where(lam[first].imag > 0, first, second)
    a, b = reals[0::2], reals[1::2]
    nc, nb = upper.size, upper.size + a.size
    W = np.empty((n, 2 * nb))
    W[:, 0:2 * nc:2], W[:, 1:2 * nc:2] = V[:, upper].real, V[:, upper].imag
    W[:, 2 * nc::2], W[:, 2 * nc + 1::2] = V[:, a].real, V[:, b].real
    T = np.zeros((nb, 2, 2))
    lr = lam[upper]
    T[:nc, 0, 0], T[:nc, 0, 1], T[:nc, 1, 0], T[:nc, 1, 1] = lr.real, lr.imag, -lr.imag, lr.real
    T[nc:, 0, 0], T[nc:, 1, 1] = lam[a].real, lam[b].real
    return T, W


def basis_condition(W: np.ndarray) -> float:
    """Condition number of a basis after scaling its columns to unit length (``inf`` if singular)."""
    if W.size == 0:
        return 1.0
    norms = np.linalg.norm(W, axis=0)
    if np.any(norms == 0):
        return np.inf
    return float(np.linalg.cond(W / norms))


def modal_from_statespace(sys: DiscreteStateSpace) -> ModalStateSpace:
    """Real block-diagonal form of a general system via the eigen-decomposition of A.

    Raises
    ------
    numpy.linalg.LinAlgError
        If ``A`` is numerically defective (eigenvector basis condition above :data:`MAX_BASIS_CONDITION`).
    """
    T, W = _real_eigenbasis(sys.A)
    if basis_condition(W) > MAX_BASIS_CONDITION:
        raise np.linalg.LinAlgError("eigenvector matrix is ill-conditioned; use the dense simulation")
    Wi = np.linalg.inv(W)
    nb = T.shape[0]
    G = (Wi @ sys.B).reshape(nb, 2, -1)
    Cm = (sys.C @ W).reshape(sys.noutputs, nb, 2)
    hold = (Wi @ sys.hold).reshape(nb, 2, -1) if sys.hold is not None else None
    return ModalStateSpace(T, G, Cm, sys.D, sys.dt, sys.input_names, sys.output_names, W, hold)


def modal_from_theta(beam: SemiDiscreteBeam, dt: float, theta: float = 0.25, substeps: int = 1,
                     input_hold: str = "foh") -> ModalStateSpace | None:
    """Block form of the θ-scheme for any damping, via the eigenvectors of **one sub-step** ``S``.

    ``Φ = S^m`` has the same eigenvectors as ``S``, but with many sub-steps the well damped high modes'
    eigenvalues ``λ^m`` all crowd near zero, where ``eig(Φ)`` cannot separate their eigenvectors (240 nodes,
    32 sub-steps: condition above 1e10); ``S``'s eigenvalues stay apart.  The sub-step blocks are raised to
    the ``m``-th power and the hold sums formed per block (:func:`~ebb_model.theta.theta_scheme.hold_matrices`).
    Returns ``None`` when even ``S``'s eigenvector basis is ill-conditioned (condition above
    :data:`MAX_BASIS_CONDITION`): then the dense system is the one to simulate.
    """
    co = theta_coefficients(beam, dt, theta, substeps)
    S, G = one_step(co.Kt, co.Ct, co.Bt, co.tau)
    try:
        Ts, W = _real_eigenbasis(S)
    except np.linalg.LinAlgError:
        return None
    if basis_condition(W) > MAX_BASIS_CONDITION:
        return None
    Wi = np.linalg.inv(W)
    nb = Ts.shape[0]
    T, G0, G1 = hold_matrices(Ts, (Wi @ G).reshape(nb, 2, -1), substeps, input_hold)
    C, D = output_matrices(beam.S, beam.sensor_kinds, co.Kt, co.Ct, co.Bt, co.tau)
    Cm = (C @ W).reshape(C.shape[0], nb, 2)
    Gc = G0 + np.matmul(T, G1)           # causal first-order hold, as in modal_from_beam
    D = D + np.einsum("pbi,bim->pm", Cm, G1)
    hold = G1 if substeps > 1 and input_hold == "foh" else None
    return ModalStateSpace(T, Gc, Cm, D, dt, beam.input_names, beam.output_names, W, hold)
