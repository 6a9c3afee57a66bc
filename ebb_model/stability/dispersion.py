"""Dispersion relation of the θ-scheme and the stability analysis built on it.

Von Neumann ansatz on the unbounded grid, :math:`w_j^n = z^n e^{i\\kappa j h}`,
in the interior stencil of :mod:`ebb_model.discretisation` and
:mod:`ebb_model.theta_scheme` gives, per wavenumber κ, a quadratic in the
temporal growth factor ``z`` (per sub-step ``τ``):

.. math::

    p_\\kappa(z) = a z^2 + b z + c,\\qquad
    \\begin{aligned}
    a &= \\rho A + \\tfrac{\\tau}{2} d + \\theta\\tau^2 k,\\\\
    b &= -2\\rho A + (1-2\\theta)\\tau^2 k,\\\\
    c &= \\rho A - \\tfrac{\\tau}{2} d + \\theta\\tau^2 k,
    \\end{aligned}

with :math:`s_2 = \\tfrac{4}{h^2}\\sin^2\\tfrac{\\kappa h}{2}`, :math:`s_4 = s_2^2`,
stiffness symbol :math:`k = EI s_4 + N s_2` and damping symbol
:math:`d = c + \\eta EI s_4`.

For degree two the Bistritz sequence evaluated at ``z = 1`` is
:math:`T_2(1) = 2(a+b+c) = 2\\tau^2 k`, :math:`T_1(1) = 2(a-c) = 2\\tau d`,
:math:`T_0 = 2(a-b+c) = 2(4\\rho A + (4\\theta - 1)\\tau^2 k)`; no zero lies
outside the unit circle iff all three are ≥ 0.  Each is *affine* in every
physical parameter, so the conditions give closed-form parameter bounds
(:func:`stability_bounds`).  The same quadratic with ``k = ω_i²`` and
``d = ξ_i`` (mass-normalised modal stiffness and damping) is the exact
characteristic polynomial of mode ``i`` of the finite beam under
proportional damping.

The wavenumbers are those that fit the beam, ``π/L ≤ κ ≤ π/h``.  Under
compression the unbounded-grid analysis is conservative: it flags
``N < -EI s_2(π/L)`` (the pinned–pinned Euler load of the grid) even when
the ends make the finite beam stiffer; :func:`analyse_stability` reports such
disagreements.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..beam import PARAMETER_NAMES
from ..config import BeamConfig, check_parameter_values
from .bistritz import bistritz

#: Relative zero tolerance of the Bistritz test on the dispersion polynomials.
_BISTRITZ_TOL = 16 * np.finfo(float).eps

__all__ = [
    "wavenumbers",
    "dispersion_coefficients",
    "growth_factors",
    "max_growth_factor",
    "bistritz_values",
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


def dispersion_coefficients(params: Mapping[str, float], *, h: float, tau: float, theta: float,
                            kappa: np.ndarray) -> np.ndarray:
    """Coefficients ``[a, b, c]`` (highest power first) of ``p_κ(z)``, shape (n_κ, 3)."""
    p = params
    s2, s4 = _symbols(np.asarray(kappa, dtype=float), h)
    k = p["EI"] * s4 + p["N"] * s2
    d = p["c"] + p["eta"] * p["EI"] * s4
    rho = p["rhoA"]
    a = rho + tau / 2 * d + theta * tau ** 2 * k
    b = -2 * rho + (1 - 2 * theta) * tau ** 2 * k
    c = rho - tau / 2 * d + theta * tau ** 2 * k
    return np.stack([a, b, c], axis=-1)


def growth_factors(coeffs: np.ndarray) -> np.ndarray:
    """Largest root modulus ``max |z|`` of each quadratic row ``[a, b, c]`` (closed form)."""
    a, b, c = coeffs[..., 0], coeffs[..., 1], coeffs[..., 2]
    disc = np.sqrt((b * b - 4 * a * c).astype(complex))
    z1 = (-b + disc) / (2 * a)
    z2 = (-b - disc) / (2 * a)
    return np.maximum(np.abs(z1), np.abs(z2))


def max_growth_factor(config: BeamConfig, params: Mapping[str, float] | None = None,
                      *, n_kappa: int = 257) -> float:
    """The seed's stabilising objective: ``max_κ max |z|`` on the unbounded grid."""
    p = check_parameter_values(config.parameter_values() | dict(params or {}))
    h = config.beam.length / (config.beam.nodes + 1)
    tau = config.time.dt / config.time.substeps
    co = dispersion_coefficients(p, h=h, tau=tau, theta=config.time.theta,
                                 kappa=wavenumbers(config.beam.length, config.beam.nodes, n_kappa))
    return float(np.max(growth_factors(co)))


def bistritz_values(coeffs: np.ndarray) -> np.ndarray:
    """Bistritz values ``(T_2(1), T_1(1), T_0(1))`` of each quadratic, shape (n, 3)."""
    a, b, c = coeffs[..., 0], coeffs[..., 1], coeffs[..., 2]
    return np.stack([2 * (a + b + c), 2 * (a - c), 2 * (a - b + c)], axis=-1)


def _endpoint_kappas(config: BeamConfig) -> np.ndarray:
    # k and d are monotone in s2 (or quadratic with extremes at the ends), so
    # the ends of the wavenumber range decide every condition.
    return wavenumbers(config.beam.length, config.beam.nodes, 2)


def _bistritz_terms(p: Mapping[str, float], s2: np.ndarray, s4: np.ndarray, tau: float,
                    theta: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Bistritz values (n_κ, 3) and their exact derivatives with respect to each parameter.

    ``T_2(1) = 2τ²k``, ``T_1(1) = 2τd``, ``T_0 = 8ρA + 2(4θ-1)τ²k`` with
    ``k = EI s4 + N s2`` and ``d = c + η EI s4``.
    """
    k = p["EI"] * s4 + p["N"] * s2
    d = p["c"] + p["eta"] * p["EI"] * s4
    T = np.stack([2 * tau ** 2 * k, 2 * tau * d, 8 * p["rhoA"] + 2 * (4 * theta - 1) * tau ** 2 * k], axis=-1)
    zero = np.zeros_like(s2)

    def dT(dk: np.ndarray, dd: np.ndarray, drho: np.ndarray) -> np.ndarray:
        return np.stack([2 * tau ** 2 * dk, 2 * tau * dd, 8 * drho + 2 * (4 * theta - 1) * tau ** 2 * dk], axis=-1)

    der = {
        "EI": dT(s4, p["eta"] * s4, zero),
        "rhoA": dT(zero, zero, zero + 1.0),
        "c": dT(zero, zero + 1.0, zero),
        "eta": dT(zero, p["EI"] * s4, zero),
        "N": dT(s2, zero, zero),
    }
    return T, der


def stability_bounds(config: BeamConfig, params: Mapping[str, float] | None = None
                     ) -> dict[str, tuple[float, float]]:
    """Interval of each parameter (others held) where the Bistritz conditions hold.

    Each Bistritz value is affine in each parameter, ``T(p) = T(p0) + T'·(p - p0)``
    with the exact derivative ``T'`` (see :func:`_bistritz_terms`), so the
    condition ``T ≥ 0`` at every wavenumber gives ``p ≥ p0 - T/T'`` (T' > 0)
    or ``p ≤ p0 - T/T'`` (T' < 0).  The physical ranges (``EI, rhoA > 0``;
    ``c, eta ≥ 0``) are intersected in.  Conditions are extremal at the two
    ends of the wavenumber range (``k`` is convex in ``s_2``, ``d`` monotone),
    so those two wavenumbers suffice.

    Returns
    -------
    dict
        ``{name: (lo, hi)}`` for ``EI, rhoA, c, eta, N``; infinite where
        unbounded; ``(nan, nan)`` when no value of that parameter alone can
        satisfy the conditions (another parameter violates one that does not
        depend on it).
    """
    p0 = check_parameter_values(config.parameter_values() | dict(params or {}))
    h = config.beam.length / (config.beam.nodes + 1)
    tau = config.time.dt / config.time.substeps
    s2, s4 = _symbols(_endpoint_kappas(config), h)
    T, der = _bistritz_terms(p0, s2, s4, tau, config.time.theta)
    out: dict[str, tuple[float, float]] = {}
    phys_lo = {"EI": 0.0, "rhoA": 0.0, "c": 0.0, "eta": 0.0, "N": -math.inf}
    for name in PARAMETER_NAMES:
        lo, hi = phys_lo[name], math.inf
        feasible = True
        for t, dt_ in zip(T.ravel(), der[name].ravel()):
            if dt_ == 0.0:
                if t < 0:
                    feasible = False
                continue
            r = p0[name] - t / dt_
            if dt_ > 0:
                lo = max(lo, r)
            else:
                hi = min(hi, r)
        out[name] = (float(lo), float(hi)) if feasible and lo <= hi else (math.nan, math.nan)
    return out


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


def _dt_max(p: Mapping[str, float], config: BeamConfig, kappa: np.ndarray) -> float:
    theta = config.time.theta
    if theta >= 0.25:
        return math.inf
    h = config.beam.length / (config.beam.nodes + 1)
    s2, s4 = _symbols(kappa, h)
    kmax = float(np.max(p["EI"] * s4 + p["N"] * s2))
    if kmax <= 0:
        return math.inf
    return config.time.substeps * 2.0 * math.sqrt(p["rhoA"] / ((1 - 4 * theta) * kmax))


def analyse_stability(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                      n_kappa: int = 257, spectral_radius: float | None = None,
                      tol: float = 1e-9) -> StabilityReport:
    """Bistritz analysis of the dispersion relation plus the finite beam's spectral radius.

    Parameters
    ----------
    config, params
        Set-up and parameter overrides.
    n_kappa
        Number of wavenumbers in ``[π/L, π/h]``.
    spectral_radius
        Spectral radius of Φ if already known; computed from the modal form otherwise.
    tol
        Relative tolerance for ``|z| ≤ 1`` and ``ρ(Φ) ≤ 1``.
    """
    p = check_parameter_values(config.parameter_values() | dict(params or {}))
    h = config.beam.length / (config.beam.nodes + 1)
    tau = config.time.dt / config.time.substeps
    kap = wavenumbers(config.beam.length, config.beam.nodes, n_kappa)
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
    dtm = _dt_max(p, config, kap)
    if config.time.dt > dtm:
        msgs.append(f"dt = {config.time.dt:g} s exceeds the explicit limit {dtm:g} s for theta = "
                    f"{config.time.theta:g}")
    return StabilityReport(g, grid_stable, on > 0, float(spectral_radius), beam_stable, bounds, dtm,
                           tuple(msgs))
