"""Dispersion relation of the θ-scheme and the stability analysis built on it.

Von Neumann ansatz on the unbounded grid, :math:`w_j^n = z^n e^{i\\kappa j h}`,
in the interior stencil of :mod:`ebb_model.space.discretisation` and
:mod:`ebb_model.theta.theta_scheme` gives, per wavenumber κ, a quadratic in the
temporal growth factor ``z`` (per sub-step ``τ``):

.. math::

    p_\\kappa(z) = a z^2 + b z + c,\\qquad
    \\begin{aligned}
    a &= m + \\tfrac{\\tau}{2} d + \\theta\\tau^2 k,\\\\
    b &= -2m + (1-2\\theta)\\tau^2 k,\\\\
    c &= m - \\tfrac{\\tau}{2} d + \\theta\\tau^2 k,
    \\end{aligned}

with :math:`s_2 = \\tfrac{4}{h^2}\\sin^2\\tfrac{\\kappa h}{2}` (the symbol of
:math:`-D_2`), :math:`s_4 = s_2^2`, mass symbol :math:`m = \\rho A + \\rho I s_2`
(rotary inertia), stiffness symbol :math:`k = EI s_4 + N s_2 + k_f` (Winkler
foundation) and damping symbol :math:`d = c + \\eta EI s_4`.

For degree two the Bistritz sequence evaluated at ``z = 1`` is
:math:`T_2(1) = 2(a+b+c) = 2\\tau^2 k`, :math:`T_1(1) = 2(a-c) = 2\\tau d`,
:math:`T_0 = 2(a-b+c) = 2(4m + (4\\theta - 1)\\tau^2 k)`; no zero lies
outside the unit circle iff all three are ≥ 0.  Each is *affine* in every
physical parameter, so the conditions give closed-form parameter bounds
(:func:`stability_bounds`), and a polynomial of degree ≤ 2 in ``s_2``, so
its minimum over the wavenumber range lies at an end of the range or at the
polynomial's vertex (:func:`critical_wavenumbers`).  The same quadratic with
``m = 1``, ``k = ω_i²`` and ``d = ξ_i`` (mass-normalised modal stiffness and
damping) is the exact characteristic polynomial of mode ``i`` of the finite
beam under proportional damping.

The wavenumbers are those that fit the beam, ``π/L ≤ κ ≤ π/h``.  Under
compression the unbounded-grid analysis is conservative: it flags
``N < -min_{s_2} (EI s_2 + k_f/s_2)`` over the range — the pinned–pinned
Euler load of the grid ``EI s_2(π/L)`` without foundation, the classical
``2√(EI k_f)`` at ``s_2 = √(k_f/EI)`` when that lies inside the range — even
when the ends make the finite beam stiffer; :func:`analyse_stability`
reports such disagreements.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping, cast

import numpy as np

from ..beam import PARAMETER_NAMES
from ..config import BeamConfig
from ..parameter_values import resolve_parameters
from .bistritz import bistritz

#: Relative zero tolerance of the Bistritz test on the dispersion polynomials.
_BISTRITZ_TOL = 16 * np.finfo(float).eps

#: Physical lower limits of the parameters (the upper ones are all infinite).
_PHYSICAL_LOWER = MappingProxyType({"EI": 0.0, "rhoA": 0.0, "c": 0.0, "eta": 0.0, "N": -math.inf,
                                    "rhoI": 0.0, "kf": 0.0})

__all__ = [
    "wavenumbers",
    "critical_wavenumbers",
    "dispersion_coefficients",
    "growth_factors",
    "max_growth_factor",
    "bistritz_values",
    "grid_omega_max",
    "stability_bounds",
    "StabilityReport",
    "analyse_stability",
]


def wavenumbers(length: float, nodes: int, n: int = 257) -> np.ndarray:
    """``n`` wavenumbers from ``π/L`` to the grid's Nyquist ``π/h`` (both included)."""
    h = length / (nodes + 1)
    return np.linspace(math.pi / length, math.pi / h, n)


def _symbols(kappa: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    s2 = 4.0 / h ** 2 * np.sin(kappa * h / 2) ** 2
    return s2, s2 * s2


def _kappa_of_s2(s2: np.ndarray, h: float) -> np.ndarray:
    """Inverse of ``s2(κ)`` on ``0 ≤ κ ≤ π/h``."""
    return 2.0 / h * np.arcsin(np.clip(np.sqrt(np.maximum(s2, 0.0)) * h / 2, 0.0, 1.0))


def _get(p: Mapping[str, float], name: str) -> float:
    # rhoI and kf default to 0 so that dicts of the original five parameters still work
    return float(p[name]) if name in p else 0.0


def dispersion_coefficients(params: Mapping[str, float], *, h: float, tau: float, theta: float,
                            kappa: np.ndarray) -> np.ndarray:
    """Coefficients ``[a, b, c]`` (highest power first) of ``p_κ(z)``, shape (n_κ, 3).

    ``params`` needs ``EI, rhoA, c, eta, N``; ``rhoI`` and ``kf`` are 0 when absent.
    """
    p = params
    s2, s4 = _symbols(np.asarray(kappa, dtype=float), h)
    k = p["EI"] * s4 + p["N"] * s2 + _get(p, "kf")
    d = p["c"] + p["eta"] * p["EI"] * s4
    m = p["rhoA"] + _get(p, "rhoI") * s2
    a = m + tau / 2 * d + theta * tau ** 2 * k
    b = -2 * m + (1 - 2 * theta) * tau ** 2 * k
    c = m - tau / 2 * d + theta * tau ** 2 * k
    return np.stack([a, b, c], axis=-1)


def growth_factors(coeffs: np.ndarray) -> np.ndarray:
    """Largest root modulus ``max |z|`` of each quadratic row ``[a, b, c]`` (closed form)."""
    a, b, c = coeffs[..., 0], coeffs[..., 1], coeffs[..., 2]
    disc = np.sqrt((b * b - 4 * a * c).astype(complex))
    z1 = (-b + disc) / (2 * a)
    z2 = (-b - disc) / (2 * a)
    return np.maximum(np.abs(z1), np.abs(z2))


def bistritz_values(coeffs: np.ndarray) -> np.ndarray:
    """Bistritz values ``(T_2(1), T_1(1), T_0(1))`` of each quadratic, shape (n, 3)."""
    a, b, c = coeffs[..., 0], coeffs[..., 1], coeffs[..., 2]
    return np.stack([2 * (a + b + c), 2 * (a - c), 2 * (a - b + c)], axis=-1)


def _bistritz_polynomials(p: Mapping[str, float], tau: float, theta: float
                          ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The Bistritz values as polynomials in ``s2`` and their exact parameter derivatives.

    Returns
    -------
    T : numpy.ndarray
        Shape (3, 3): rows ``T_2(1), T_1(1), T_0(1)``, each the coefficients of
        a polynomial of degree ≤ 2 in ``s2`` (highest power first):
        ``T_2 = 2τ²k``, ``T_1 = 2τd``, ``T_0 = 8m + β k`` with ``β = 2(4θ-1)τ²``,
        ``k = EI s2² + N s2 + kf``, ``d = eta EI s2² + c``, ``m = rhoI s2 + rhoA``.
    der : dict
        ``{name: dT/d(name)}``, same shape (each ``T`` is affine in each parameter).
    """
    EI, N, kf = p["EI"], p["N"], _get(p, "kf")
    rhoA, rhoI, c, eta = p["rhoA"], _get(p, "rhoI"), p["c"], p["eta"]
    t2, t1 = 2 * tau ** 2, 2 * tau
    beta = 2 * (4 * theta - 1) * tau ** 2

    def rows(k: tuple[float, float, float], d: tuple[float, float, float],
             m: tuple[float, float, float]) -> np.ndarray:
        k_, d_, m_ = np.asarray(k, float), np.asarray(d, float), np.asarray(m, float)
        return np.stack([t2 * k_, t1 * d_, 8 * m_ + beta * k_])

    zero = (0.0, 0.0, 0.0)
    T = rows((EI, N, kf), (eta * EI, 0.0, c), (0.0, rhoI, rhoA))
    der = {
        "EI": rows((1.0, 0.0, 0.0), (eta, 0.0, 0.0), zero),
        "rhoA": rows(zero, zero, (0.0, 0.0, 1.0)),
        "c": rows(zero, (0.0, 0.0, 1.0), zero),
        "eta": rows(zero, (EI, 0.0, 0.0), zero),
        "N": rows((0.0, 1.0, 0.0), zero, zero),
        "rhoI": rows(zero, zero, (0.0, 1.0, 0.0)),
        "kf": rows((0.0, 0.0, 1.0), zero, zero),
    }
    return T, der


def _s2_range(config: BeamConfig) -> tuple[float, float]:
    h = config.beam.length / (config.beam.nodes + 1)
    s2, _ = _symbols(wavenumbers(config.beam.length, config.beam.nodes, 2), h)
    return float(s2[0]), float(s2[1])


def _interior_roots(poly: np.ndarray, lo: float, hi: float) -> list[float]:
    """Real roots of ``poly`` (highest power first) strictly inside ``(lo, hi)``."""
    poly = np.trim_zeros(np.asarray(poly, dtype=float), "f")
    if poly.size < 2:
        return []
    out = []
    for r in np.roots(poly):
        if abs(r.imag) <= 1e-12 * max(1.0, abs(r.real)) and lo < r.real < hi:
            out.append(float(r.real))
    return out


def critical_wavenumbers(config: BeamConfig, params: Mapping[str, float] | None = None) -> np.ndarray:
    """Wavenumbers inside ``(π/L, π/h)`` where a Bistritz value is stationary in ``s_2``.

    Each Bistritz value is a polynomial of degree ≤ 2 in ``s_2`` (a monotone
    function of κ), so its minimum over the range lies at an end or at its
    vertex.  The ends are always sampled; these are the vertices inside.
    Without a foundation they only occur beyond the grid's Euler load; with
    one, the vertex of ``k`` at ``s_2 = -N/(2EI)`` is where a compressed beam
    on a Winkler foundation buckles first.
    """
    p = resolve_parameters(config, params)
    tau = config.time.dt / config.time.substeps
    lo, hi = _s2_range(config)
    T, _ = _bistritz_polynomials(p, tau, config.time.theta)
    s2 = sorted({r for row in T for r in _interior_roots(np.polyder(row), lo, hi)})
    h = config.beam.length / (config.beam.nodes + 1)
    return _kappa_of_s2(np.asarray(s2, dtype=float), h)


def _analysis_kappas(config: BeamConfig, p: Mapping[str, float], n_kappa: int) -> np.ndarray:
    kap = wavenumbers(config.beam.length, config.beam.nodes, n_kappa)
    crit = critical_wavenumbers(config, p)
    return np.sort(np.concatenate([kap, crit])) if crit.size else kap


def max_growth_factor(config: BeamConfig, params: Mapping[str, float] | None = None,
                      *, n_kappa: int = 257) -> float:
    """The seed's stabilising objective: ``max_κ max |z|`` on the unbounded grid.

    Evaluated at ``n_kappa`` equidistant wavenumbers in ``[π/L, π/h]`` plus
    the :func:`critical_wavenumbers`.
    """
    p = resolve_parameters(config, params)
    h = config.beam.length / (config.beam.nodes + 1)
    tau = config.time.dt / config.time.substeps
    co = dispersion_coefficients(p, h=h, tau=tau, theta=config.time.theta,
                                 kappa=_analysis_kappas(config, p, n_kappa))
    return float(np.max(growth_factors(co)))


def stability_bounds(config: BeamConfig, params: Mapping[str, float] | None = None
                     ) -> dict[str, tuple[float, float]]:
    """Interval of each parameter (others held) where the Bistritz conditions hold.

    Each Bistritz value is affine in each parameter,
    ``T(s2; p) = T(s2; p0) + T'(s2)·(p - p0)`` with the exact derivative ``T'``
    (see :func:`_bistritz_polynomials`; ``T'`` has one sign for ``s2 > 0``), so
    ``T ≥ 0`` at every ``s2`` of the range gives ``p ≥ sup r`` (``T' > 0``) or
    ``p ≤ inf r`` (``T' < 0``) with ``r(s2) = p0 - T/T'``.  ``r`` is a ratio of
    polynomials of degree ≤ 2, so its extremes over ``[s2(π/L), s2(π/h)]`` lie
    at the ends or where ``T'·dT/ds2 - T·dT'/ds2 = 0`` — e.g. the foundation's
    critical load ``N = -2√(EI k_f)`` at ``s2 = √(k_f/EI)``.  Where ``T' ≡ 0``
    the condition ``T ≥ 0`` does not depend on the parameter.  The physical
    ranges (``EI, rhoA > 0``; ``c, eta, rhoI, kf ≥ 0``) are intersected in.

    Returns
    -------
    dict
        ``{name: (lo, hi)}`` for every name of ``PARAMETER_NAMES``; infinite
        where unbounded; ``(nan, nan)`` when no value of that parameter alone
        can satisfy the conditions (another parameter violates one that does
        not depend on it).
    """
    p0 = resolve_parameters(config, params)
    tau = config.time.dt / config.time.substeps
    s_lo, s_hi = _s2_range(config)
    T, der = _bistritz_polynomials(p0, tau, config.time.theta)
    out: dict[str, tuple[float, float]] = {}
    for name in PARAMETER_NAMES:
        lo, hi = _PHYSICAL_LOWER[name], math.inf
        feasible = True
        for P, Q in zip(T, der[name]):
            if not np.any(Q):
                cand = [s_lo, s_hi] + _interior_roots(np.polyder(P), s_lo, s_hi)
                if min(np.polyval(P, s) for s in cand) < 0:
                    feasible = False
                continue
            crit = np.polysub(np.polymul(Q, np.polyder(P)), np.polymul(P, np.polyder(Q)))
            for s in [s_lo, s_hi] + _interior_roots(crit, s_lo, s_hi):
                q = np.polyval(Q, s)
                # a float64 scalar (s is a float; numpy's stub types polyval's value as an array)
                r = cast(float, p0[name] - np.polyval(P, s) / q)
                if q > 0:
                    lo = max(lo, r)
                else:
                    hi = min(hi, r)
        out[name] = (float(lo), float(hi)) if feasible and lo <= hi else (math.nan, math.nan)
    return out


def grid_omega_max(config: BeamConfig, params: Mapping[str, float] | None = None) -> float:
    """Highest angular frequency of the semi-discrete unbounded grid [rad/s].

    ``ω²(s2) = k/m = (EI s2² + N s2 + kf) / (rhoA + rhoI s2)``; its derivative
    has the sign of ``EI rhoI s2² + 2 EI rhoA s2 + N rhoA - rhoI kf``, which
    increases with ``s2``, so the maximum over the range lies at one of its
    ends (at the Nyquist wavenumber ``π/h`` unless the grid is very coarse).
    Rotary inertia lowers it: ``ω_max² ≈ 4EI/(h² rhoI)`` once ``rhoI ≫ rhoA h²/4``.
    Returns 0 when ``k ≤ 0`` at both ends.
    """
    p = resolve_parameters(config, params)
    w2 = max((p["EI"] * s * s + p["N"] * s + p["kf"]) / (p["rhoA"] + p["rhoI"] * s) for s in _s2_range(config))
    return math.sqrt(w2) if w2 > 0 else 0.0


@dataclass(frozen=True)
class StabilityReport:
    """Outcome of :func:`analyse_stability`.

    Attributes
    ----------
    max_growth_factor
        ``max_κ max|z|`` per sub-step on the unbounded grid (the stabilising objective).
    grid_stable
        Bistritz verdict over all wavenumbers: no zero outside the unit circle.
    marginal
        Some zeros lie on the unit circle (e.g. undamped).
    spectral_radius
        Spectral radius of Φ (per sample) of the finite beam.
    beam_stable
        ``spectral_radius ≤ 1`` (within round-off).
    bounds
        Parameter bounds implied by the Bistritz conditions (others held).
    dt_max
        Largest stable sample time (``inf`` for ``θ ≥ 1/4``).
    messages
        Human-readable findings, including disagreements between the grid and the beam.
    """

    max_growth_factor: float
    grid_stable: bool
    marginal: bool
    spectral_radius: float
    beam_stable: bool
    bounds: dict[str, tuple[float, float]]
    dt_max: float
    messages: tuple[str, ...] = field(default=())

    @property
    def stable(self) -> bool:
        """The finite beam's verdict (what a simulation will do)."""
        return self.beam_stable

    @property
    def agree(self) -> bool:
        """Whether the unbounded-grid and finite-beam verdicts agree."""
        return self.grid_stable == self.beam_stable


def _dt_max(p: Mapping[str, float], config: BeamConfig) -> float:
    """Largest stable sample time of the grid for ``θ < 1/4``: ``τ ≤ 2/(ω_max √(1-4θ))``."""
    theta = config.time.theta
    if theta >= 0.25:
        return math.inf
    w_max = grid_omega_max(config, p)
    if w_max <= 0:
        return math.inf
    return config.time.substeps * 2.0 / (w_max * math.sqrt(1 - 4 * theta))


def analyse_stability(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                      n_kappa: int = 257, spectral_radius: float | None = None,
                      tol: float = 1e-9) -> StabilityReport:
    """Bistritz analysis of the dispersion relation plus the finite beam's spectral radius.

    Parameters
    ----------
    config, params
        Set-up and parameter overrides.
    n_kappa
        Number of equidistant wavenumbers in ``[π/L, π/h]`` (the
        :func:`critical_wavenumbers` are added).
    spectral_radius
        Spectral radius of Φ if already known; computed from the modal form otherwise.
    tol
        Relative tolerance for ``|z| ≤ 1`` and ``ρ(Φ) ≤ 1``.
    """
    p = resolve_parameters(config, params)
    h = config.beam.length / (config.beam.nodes + 1)
    tau = config.time.dt / config.time.substeps
    kap = _analysis_kappas(config, p, n_kappa)
    co = dispersion_coefficients(p, h=h, tau=tau, theta=config.time.theta, kappa=kap)
    g = float(np.max(growth_factors(co)))
    outside = 0
    on = 0
    for row in co:
        # tolerance: the rounding of the coefficient sums in the sequence (a few eps);
        # undamped rows are exactly self-reciprocal (a == c bit for bit), so exact
        # zeros stay exact
        zl = bistritz(row, tol=_BISTRITZ_TOL)
        outside += zl.outside
        on += zl.on
    grid_stable = outside == 0
    if spectral_radius is None:
        from ..simulate import fast_model  # local import: simulate depends on this package's siblings

        spectral_radius = fast_model(config, p).spectral_radius()
    beam_stable = spectral_radius <= 1.0 + tol
    bounds = stability_bounds(config, p)
    msgs: list[str] = []
    stuck = [name for name, (lo, _) in bounds.items() if math.isnan(lo)]
    if stuck:
        msgs.append(f"no value of {', '.join(stuck)} alone satisfies the Bistritz conditions of "
                    f"the unbounded grid (another parameter violates them)")
    for name, (lo, hi) in bounds.items():
        v = p[name]
        if math.isnan(lo):
            continue
        if not lo <= v <= hi:
            msgs.append(f"{name} = {v:g} lies outside the Bistritz bounds [{lo:g}, {hi:g}] "
                        f"of the unbounded grid")
    if grid_stable and not beam_stable:
        msgs.append(f"the unbounded-grid analysis says stable but the finite beam is not "
                    f"(spectral radius of Phi {spectral_radius:.12g}): the boundary conditions "
                    f"destabilise it (e.g. buckling of a cantilever under compression)")
    if beam_stable and not grid_stable:
        msgs.append(f"the unbounded-grid analysis says unstable (max growth factor {g:.12g}) but the "
                    f"finite beam is stable (spectral radius {spectral_radius:.12g}): its ends "
                    f"stiffen it beyond the grid's Euler load")
    dtm = _dt_max(p, config)
    if config.time.scheme == "exact":
        msgs.append("time.scheme = exact: integrated exactly in time, stable whenever the beam is (spectral "
                    f"radius {spectral_radius:.12g}); the growth factor and the Bistritz bounds are those of the "
                    f"seed's theta-scheme (theta = {config.time.theta:g}) on the same grid")
    elif config.time.dt > dtm:
        msgs.append(f"dt = {config.time.dt:g} s exceeds the explicit limit {dtm:g} s for theta = "
                    f"{config.time.theta:g}")
    return StabilityReport(g, grid_stable, on > 0, float(spectral_radius), beam_stable, bounds, dtm,
                           tuple(msgs))
