"""Spatial discretisation: central finite differences with ghost nodes.

Grid
----
``n`` interior points, spacing ``h = L/(n+1)``, nodes ``x_i = i h`` for
``i = 0 … n+1``.  A boundary node is an unknown when its end can translate
(``kt < inf``); ghost nodes ``x_{-1}, x_{-2}`` (and their mirror images at
``x = L``) are eliminated with the boundary conditions.

Stencils (O(h²))
----------------
.. math::

    (D_4 w)_i = \\frac{w_{i-2} - 4w_{i-1} + 6w_i - 4w_{i+1} + w_{i+2}}{h^4},\\qquad
    (D_2 w)_i = \\frac{w_{i-1} - 2w_i + w_{i+1}}{h^2}.

Ghost nodes at the left end (the right end is its mirror image), with
:math:`r = k_r h / (2EI)`:

* moment, ``EI w'' = kr w'``:
  :math:`w_{-1} = (2w_0 + (r-1)w_1)/(1+r)`, and :math:`w_{-1} = w_1` for
  ``kr = inf`` (clamped);
* shear, ``EI w''' - N w' - rhoI w_xtt = -kt w`` (only when ``w_0`` is unknown):
  :math:`w_{-2} = w_2 - 2w_1 + 2w_{-1} - \\tfrac{Nh^2}{EI}(w_1 - w_{-1}) + \\tfrac{2h^3 k_t}{EI} w_0
  - \\tfrac{\\rho I h^2}{EI}(\\ddot w_1 - \\ddot w_{-1})`.  The last (rotary-inertia) part
  involves accelerations and goes into the mass matrix (below); the
  extension ``E`` holds the rest.

Semi-discrete system
--------------------
Each nodal equation is multiplied by its control length ``V_i`` (``h``
inside, ``h/2`` at a boundary node that is an unknown), giving

.. math::  M \\ddot q + C \\dot q + K q = F f(t),

with :math:`M = \\rho A\\,\\mathrm{diag}(V) + \\rho I\\, M_r + \\sum_m m_m \\phi(a_m)\\phi(a_m)^T`,
:math:`K = \\mathrm{diag}(V)(EI D_4 - N D_2)E + k_f\\,\\mathrm{diag}(V)`,
:math:`C = c\\,\\mathrm{diag}(V) + \\eta EI\\,\\mathrm{diag}(V) D_4 E`
(``E`` maps unknowns to the extended vector with ghosts; the Kelvin–Voigt
term uses the same ghost relations as the displacement, which is exact for
clamped and pinned ends and neglects an ``η N ẇ'`` term under axial load —
and, with rotary inertia, an ``η ρI ẇ_xtt`` term — at free/elastic ends).

Rotary inertia: the row of unknown ``i`` gets :math:`-\\rho I\\,V_i (D_2 \\ddot w)_i`
(with ``ẅ_0 = 0`` where an end cannot translate).  At an end that can
translate, the rotary-inertia part of the shear ghost ``w_{-2}`` adds
:math:`-\\tfrac{\\rho I}{2h}(\\ddot w_1 - \\ddot w_{-1})` to row 0 (through
``EI V_0 D_4``); its ``ẅ_{-1}`` cancels the one of the ``D_2`` stencil whatever
the moment condition, leaving :math:`\\tfrac{\\rho I}{h}(\\ddot w_0 - \\ddot w_1)`.
Hence, exactly, :math:`M_r = h\\,(GP)^T(GP)` with ``G`` the slopes
:math:`(w_{i+1} - w_i)/h` of the ``n + 1`` cells and ``P`` the
unknowns-to-grid map: the kinetic energy :math:`\\tfrac12\\rho I\\int \\dot w_x^2\\,dx`
of the piecewise-linear interpolant, so ``M`` stays symmetric positive
definite (:func:`rotary_mass`).  The Winkler foundation is lumped like the
translational mass, :math:`k_f\\,\\mathrm{diag}(V)`, and enters no boundary
condition.

Springs to ground add :math:`\\sum_s k_s \\phi(a_s)\\phi(a_s)^T` to ``K`` in the same way.

Weak segments (a local loss of bending stiffness): the bending term is written as the second difference of the
nodal moments, :math:`(D_4 w)_i \\to \\big(D_2 (e\\,D_2 w)\\big)_i / EI` with :math:`e_j = EI_j` the stiffness
of node ``j``'s cell (:func:`cell_stiffness`: compliance-averaged over the part of the cell a segment covers, as
flexibilities in series add), the ghost nodes' taken from their boundary node.  With a uniform ``EI`` this is the
:math:`D_4` stencil exactly; the boundary conditions use the nominal ``EI`` (a segment reaching an end is an
approximation there).  The Kelvin–Voigt term follows the local stiffness.

Point forces, point masses and sensors use the piecewise
linear "hat" functions :math:`\\phi_i(x)` of the grid, so a force between nodes
is shared by its two neighbours with weights summing to one (consistent load
distribution) and a collocated sensor/actuator pair is reciprocal.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..beam import End, PointMass, PointSpring, WeakSegment
from ..config import BeamConfig
from ..errors import ParameterError
from ..memo import memoised
from ..parameter_values import resolve_parameters

#: The largest point mass, in units of the beam's mass per grid cell ``ρA h``, that keeps the mass matrix
#: numerically positive definite (its Cholesky factor fails from about ``1/eps ≈ 1e16``).
MAX_MASS_RATIO = 1e12
#: The stiffest spring to ground, in units of a grid cell's bending stiffness ``EI/h³``, that keeps the
#: stiffness matrix's condition (and with it the modes' round-off) within what a constrained node would give.
MAX_SPRING_RATIO = 1e12

__all__ = ["SemiDiscreteBeam", "discretise", "grid_nodes", "hat_weights", "rotary_mass", "cell_stiffness",
           "check_attachments", "load_rows", "control_lengths", "unknown_nodes", "Grid", "grid", "assemble_matrices"]


@dataclass(frozen=True)
class SemiDiscreteBeam:
    """The semi-discrete beam ``M q'' + C q' + K q = F u``, ``y_pos = S q``.

    Attributes
    ----------
    M, C, K
        Mass, damping and stiffness matrices (n_u × n_u), symmetric for the
        supported boundary conditions.
    F
        Load matrix (n_u × n_inputs): hat-function weights of the actuators.
    S
        Sensor position matrix (n_outputs × n_u): hat-function weights.
    sensor_kinds
        Kind of each output (displacement, velocity, acceleration).
    x
        Positions of all grid nodes ``0 … n+1`` [m].
    unknown
        Indices (into ``x``) of the nodes that are unknowns.
    input_names, output_names
        Actuator and sensor names (the columns of ``F``, the rows of ``S``).
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    F: np.ndarray
    S: np.ndarray
    sensor_kinds: tuple[str, ...]
    x: np.ndarray
    unknown: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]

    @property
    def n_unknowns(self) -> int:
        """Number of nodal unknowns."""
        return self.M.shape[0]

    def field_rows(self) -> np.ndarray:
        """Matrix (n_nodes × n_u) mapping unknowns to the deflection at every grid node."""
        P = np.zeros((self.x.size, self.n_unknowns))
        P[self.unknown, np.arange(self.n_unknowns)] = 1.0
        return P


def grid_nodes(length: float, nodes: int) -> np.ndarray:
    """Positions of the ``nodes + 2`` grid points (interior plus both boundaries)."""
    return np.linspace(0.0, length, nodes + 2)


def hat_weights(x: float, length: float, nodes: int) -> np.ndarray:
    """Piecewise-linear interpolation weights of point ``x`` on the full grid.

    Returns a vector over the ``nodes + 2`` grid points with at most two
    non-zero entries, summing to one.
    """
    h = length / (nodes + 1)
    w = np.zeros(nodes + 2)
    s = x / h
    i = min(int(math.floor(s)), nodes)  # left node of the cell, last cell closed
    t = s - i
    w[i] += 1.0 - t
    w[i + 1] += t
    return w


def rotary_mass(nodes: int, h: float, unknown: np.ndarray) -> np.ndarray:
    """Rotary-inertia mass matrix per unit ``rhoI``: ``h (G P)ᵀ (G P)``.

    Parameters
    ----------
    nodes
        Number of interior grid points ``n``.
    h
        Grid spacing [m].
    unknown
        Indices (into the ``n + 2`` grid nodes) of the nodal unknowns; the
        other nodes are held at zero.

    Returns
    -------
    numpy.ndarray
        Symmetric positive semi-definite (n_u × n_u) matrix, ``1/h`` times the
        grid's graph Laplacian: ``2`` on the diagonal of an interior unknown,
        ``1`` at a boundary unknown, ``-1`` between neighbours.  It equals
        ``-diag(V) D_2`` plus the rotary-inertia part of the shear ghost
        relation (see the module docstring).
    """
    unknown = np.asarray(unknown)
    # cells adjacent to each unknown's node: 1 at a boundary node, 2 inside
    cells = np.where((unknown == 0) | (unknown == nodes + 1), 1.0, 2.0)
    Mr = np.diag(cells / h)
    nb = np.flatnonzero(np.diff(unknown) == 1)  # neighbouring unknowns share a cell
    Mr[nb, nb + 1] = Mr[nb + 1, nb] = -1.0 / h
    return Mr


def cell_stiffness(length: float, nodes: int, segments) -> np.ndarray:
    """Relative bending stiffness ``EI_j/EI`` of each grid node's cell (``nodes + 2`` values): ``1/(1 + Σ_s o_s
    (1/f_s − 1))`` with ``o_s`` the fraction of the cell (half a cell at a boundary node) that segment ``s`` of
    factor ``f_s`` covers — flexibilities in series add."""
    h = length / (nodes + 1)
    x = grid_nodes(length, nodes)
    lo, hi = np.clip(x - h / 2, 0.0, length), np.clip(x + h / 2, 0.0, length)
    compliance = np.ones(nodes + 2)
    for seg in segments:
        a, b = seg.ends
        covered = np.clip(np.minimum(hi, b) - np.maximum(lo, a), 0.0, None) / (hi - lo)
        compliance += covered * (1.0 / seg.factor - 1.0)
    return 1.0 / compliance


def _bending(n: int, h: float, rows: np.ndarray, E: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``D_2 (e D_2 w)`` on the extended numbering (rows: the unknowns' extended rows), ``e`` over the grid
    nodes, mirrored onto the ghost nodes ``-1`` and ``n + 2``."""
    ext = np.concatenate([[1.0, e[0]], e, [e[-1], 1.0]])      # extended indices 0 … n+5 (nodes -2 … n+3)
    n_ext = n + 6
    C2 = _stencil_rows(np.arange(1, n_ext - 1), n_ext, _SECOND)
    moments = np.zeros((n_ext, E.shape[1]))
    moments[1:-1] = ext[1:-1, None] * (C2 @ E)
    return (_stencil_rows(rows, n_ext, _SECOND) @ moments) / h ** 4


#: Central-difference stencils: second and fourth differences (times ``h²``, ``h⁴``).
_SECOND = np.array([1.0, -2.0, 1.0])
_FOURTH = np.array([1.0, -4.0, 6.0, -4.0, 1.0])


def _stencil_rows(rows: np.ndarray, n_ext: int, taps: np.ndarray) -> np.ndarray:
    """One row per entry of ``rows`` (indices on the extended numbering, ``n_ext`` columns) with the centred
    stencil ``taps`` around it."""
    half = taps.size // 2
    out = np.zeros((rows.size, n_ext))
    out[np.arange(rows.size)[:, None], rows[:, None] + np.arange(-half, half + 1)] = taps
    return out


def _apply(D: np.ndarray, E: np.ndarray, unknown: np.ndarray, ghost: np.ndarray) -> np.ndarray:
    """``D @ E`` for the extension ``E`` (identity on the unknowns' rows, zero on fixed nodes' rows, the ghost
    relations on the rows ``ghost``): the unknowns' columns of ``D`` plus its ghost columns through ``E``."""
    return D[:, unknown + 2] + D[:, ghost] @ E[ghost]


def _extension(n: int, h: float, EI: float, N: float, left, right, unknown: np.ndarray) -> np.ndarray:
    """Matrix E mapping unknowns to grid values on indices -2 … n+3 (offset +2)."""
    n_ext = n + 6
    E = np.zeros((n_ext, unknown.size))
    E[unknown + 2, np.arange(unknown.size)] = 1.0

    def ghosts(end, b: int, s: int) -> None:
        # b: boundary node index, s: +1 going inwards.  Rows in the extended
        # numbering: node k -> row k + 2.
        row = lambda k: k + 2  # noqa: E731
        w0, w1, w2 = E[row(b)], E[row(b + s)], E[row(b + 2 * s)]
        if end.rotation_fixed:
            wg1 = w1.copy()
        else:
            r = end.kr * h / (2.0 * EI)
            wg1 = (2.0 * w0 + (r - 1.0) * w1) / (1.0 + r)
        E[row(b - s)] = wg1
        if not end.translation_fixed:
            wg2 = (w2 - 2.0 * w1 + 2.0 * wg1 - (N * h * h / EI) * (w1 - wg1)
                   + (2.0 * h ** 3 * end.kt / EI) * w0)
            E[row(b - 2 * s)] = wg2

    ghosts(left, 0, +1)
    ghosts(right, n + 1, -1)
    return E


def discretise(config: BeamConfig, params: Mapping[str, float] | None = None) -> SemiDiscreteBeam:
    """Assemble the finite-difference semi-discrete beam.

    Parameters
    ----------
    config
        The validated set-up.
    params
        Physical parameters overriding the config's nominal values
        (any subset of ``EI, rhoA, c, eta, N, rhoI, kf``).

    Returns
    -------
    SemiDiscreteBeam

    Raises
    ------
    ParameterError
        When a parameter is missing, non-finite or out of its physical range, or a point mass so heavy (a
        spring so stiff) that the mass (stiffness) matrix would be numerically singular.
    """
    p = resolve_parameters(config, params)
    check_attachments(config, p)
    g = config.beam
    M, C, K, unknown = assemble_matrices(g.length, g.nodes, g.left, g.right, config.masses, config.springs,
                                         config.weak_segments, p)
    F, S, _ = load_rows(config, g.nodes)
    return SemiDiscreteBeam(
        M=M, C=C, K=K, F=F, S=S,
        sensor_kinds=tuple(s.kind for s in config.sensors),
        x=grid_nodes(g.length, g.nodes), unknown=unknown,
        input_names=config.input_names, output_names=config.output_names,
    )


def check_attachments(config: BeamConfig, p: Mapping[str, float], nodes: int | None = None) -> None:
    """Raise :class:`ParameterError` for a point mass too heavy (a spring too stiff) for the grid of ``nodes``
    interior points (default: the config's): the mass (stiffness) matrix would be numerically singular."""
    h = config.beam.length / ((config.beam.nodes if nodes is None else nodes) + 1)
    rhoA, EI = p["rhoA"], p["EI"]
    for m in config.masses:
        if m.mass > MAX_MASS_RATIO * rhoA * h:
            raise ParameterError(f"masses.{m.name}: {m.mass:g} kg is more than {MAX_MASS_RATIO:g} times the "
                                 f"beam's mass per grid cell ({rhoA * h:g} kg): the mass matrix would be "
                                 f"numerically singular")
    for sp in config.springs:
        if sp.k > MAX_SPRING_RATIO * EI / h ** 3:
            raise ParameterError(f"springs.{sp.name}: {sp.k:g} N/m is more than {MAX_SPRING_RATIO:g} times a grid "
                                 f"cell's bending stiffness EI/h^3 = {EI / h ** 3:g} N/m: the stiffness matrix would "
                                 f"be numerically singular (a rigid support is an end condition)")


def load_rows(config: BeamConfig, nodes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, S, J)``: the actuators' load columns and the sensors' position rows (hat weights) on the grid of
    ``nodes`` interior points, restricted to its unknown nodes, and the unknowns ``J`` where either has an entry
    (memoised per process on the positions: read-only arrays)."""
    g = config.beam
    return _load_rows((g.length, nodes, g.left.translation_fixed, g.right.translation_fixed,
                       tuple(a.x for a in config.actuators), tuple(s.x for s in config.sensors)))


@memoised
def _load_rows(key: tuple[float, int, bool, bool, tuple[float, ...], tuple[float, ...]]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`load_rows` of ``key = (length, nodes, left end fixes translation, right end fixes translation,
    actuator positions, sensor positions)``."""
    length, nodes, left_fixed, right_fixed, actuators, sensors = key
    unknown = _grid((length, nodes, left_fixed, right_fixed)).unknown
    nu = unknown.size
    F = np.column_stack([hat_weights(x, length, nodes)[unknown] for x in actuators]) if actuators \
        else np.zeros((nu, 0))
    S = np.vstack([hat_weights(x, length, nodes)[unknown] for x in sensors]) if sensors else np.zeros((0, nu))
    J = np.flatnonzero(np.any(F != 0.0, axis=1) | np.any(S != 0.0, axis=0))
    for a in (F, S, J):
        a.setflags(write=False)
    return F, S, J


def control_lengths(n: int, h: float, left: End, right: End) -> np.ndarray:
    """Each unknown's control length ``V_i``: ``h`` inside, ``h/2`` at a boundary node that is an unknown."""
    first = 0 if left.translation_fixed else 1
    last = 0 if right.translation_fixed else 1
    V = np.full(n + first + last, h)
    if first:
        V[0] = h / 2.0
    if last:
        V[-1] = h / 2.0
    return V


def unknown_nodes(n: int, left: End, right: End) -> np.ndarray:
    """The unknown nodes of a grid of ``n`` interior points (``0 … n + 1``): the interior ones, and an end node
    whose translation is not fixed."""
    return np.arange(1 if left.translation_fixed else 0, (n if right.translation_fixed else n + 1) + 1)


@dataclass(frozen=True, eq=False)
class Grid:
    """A grid of ``n`` interior points: its nodes ``x`` (ends included), the ``unknown`` nodes
    (:func:`unknown_nodes`) and their control lengths ``V`` (:func:`control_lengths`).  Read-only arrays."""

    x: np.ndarray
    unknown: np.ndarray
    V: np.ndarray


def grid(length: float, n: int, left: End, right: End) -> Grid:
    """The :class:`Grid` of a beam of ``length`` on ``n`` interior points with these ends (memoised per process:
    it depends on whether each end fixes the translation only)."""
    return _grid((length, n, left.translation_fixed, right.translation_fixed))


@memoised
def _grid(key: tuple[float, int, bool, bool]) -> Grid:
    """The :class:`Grid` of ``key = (length, n, left end fixes translation, right end fixes translation)``."""
    length, n, *fixed = key
    left, right = (End.of("pinned") if f else End.of("free") for f in fixed)
    out = Grid(grid_nodes(length, n), unknown_nodes(n, left, right), control_lengths(n, length / (n + 1), left, right))
    for a in (out.x, out.unknown, out.V):
        a.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class _Operators:
    """What :func:`assemble_matrices` needs of a grid besides the parameter values: the ``unknown`` nodes, their
    control lengths ``V``, the bending operator ``B4 = diag(V) D_4 E`` (per unit ``EI``; :func:`_bending` with
    weak segments) and the axial one ``A2 = diag(V) D_2 E``.  Read-only arrays."""

    unknown: np.ndarray
    V: np.ndarray
    B4: np.ndarray
    A2: np.ndarray


@memoised
def _operators(key: tuple) -> _Operators:
    """The :class:`_Operators` of ``key = (length, n, left, right, segments, EI, N)`` (memoised per process:
    every parameter set on a grid shares them; ``EI`` and ``N`` are ``None`` where the ghost relations do not
    read them, so they are shared across those values too)."""
    length, n, left, right, segments, EI, N = key
    h = length / (n + 1)
    g = grid(length, n, left, right)
    unknown, V = g.unknown, g.V
    E = _extension(n, h, 1.0 if EI is None else EI, 0.0 if N is None else N, left, right, unknown)
    rows = unknown + 2
    ghost = np.array([0, 1, n + 4, n + 5])     # the ghost nodes -2, -1, n+2, n+3 on the extended numbering
    # D4 and D2 rows on the extended numbering, one row per unknown node
    D4 = _stencil_rows(rows, n + 6, _FOURTH) / h ** 4
    D2 = _stencil_rows(rows, n + 6, _SECOND) / h ** 2
    if segments:
        B4 = V[:, None] * _bending(n, h, rows, E, cell_stiffness(length, n, segments))
    else:
        B4 = V[:, None] * _apply(D4, E, unknown, ghost)
    A2 = V[:, None] * _apply(D2, E, unknown, ghost)
    for a in (unknown, V, B4, A2):
        a.setflags(write=False)
    return _Operators(unknown, V, B4, A2)


def assemble_matrices(length: float, n: int, left: End, right: End, masses: Sequence[PointMass],
                      springs: Sequence[PointSpring], segments: Sequence[WeakSegment], p: Mapping[str, float]
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(M, C, K, unknown)`` of the beam of ``length`` on ``n`` interior points with the values ``p`` (``EI``,
    ``rhoA``, ``c``, ``eta``, ``N``, ``rhoI``, ``kf``; taken as they are, unchecked: :func:`discretise` checks
    them) — the module docstring's matrices."""
    EI, rhoA, c, eta, N = p["EI"], p["rhoA"], p["c"], p["eta"], p["N"]
    rhoI, kf = p["rhoI"], p["kf"]
    h = length / (n + 1)
    # the ghost relations read EI at an elastic or free end and N at a free end only
    free = not (left.translation_fixed and right.translation_fixed)
    elastic = free or any(not e.rotation_fixed and e.kr != 0.0 for e in (left, right))
    ops = _operators((length, n, left, right, tuple(segments), EI if elastic else None, N if free else None))
    unknown, V, B4 = ops.unknown.copy(), ops.V, ops.B4
    nu = unknown.size
    K = EI * B4 - N * ops.A2
    C = eta * EI * B4
    K[np.diag_indices(nu)] += kf * V
    C[np.diag_indices(nu)] += c * V
    M = np.diag(rhoA * V)
    if rhoI != 0.0:
        M += rhoI * rotary_mass(n, h, unknown)
    for m in masses:
        phi = hat_weights(m.x, length, n)[unknown]
        M += m.mass * np.outer(phi, phi)
    for sp in springs:
        phi = hat_weights(sp.x, length, n)[unknown]
        K += sp.k * np.outer(phi, phi)
    # symmetrise away round-off (the exact matrices are symmetric)
    K = 0.5 * (K + K.T)
    C = 0.5 * (C + C.T)
    return M, C, K, unknown
