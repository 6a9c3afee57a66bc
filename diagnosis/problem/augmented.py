r"""Native simulation of the signal-level and axial-force effects of the catalogue.

The simulation engine of :class:`diagnosis.effects.AugmentedModel`: the
structural effects (end springs, point mass, Kelvin–Voigt damping, rotary
inertia, foundation) are config changes simulated by the model core; the
signal-level parts (:class:`diagnosis.effects.Signal`) act on the inputs and
outputs themselves (e.g. :mod:`diagnosis.effects.lag`), and their axial-force
terms (:class:`diagnosis.effects.AxialLoad`: a drift ``rate``, mid-plane
stretching ``EA``, from :mod:`diagnosis.effects.axial`) are integrated here:

.. math::

    N(t) = N + \text{rate}\cdot t + \frac{EA}{2L}\int_0^L w_x^2\,dx .

Axial-force perturbation
------------------------
Both axial effects are an extra axial force :math:`\delta N(t)` on the
finite-difference beam of :mod:`ebb_model.space.discretisation`.  Its stiffness
matrix is affine in ``N``, :math:`K(N) = K_0 + N K_g`, so ``δN`` is the nodal
load :math:`g = -\delta N\,K_g q` with the model's own geometric stiffness
:math:`K_g = \partial K/\partial N` (same ghost-node relations; computed as a
difference quotient of two discretisations, exact because ``K`` is affine).
The load enters the θ-scheme of :mod:`ebb_model.theta.theta_scheme` *explicitly* at
the centre level of every sub-step ``j`` (``τ = dt/substeps``):

.. math::

    v^{j+1/2} = (I - \tilde C) v^{j-1/2} - \tilde K q^j
                - \delta N^j\, L'^{-1} K_g\, q^j + \tilde B u_k, \qquad
    q^{j+1} = q^j + \tau v^{j+1/2},

with :math:`\delta N^j = \delta N_0 + \text{rate}\; j\tau +
\frac{EA}{2L}\, s(q^j)`.  The implicit scheme weights the stiffness term as
:math:`\theta q^{j+1} + (1-2\theta) q^j + \theta q^{j-1}
= q^j + O(\tau^2)`, so the explicit centre-level treatment of ``δN`` keeps the
scheme's second-order consistency (the difference to treating ``δN``
implicitly is :math:`\theta\tau^2\,\delta N K_g \ddot q`).  It is
conditionally stable in the perturbation only: :math:`\tau^2\,
\lambda_{max}(M^{-1}\delta N K_g) \lesssim 4`, i.e.
:math:`|\delta N| \lesssim \rho A h^2/\tau^2` — far beyond any physical drift
or stretching force at the project's grids and sample times.  Between samples
the force follows the straight line between them (first-order hold), as in
:func:`ebb_model.assemble.assemble`; with ``δN ≡ 0`` the recursion is exactly the sub-stepped scheme that
:func:`ebb_model.theta.theta_scheme.discretise_time` condenses into ``Φ = S^m``.

Outputs at ``t_k`` (sub-step ``j = mk``) use the scheme's central differences
including the perturbation load, consistent with the feedthrough of
:func:`ebb_model.theta.theta_scheme.output_matrices`: displacement ``P q^j``,
velocity ``P (v^{j+1/2} + v^{j-1/2})/2``, acceleration
``P (v^{j+1/2} - v^{j-1/2})/τ``.

Stretching integral
-------------------
:math:`s(q) = \int_0^L w_x^2\,dx` is evaluated exactly for the piecewise-linear
interpolant of the grid deflection (fixed boundary nodes are zero):
:math:`s = \sum_{i=0}^{n} (w_{i+1} - w_i)^2/h`, second-order accurate for a
smooth ``w`` and equal to :math:`q^T K_g q` whenever both ends are axially
fixed (clamped/pinned), so the stretching load is then the exact gradient of
the discrete stretching energy :math:`\frac{EA}{8L}s(q)^2`.

The perturbation changes the stiffness only.  With Kelvin–Voigt damping and
an end that can translate, the core's damping matrix also depends on ``N``
through the ghost nodes (the ``η N ẇ'`` term the core documents as
neglected); ``δN`` leaves the damping at the base ``N`` (for a constant
``δN`` on a cantilever with ``η = 1e-4`` s this differs from re-discretising
with ``N + δN`` by < 1 % of the effect of ``δN`` itself).

Cost: ``2–3 n_u²`` multiply–adds per sub-step in a compiled kernel, no modal
truncation: 4000 samples take 3–6 ms with 40–60 nodes (about twice that with
two sub-steps), set-up included, on one core.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numba
import numpy as np

from ebb_model.arrays import as_matrix
from ebb_model.assemble import check_stable
from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.space.discretisation import SemiDiscreteBeam, discretise
from ebb_model.errors import ConfigError, DataError, StabilityError
from ebb_model.parameter_values import resolve_parameters
from ebb_model.simulate import fast_model, simulate
from ebb_model.theta.theta_scheme import ThetaCoefficients, one_step, theta_coefficients

from .axial_modal import simulate_axial_exact
from .axial_terms import geometric_stiffness
from ..effects.base import AxialLoad, Signal

__all__ = ["simulate_axial", "simulate_effects"]

_KIND_CODE = {"displacement": 0, "velocity": 1, "acceleration": 2}
_FASTMATH = {"reassoc", "contract", "nsz", "arcp"}


# ---------------------------------------------------------------------------
# validation helpers
# ---------------------------------------------------------------------------
def _check_inputs(u: np.ndarray, config: BeamConfig) -> np.ndarray:
    return as_matrix(u, "inputs", shape=(None, len(config.actuators)), columns=config.input_names,
                     column="input")


# ---------------------------------------------------------------------------
# axial-force perturbation
# ---------------------------------------------------------------------------
@numba.njit(cache=True, nogil=True, fastmath=_FASTMATH)
def _axial_kernel(Kt, Ct, KGt, Bt, P, kinds, u, substeps, foh, tau, offset, rate, ea_coef,
                  first, n_nodes, h, q0, v0, y):  # pragma: no cover - compiled
    n = Kt.shape[0]
    ns, ni = u.shape
    no = P.shape[0]
    has_c = False
    for r in range(n):
        for c in range(n):
            if Ct[r, c] != 0.0:
                has_c = True
    q = q0.copy()
    v = v0.copy()
    vn = np.empty(n)
    bu = np.empty(n)
    bu0 = np.empty(n)
    bu1 = np.empty(n)
    for k in range(ns):
        k1 = k + 1 if k + 1 < ns else k
        for r in range(n):
            a0 = 0.0
            a1 = 0.0
            for i in range(ni):
                a0 += Bt[r, i] * u[k, i]
                a1 += Bt[r, i] * u[k1, i]
            bu0[r] = a0
            bu1[r] = a1
        for sub in range(substeps):
            # first-order hold: the force at sub-step level j is the straight line between samples
            w = foh * sub / substeps
            for r in range(n):
                bu[r] = (1.0 - w) * bu0[r] + w * bu1[r]
            j = k * substeps + sub
            dN = offset + rate * (j * tau)
            if ea_coef != 0.0:
                # ∫ w_x² of the piecewise-linear grid deflection; boundary nodes
                # that are not unknowns are zero
                s = 0.0
                prev = 0.0 if first > 0 else q[0]
                for node in range(1, n_nodes):
                    idx = node - first
                    cur = q[idx] if 0 <= idx < n else 0.0
                    d = cur - prev
                    s += d * d
                    prev = cur
                dN += ea_coef * s / h
            for r in range(n):
                acc = 0.0
                if has_c:
                    for c in range(n):
                        acc += (Kt[r, c] + dN * KGt[r, c]) * q[c] + Ct[r, c] * v[c]
                else:
                    for c in range(n):
                        acc += (Kt[r, c] + dN * KGt[r, c]) * q[c]
                vn[r] = v[r] - acc + bu[r]
            if sub == 0:
                for o in range(no):
                    acc = 0.0
                    kd = kinds[o]
                    for c in range(n):
                        if kd == 0:
                            acc += P[o, c] * q[c]
                        elif kd == 1:
                            acc += P[o, c] * 0.5 * (vn[c] + v[c])
                        else:
                            acc += P[o, c] * (vn[c] - v[c])
                    y[k, o] = acc / tau if kd == 2 else acc
            for r in range(n):
                q[r] += tau * vn[r]
                v[r] = vn[r]


def _scheme(config: BeamConfig, p: Mapping[str, float]) -> tuple[SemiDiscreteBeam, np.ndarray, ThetaCoefficients]:
    """The discretised beam, ``K_g`` and the θ-scheme coefficients with ``[B̃_u, L'^{-1}K_g]``."""
    beam = discretise(config, p)
    Kg = geometric_stiffness(config, p)
    ts = config.time
    co = theta_coefficients(replace(beam, F=np.hstack([beam.F, Kg])), ts.dt, ts.theta, ts.substeps)
    return beam, Kg, co


def simulate_axial(config: BeamConfig, params: Mapping[str, float] | None, inputs: np.ndarray, *,
                   offset: float = 0.0, rate: float = 0.0, EA: float = 0.0,
                   x0: np.ndarray | None = None, check_stability: bool = False) -> np.ndarray:
    r"""Simulate the beam under the axial force :math:`N + \delta N(t)` (module docstring).

    .. math::  \delta N(t) = \text{offset} + \text{rate}\cdot t + \frac{EA}{2L}\int_0^L w_x^2\,dx .

    With ``time.scheme = "exact"`` the perturbation acts on the exact-scheme model instead
    (:func:`diagnosis.problem.axial_modal.simulate_axial_exact`), so candidates and baseline share its accuracy.

    Parameters
    ----------
    config, params
        The set-up and parameter values (``params`` override the nominal
        ones; ``None`` keeps them).
    inputs
        Input samples (n_samples, n_inputs), linear between samples (first-order hold).
    offset
        Constant extra axial force [N] (a hook for consistency checks: the
        result approaches the LTI beam with ``N + offset`` as ``τ → 0``).
    rate
        Axial-load drift rate [N/s], ``t = 0`` at the first sample.
    EA
        Axial stiffness [N] of mid-plane stretching, >= 0.
    x0
        Initial state ``(q^0, v^{-1/2})`` of nodal unknowns (2 n_u,), as the
        state of :func:`ebb_model.assemble.assemble`; zero by default.
    check_stability
        Raise :class:`~ebb_model.errors.StabilityError` when the base scheme is
        unstable or the result is not finite.

    Returns
    -------
    numpy.ndarray
        Outputs (n_samples, n_sensors) at ``t_k = k dt``.

    Raises
    ------
    ParameterError, DataError, StabilityError
    """
    offset, rate = finite_scalar("axial offset", offset), finite_scalar("axial_drift.rate", rate)
    EA = finite_scalar("geometric_stiffening.EA", EA, minimum=0.0)
    u = _check_inputs(inputs, config)
    if config.time.scheme == "exact":
        if x0 is not None:
            raise ConfigError("x0: a nodal initial state applies to the θ-scheme only (time.scheme = \"theta\")")
        return simulate_axial_exact(config, params, u, offset=offset, rate=rate, EA=EA,
                                    check_stability=check_stability)
    p = resolve_parameters(config, params)
    beam, _, co = _scheme(config, p)
    n = beam.n_unknowns
    if check_stability:
        S, _ = one_step(co.Kt, co.Ct, co.Bt, co.tau)
        rho = float(np.max(np.abs(np.linalg.eigvals(S)))) if n else 0.0
        check_stable(config, p, rho ** config.time.substeps)
    if x0 is None:
        q0, v0 = np.zeros(n), np.zeros(n)
    else:
        x0 = np.asarray(x0, dtype=float)
        if x0.shape != (2 * n,) or not np.all(np.isfinite(x0)):
            raise DataError(f"initial state x0 must be {2 * n} finite values (q, v), got shape {x0.shape}")
        q0, v0 = x0[:n].copy(), x0[n:].copy()
    m_in = u.shape[1]
    kinds = np.array([_KIND_CODE[k] for k in beam.sensor_kinds], dtype=np.int64)
    y = np.empty((u.shape[0], len(beam.sensor_kinds)))
    h = config.beam.length / (config.beam.nodes + 1)
    _axial_kernel(np.ascontiguousarray(co.Kt), np.ascontiguousarray(co.Ct),
                  np.ascontiguousarray(co.Bt[:, m_in:]), np.ascontiguousarray(co.Bt[:, :m_in]),
                  np.ascontiguousarray(beam.S), kinds, u, int(config.time.substeps),
                  1.0 if config.time.input_hold == "foh" else 0.0, float(co.tau),
                  offset, rate, EA / (2.0 * config.beam.length), int(beam.unknown[0]), int(beam.x.size), h,
                  q0, v0, y)
    if check_stability and not np.all(np.isfinite(y)):
        raise StabilityError("the simulation with axial drift/stretching diverged (non-finite outputs): "
                             f"rate = {rate:g} N/s, EA = {EA:g} N, offset = {offset:g} N")
    return y


def simulate_effects(config: BeamConfig, params: Mapping[str, float] | None, inputs: np.ndarray,
                     signals: Sequence[Signal] = (), *, check_stability: bool = False) -> np.ndarray:
    """Simulate the beam with the signal-level parts of effects (:class:`diagnosis.effects.Signal`).

    The measured inputs pass through each part's :meth:`~diagnosis.effects.Signal.inputs` in order, the beam
    is simulated under the parts' axial-force terms together, and its outputs pass through each part's
    :meth:`~diagnosis.effects.Signal.outputs` in order.

    Parameters
    ----------
    config, params
        The (possibly structurally augmented) set-up and parameter values.
    inputs
        Measured actuator forces (n_samples, n_inputs).
    signals
        The signal-level parts (an :class:`~diagnosis.effects.AugmentedModel`'s ``signals``); none: the beam.
    check_stability
        Raise :class:`~ebb_model.errors.StabilityError` for an unstable scheme
        or a diverging simulation (off by default, like
        :func:`ebb_model.simulate.simulate_config`).

    Returns
    -------
    numpy.ndarray
        Outputs (n_samples, n_sensors), columns in the config's sensor order.

    Notes
    -----
    Without axial-force terms the beam is simulated on the modal fast path
    (:func:`ebb_model.simulate.fast_model`), otherwise by :func:`simulate_axial`.

    Raises
    ------
    ConfigError
        A part names a sensor the config does not have.
    DataError
        Inputs of the wrong shape or with NaN/inf.
    StabilityError
        With ``check_stability``: an unstable scheme or a diverging simulation.
    """
    u = _check_inputs(inputs, config)
    dt = config.time.dt
    for part in signals:
        u = part.inputs(u, dt)
    load = sum((part.axial() for part in signals), AxialLoad())
    if load.zero:
        p = resolve_parameters(config, params)
        model = fast_model(config, p)
        if check_stability:
            check_stable(config, p, model.spectral_radius())
        y = simulate(model, u).outputs
        if check_stability and not np.all(np.isfinite(y)):
            raise StabilityError("the simulation diverged (non-finite outputs)")
    else:
        y = simulate_axial(config, params, u, rate=load.rate, EA=load.EA, check_stability=check_stability)
    for part in signals:
        y = part.outputs(y, dt, config.output_names)
    return y
