r"""Cubic Hermite finite-element reference model of the damped, axially loaded beam.

This is an *independent* discretisation (Galerkin finite elements) of the
project's model

.. math::

    \rho A\, w_{tt} - (\rho I\, w_{xtt})_x + c\, w_t + \eta EI\, w_{xxxxt}
    + EI\, w_{xxxx} - N w_{xx} + k_f w
    = \sum_j f_j(t)\, \delta(x - a_j), \qquad 0 \le x \le L,

(rotary inertia :math:`\rho I` of the Rayleigh beam and a Winkler foundation
:math:`k_f` are optional and zero by default), used to validate the project's
finite-difference model and to generate synthetic "measured" data
(:mod:`ebb_model.reference.synthetic`).

Weak form and discretisation
----------------------------
Multiplying by a test function :math:`v` and integrating by parts twice
(bending) and once (axial force) gives

.. math::

    \int_0^L \rho A\, \ddot w v + \rho I\, \ddot w' v'
    + c\, \dot w v + k_f w v
    + EI (w'' + \eta \dot w'') v''
    + N w' v' \,dx
    + \sum_{\text{ends}} \bigl(k_t\, w v + k_r\, w' v'\bigr)
    + \sum_i m_i \ddot w(x_i) v(x_i)
    = \sum_j f_j(t)\, v(a_j).

The natural boundary conditions at an unconstrained end are therefore
:math:`EI w'' = \mp k_r w'` and :math:`EI w''' - N w' - \rho I \ddot w' = \pm k_t w`
(zero for a free end: moment and transverse shear vanish), consistent with
:mod:`ebb_model.reference.analytic` for :math:`\rho I = 0`.

On a uniform mesh of ``n_elements`` elements of length :math:`l`, with nodal
unknowns :math:`(w_i, w'_i)`, the element shape functions in
:math:`\xi = (x - x_e)/l \in [0, 1]` are

.. math::

    N_1 = 1 - 3\xi^2 + 2\xi^3, \quad N_2 = l(\xi - 2\xi^2 + \xi^3), \quad
    N_3 = 3\xi^2 - 2\xi^3, \quad N_4 = l(-\xi^2 + \xi^3),

giving the exact (closed-form) element matrices

.. math::

    M_e = \frac{\rho A l}{420}
    \begin{bmatrix} 156 & 22l & 54 & -13l\\ 22l & 4l^2 & 13l & -3l^2\\
                     54 & 13l & 156 & -22l\\ -13l & -3l^2 & -22l & 4l^2 \end{bmatrix},
    \qquad
    K_{b,e} = \frac{EI}{l^3}
    \begin{bmatrix} 12 & 6l & -12 & 6l\\ 6l & 4l^2 & -6l & 2l^2\\
                    -12 & -6l & 12 & -6l\\ 6l & 2l^2 & -6l & 4l^2 \end{bmatrix},

.. math::

    K_{g,e} = \frac{N}{30 l}
    \begin{bmatrix} 36 & 3l & -36 & 3l\\ 3l & 4l^2 & -3l & -l^2\\
                    -36 & -3l & 36 & -3l\\ 3l & -l^2 & -3l & 4l^2 \end{bmatrix}.

The rotary-inertia matrix :math:`\int \rho I\, N'^T N'` has the shape of
:math:`K_{g,e}` with :math:`N \to \rho I`, and the foundation matrix
:math:`\int k_f N^T N = (k_f/\rho A) M_e`.

Global matrices: :math:`M = M_{\rho A} + M_{\rho I} + \sum_i m_i \phi(x_i)\phi(x_i)^T`,
:math:`K = K_b + K_g + (k_f/\rho A) M_{\rho A} + K_{\text{springs}}`,
:math:`C = (c/\rho A)\, M_{\rho A} + \eta K_b` (viscous damping acts on the
translational inertia only), where :math:`\phi(x)` is the
vector of global shape functions (translational part) at :math:`x`.
Constrained DOFs (spring stiffness ``inf``) are removed.
The semi-discrete system is :math:`M\ddot q + C\dot q + K q = \Phi u(t)`
with :math:`\Phi = [\phi(a_1), \dots]` and outputs :math:`y = \phi(s)^T q`
(or its time derivatives).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg as sla

from ..checks import finite_scalar
from ..errors import ConfigError, ParameterError

__all__ = [
    "HermiteBeam",
    "hermite_beam",
    "hermite_shape_functions",
    "element_matrices",
    "CLAMPED",
    "PINNED",
    "FREE",
    "SENSOR_KINDS",
]

#: End conditions as ``(k_translational, k_rotational)`` pairs.
CLAMPED: tuple[float, float] = (math.inf, math.inf)
PINNED: tuple[float, float] = (math.inf, 0.0)
FREE: tuple[float, float] = (0.0, 0.0)

#: Accepted sensor kinds.
SENSOR_KINDS: tuple[str, ...] = ("displacement", "velocity", "acceleration")


# --------------------------------------------------------------------------
# element level
# --------------------------------------------------------------------------
def hermite_shape_functions(xi: float, l: float) -> np.ndarray:
    r"""Cubic Hermite shape functions :math:`[N_1, N_2, N_3, N_4]` at local ``xi``.

    Parameters
    ----------
    xi
        Local coordinate :math:`\xi = (x - x_e)/l \in [0, 1]`.
    l
        Element length.

    Returns
    -------
    numpy.ndarray
        Shape (4,), multiplying :math:`(w_e, w'_e, w_{e+1}, w'_{e+1})`.
    """
    x2 = xi * xi
    x3 = x2 * xi
    return np.array(
        [1.0 - 3.0 * x2 + 2.0 * x3, l * (xi - 2.0 * x2 + x3), 3.0 * x2 - 2.0 * x3, l * (x3 - x2)]
    )


def element_matrices(l: float, EI: float, rhoA: float, N: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Consistent element mass, bending and geometric stiffness matrices.

    Parameters
    ----------
    l
        Element length.
    EI, rhoA, N
        Bending stiffness, mass per length, axial force (tension positive).

    Returns
    -------
    (M_e, Kb_e, Kg_e)
        :math:`\int \rho A\, N^T N`, :math:`\int EI\, N''^T N''`,
        :math:`\int N\, N'^T N'` over the element (4 x 4 each); see the module
        docstring for the closed forms.
    """
    l2 = l * l
    Me = (rhoA * l / 420.0) * np.array(
        [
            [156.0, 22.0 * l, 54.0, -13.0 * l],
            [22.0 * l, 4.0 * l2, 13.0 * l, -3.0 * l2],
            [54.0, 13.0 * l, 156.0, -22.0 * l],
            [-13.0 * l, -3.0 * l2, -22.0 * l, 4.0 * l2],
        ]
    )
    Kb = (EI / l**3) * np.array(
        [
            [12.0, 6.0 * l, -12.0, 6.0 * l],
            [6.0 * l, 4.0 * l2, -6.0 * l, 2.0 * l2],
            [-12.0, -6.0 * l, 12.0, -6.0 * l],
            [6.0 * l, 2.0 * l2, -6.0 * l, 4.0 * l2],
        ]
    )
    Kg = (N / (30.0 * l)) * np.array(
        [
            [36.0, 3.0 * l, -36.0, 3.0 * l],
            [3.0 * l, 4.0 * l2, -3.0 * l, -l2],
            [-36.0, -3.0 * l, 36.0, -3.0 * l],
            [3.0 * l, -l2, -3.0 * l, 4.0 * l2],
        ]
    )
    return Me, Kb, Kg


def _global_shape_vector(x: float, length: float, n_elements: int) -> np.ndarray:
    r"""Global vector :math:`\phi(x)` (all ``2(n_e+1)`` DOFs) with :math:`w(x) = \phi^T q`."""
    try:
        x = float(x)
    except (TypeError, ValueError):
        raise ParameterError(f"position must be a real number, got {x!r}") from None
    tol = 1e-12 * length
    if not math.isfinite(x) or x < -tol or x > length + tol:
        raise ParameterError(f"position x = {x!r} lies outside the beam [0, {length:g}]")
    x = min(max(x, 0.0), length)
    l = length / n_elements
    e = min(int(x / l), n_elements - 1)
    xi = (x - e * l) / l
    phi = np.zeros(2 * (n_elements + 1))
    phi[2 * e : 2 * e + 4] = hermite_shape_functions(xi, l)
    return phi


# --------------------------------------------------------------------------
# assembled model
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class HermiteBeam:
    r"""Assembled and constrained Hermite finite-element beam.

    The semi-discrete equations of motion are
    :math:`M\ddot q + C\dot q + K q = \sum_j \phi(a_j) f_j(t)` in the free
    DOFs :math:`q` (the entries ``free_dofs`` of the global vector
    :math:`(w_0, w'_0, w_1, w'_1, \dots, w_{n_e}, w'_{n_e})`).

    Attributes
    ----------
    M, C, K
        Mass, damping and stiffness matrices (n_free x n_free, read-only).
    free_dofs
        Indices of the unconstrained global DOFs.
    n_elements
        Number of (equal) elements.
    length
        Beam length :math:`L`.
    K_axial
        :math:`\partial K/\partial N = \int N'^T N'\,dx` (free DOFs,
        read-only), so that the stiffness for another axial force
        :math:`N + \Delta N` is ``K + ΔN * K_axial``; also
        :math:`q^T K_{axial} q = \int_0^L w_x^2\,dx`.  ``None`` when the beam
        was built without it.
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    free_dofs: np.ndarray
    n_elements: int
    length: float
    K_axial: np.ndarray | None = None

    def _row(self, x: float) -> np.ndarray:
        return _global_shape_vector(x, self.length, self.n_elements)[self.free_dofs]

    def load_vector(self, x: float) -> np.ndarray:
        r"""Consistent load vector :math:`\phi(x)` of a unit point force at ``x``.

        For :math:`f\,\delta(x - a)`, :math:`\int f\delta(x-a) v\,dx = f\,v(a)`,
        so the nodal load is :math:`f\,\phi(a)` (free DOFs only).
        """
        return self._row(x)

    def displacement_row(self, x: float) -> np.ndarray:
        r"""Output row :math:`\phi(x)^T` with :math:`w(x) = \phi(x)^T q`.

        The same row applied to :math:`\dot q` / :math:`\ddot q` gives the
        velocity / acceleration at ``x``.
        """
        return self._row(x)

    def natural_frequencies_hz(self, n_modes: int | None = None) -> np.ndarray:
        r"""Undamped natural frequencies :math:`f_n = \sqrt{\lambda_n}/2\pi` in Hz.

        :math:`\lambda_n` are the eigenvalues of :math:`K\phi = \lambda M\phi`,
        computed with ``scipy.linalg.eigh``.  When :math:`K` is positive
        definite the *inverted* problem :math:`M\phi = \mu K\phi`,
        :math:`\mu = 1/\lambda`, is solved instead: its absolute round-off is
        of order :math:`\epsilon\,\mu_{\max}` (relative to the *lowest*
        mode), so the low modes stay accurate with fine meshes and with
        penalty-like end springs (e.g. :math:`k \sim 10^{12} EI/L^3`), for
        which the direct problem loses many digits (measured: 1e-9 instead of
        1e-1 relative error for :math:`10^{12}` springs; about 1e-9..3e-7
        instead of 1e-6..2e-4 with 320 elements).  Otherwise (rigid-body modes, buckled beam) the
        direct problem is solved and round-off negatives of rigid-body modes
        are clipped to 0.

        Parameters
        ----------
        n_modes
            Number of lowest modes (all if ``None``).

        Raises
        ------
        ParameterError
            If :math:`K` has a clearly negative eigenvalue (buckled beam).
        """
        n_dof = self.M.shape[0]
        if n_modes is None:
            n = n_dof
        else:
            if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
                raise ParameterError(f"n_modes must be an integer >= 1, got {n_modes!r}")
            n = min(int(n_modes), n_dof)
        try:
            sla.cholesky(self.K, lower=True, check_finite=False)
            k_pd = True
        except np.linalg.LinAlgError:
            k_pd = False
        if k_pd:
            mu = sla.eigh(self.M, self.K, eigvals_only=True, subset_by_index=[n_dof - n, n_dof - 1])
            if np.all(mu > 0.0):
                return np.sort(1.0 / np.sqrt(mu)) / (2.0 * np.pi)
        lam = sla.eigh(self.K, self.M, eigvals_only=True, subset_by_index=[0, n - 1])
        scale = float(np.max(np.abs(np.diag(self.K)) / np.diag(self.M)))
        if lam.size and lam[0] < -1e-9 * scale:
            raise ParameterError(
                "the stiffness matrix is indefinite (beam buckled under compression); "
                "no real natural frequencies"
            )
        return np.sqrt(np.maximum(lam, 0.0)) / (2.0 * np.pi)


def _check_end(name: str, end: tuple[float, float]) -> tuple[float, float]:
    try:
        kt, kr = end
        kt, kr = float(kt), float(kr)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a pair (kt, kr) of spring stiffnesses, got {end!r}") from None
    for k, label in ((kt, "kt"), (kr, "kr")):
        if math.isnan(k) or k < 0.0:
            raise ParameterError(f"{name}.{label} must be in [0, inf], got {k!r}")
    return kt, kr


def _point_matrix(items: Sequence[tuple[float, float]], what: str, pair: str, length: float, ne: int
                  ) -> np.ndarray:
    """``Σ v φ(x) φ(x)ᵀ`` over the ``(v, x)`` pairs of point masses or springs (``v >= 0``, finite)."""
    out = np.zeros((2 * (ne + 1), 2 * (ne + 1)))
    for item in items:
        try:
            v, x = item
        except (TypeError, ValueError):
            raise ParameterError(f"{what} must be a {pair} pair, got {item!r}") from None
        v = finite_scalar(what, v, minimum=0.0)
        phi = _global_shape_vector(x, length, ne)
        out += v * np.outer(phi, phi)
    return out


def hermite_beam(
    length: float,
    n_elements: int,
    *,
    EI: float,
    rhoA: float,
    N: float = 0.0,
    c: float = 0.0,
    eta: float = 0.0,
    left: tuple[float, float] = CLAMPED,
    right: tuple[float, float] = CLAMPED,
    point_masses: Sequence[tuple[float, float]] = (),
    rhoI: float = 0.0,
    kf: float = 0.0,
    point_springs: Sequence[tuple[float, float]] = (),
    weak_segments: Sequence[tuple[float, float, float]] = (),
) -> HermiteBeam:
    r"""Assemble the cubic Hermite finite-element model.

    Parameters
    ----------
    length
        Beam length :math:`L > 0`.
    n_elements
        Number of equal elements (>= 1).
    EI
        Bending stiffness (> 0).
    rhoA
        Mass per unit length (> 0).
    N
        Axial force, tension positive (any finite value; a buckled beam gives
        an indefinite :math:`K`).
    c
        Viscous damping per unit length: :math:`C \mathrel{+}= (c/\rho A) M_{\rho A}`.
    eta
        Kelvin–Voigt retardation time: :math:`C \mathrel{+}= \eta K_b`.
    left, right
        End supports ``(kt, kr)``: translational spring [force/length] and
        rotational spring [moment/rad], each in ``[0, inf]``; ``inf``
        constrains the DOF.  ``CLAMPED = (inf, inf)``, ``PINNED = (inf, 0)``,
        ``FREE = (0, 0)``.
    point_masses
        ``(mass, x)`` pairs; each adds :math:`m\,\phi(x)\phi(x)^T` to
        :math:`M` (consistent with the Hermite interpolation, any
        :math:`x \in [0, L]`).
    rhoI
        Rotary inertia per unit length :math:`\rho I` [kg m] (>= 0):
        :math:`M \mathrel{+}= \int \rho I\, N'^T N'\,dx` (Rayleigh beam).
    kf
        Winkler foundation modulus [N/m²] (>= 0):
        :math:`K \mathrel{+}= \int k_f N^T N\,dx = (k_f/\rho A) M_{\rho A}`.
    weak_segments
        ``(start, end, factor)``: the bending stiffness there is ``factor`` × EI (``0 < factor <= 1``); an
        element partly covered gets the compliance average ``EI/(1 + o (1/factor − 1))`` (``o`` the covered
        fraction) — exact when the segment's ends are element boundaries.
    point_springs
        ``(k, x)`` pairs of translational springs to ground [N/m]; each adds :math:`k\,\phi(x)\phi(x)^T` to
        :math:`K` (any :math:`x \in [0, L]`).

    Returns
    -------
    HermiteBeam
    """
    L = finite_scalar("length", length, minimum=0.0, strict=True)
    if isinstance(n_elements, bool) or not isinstance(n_elements, (int, np.integer)) or n_elements < 1:
        raise ParameterError(f"n_elements must be an integer >= 1, got {n_elements!r}")
    ne = int(n_elements)
    EI = finite_scalar("EI", EI, minimum=0.0, strict=True)
    rhoA = finite_scalar("rhoA", rhoA, minimum=0.0, strict=True)
    N = finite_scalar("N", N)
    c = finite_scalar("c", c, minimum=0.0)
    eta = finite_scalar("eta", eta, minimum=0.0)
    rhoI = finite_scalar("rhoI", rhoI, minimum=0.0)
    kf = finite_scalar("kf", kf, minimum=0.0)
    kt0, kr0 = _check_end("left", left)
    kt1, kr1 = _check_end("right", right)

    l = L / ne
    Me, Kbe, Ge = element_matrices(l, EI, rhoA, 1.0)  # Ge = int N'^T N' (unit axial force)
    ndof = 2 * (ne + 1)
    Mr = np.zeros((ndof, ndof))
    Kb = np.zeros((ndof, ndof))
    G = np.zeros((ndof, ndof))
    compliance = np.ones(ne)
    for item in weak_segments:
        try:
            a, b, f = (float(v) for v in item)
        except (TypeError, ValueError):
            raise ParameterError(f"weak segment must be a (start, end, factor) triple, got {item!r}") from None
        if not (0.0 <= a < b <= L and 0.0 < f <= 1.0):
            raise ParameterError(f"weak segment {item!r}: needs 0 <= start < end <= length and 0 < factor <= 1")
        edges = np.arange(ne + 1) * l
        covered = np.clip(np.minimum(edges[1:], b) - np.maximum(edges[:-1], a), 0.0, None) / l
        compliance += covered * (1.0 / f - 1.0)
    for e in range(ne):
        s = slice(2 * e, 2 * e + 4)
        Mr[s, s] += Me
        Kb[s, s] += Kbe / compliance[e]
        G[s, s] += Ge

    Mp = _point_matrix(point_masses, "point mass", "(mass, x)", L, ne)
    Kp = _point_matrix(point_springs, "point spring", "(k, x)", L, ne)

    Ks = np.zeros((ndof, ndof))
    constrained: list[int] = []
    for (kt, kr), (iw, ir) in (((kt0, kr0), (0, 1)), ((kt1, kr1), (ndof - 2, ndof - 1))):
        for k, i in ((kt, iw), (kr, ir)):
            if math.isinf(k):
                constrained.append(i)
            else:
                Ks[i, i] += k
    free = np.setdiff1d(np.arange(ndof), np.asarray(constrained, dtype=int))
    if free.size == 0:  # pragma: no cover - impossible for ne >= 1
        raise ConfigError("all degrees of freedom are constrained")

    ix = np.ix_(free, free)
    M = (Mr + rhoI * G + Mp)[ix]
    K = (Kb + N * G + (kf / rhoA) * Mr + Ks + Kp)[ix]
    C = ((c / rhoA) * Mr + eta * Kb)[ix]
    K_axial = G[ix]
    for arr in (M, C, K, free, K_axial):
        arr.setflags(write=False)
    return HermiteBeam(M=M, C=C, K=K, free_dofs=free, n_elements=ne, length=L, K_axial=K_axial)
