r"""Native simulation of the signal-level and axial-force effects of the catalogue.

Structural effects (end springs, point mass, Kelvin–Voigt damping, rotary
inertia, foundation) are config changes simulated by the model core.  This
module adds the four effects that are *not* a change of the linear
time-invariant beam:

``actuator_lag`` (``tau``)
    The force the beam feels is the measured force through ``1/(τ s + 1)``:
    :func:`first_order_lag` is applied to the input samples before simulating.
``sensor_lag`` (``tau``, ``sensor``)
    That sensor's reading is the simulated quantity (displacement, velocity or
    acceleration — the filter is LTI, so it acts on the quantity itself)
    through ``1/(τ s + 1)``.
``axial_drift`` (``rate``)
    :math:`N(t) = N + \text{rate}\cdot t`, ``t`` from the record start.
``geometric_stiffening`` (``EA``)
    :math:`N(t) = N + \frac{EA}{2L}\int_0^L w_x^2\,dx` (mid-plane stretching;
    physically meaningful only when both ends are axially restrained).

Axial-force perturbation
------------------------
Both axial effects are an extra axial force :math:`\delta N(t)` on the
finite-difference beam of :mod:`ebb_model.discretisation`.  Its stiffness
matrix is affine in ``N``, :math:`K(N) = K_0 + N K_g`, so ``δN`` is the nodal
load :math:`g = -\delta N\,K_g q` with the model's own geometric stiffness
:math:`K_g = \partial K/\partial N` (same ghost-node relations; computed as a
difference quotient of two discretisations, exact because ``K`` is affine).
The load enters the θ-scheme of :mod:`ebb_model.theta_scheme` *explicitly* at
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
:func:`ebb_model.theta_scheme.discretise_time` condenses into ``Φ = S^m``.

Outputs at ``t_k`` (sub-step ``j = mk``) use the scheme's central differences
including the perturbation load, consistent with the feedthrough of
:func:`ebb_model.theta_scheme.output_matrices`: displacement ``P q^j``,
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

import math
from collections.abc import Mapping
from dataclasses import replace

import numba
import numpy as np
import scipy.signal as ss

from ebb_model.arrays import as_matrix
from ebb_model.assemble import check_stable
from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.discretisation import SemiDiscreteBeam, discretise
from ebb_model.errors import ConfigError, DataError, ParameterError, StabilityError
from ebb_model.parameter_values import resolve_parameters
from ebb_model.simulate import fast_model, simulate
from ebb_model.theta_scheme import ThetaCoefficients, one_step, theta_coefficients

__all__ = ["first_order_lag", "lag_coefficients", "geometric_stiffness", "simulate_axial", "simulate_effects",
           "stretch_integral"]

_KIND_CODE = {"displacement": 0, "velocity": 1, "acceleration": 2}
_FASTMATH = {"reassoc", "contract", "nsz", "arcp"}


# ---------------------------------------------------------------------------
# validation helpers
# ---------------------------------------------------------------------------
def _check_inputs(u: np.ndarray, config: BeamConfig) -> np.ndarray:
    return as_matrix(u, "inputs", shape=(None, len(config.actuators)), columns=config.input_names,
                     column="input")


# ---------------------------------------------------------------------------
# first-order lag
# ---------------------------------------------------------------------------
def lag_coefficients(r: float) -> tuple[float, float, float]:
    """``a = e^{-r}``, ``b0 = 1 - (1-a)/r`` and ``b1 = (1-a)/r - a`` for ``r = dt/τ`` (no cancellation)."""
    a = math.exp(-r)
    if r < 1e-2:  # series of (r - 1 + e^{-r})/r and ((1-e^{-r}) - r e^{-r})/r
        b0 = r * (1 / 2 - r / 6 + r * r / 24 - r ** 3 / 120 + r ** 4 / 720)
        b1 = r * (1 / 2 - r / 3 + r * r / 8 - r ** 3 / 30 + r ** 4 / 144)
    else:
        one_minus_a = -math.expm1(-r)
        b0 = 1.0 - one_minus_a / r
        b1 = one_minus_a / r - a
    return a, b0, b1


def first_order_lag(x: np.ndarray, dt: float, tau: float, *, y0: np.ndarray | float | None = None) -> np.ndarray:
    r"""Samples of the output of ``1/(τ s + 1)`` driven by the piecewise-linear interpolant of ``x``.

    The exact discretisation for a first-order-hold input: on
    :math:`[t_k, t_{k+1}]` the input is the straight line between ``x[k]``
    and ``x[k+1]``, and with :math:`a = e^{-dt/τ}`

    .. math::

        y_{k+1} = a\,y_k + \Bigl(1 - \tfrac{τ}{dt}(1-a)\Bigr) x_{k+1}
                  + \Bigl(\tfrac{τ}{dt}(1-a) - a\Bigr) x_k ,

    which reproduces the continuous response of any piecewise-linear input
    exactly (ramps and constants in particular) and has unit DC gain.

    Parameters
    ----------
    x
        Samples, shape (n,) or (n, m) (one column per signal), uniformly
        spaced by ``dt``.
    dt
        Sample time [s], > 0.
    tau
        Time constant [s], >= 0; ``tau = 0`` returns a copy of ``x``.
    y0
        Initial output ``y[0]``.  Default ``None``: the filter starts in the
        steady state of ``x[0]`` (``y[0] = x[0]``, i.e. the input is taken as
        constant before the record), so a constant signal passes unchanged.
        Pass ``0`` for a filter at rest from zero.

    Returns
    -------
    numpy.ndarray
        Filtered samples, same shape as ``x``.

    Raises
    ------
    ParameterError
        ``tau`` negative or non-finite, ``dt`` not a finite number > 0.
    DataError
        ``x`` empty, of more than two dimensions or containing NaN/inf.
    """
    tau = finite_scalar("lag time constant tau", tau, minimum=0.0)
    dt_f = finite_scalar("sample time dt", dt)
    if dt_f <= 0:
        raise ParameterError(f"sample time dt must be > 0, got {dt!r}")
    x = np.asarray(x, dtype=float)
    if x.ndim not in (1, 2) or x.shape[0] == 0:
        raise DataError(f"lag input must have shape (n,) or (n, m) with n >= 1, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise DataError(f"lag input contains a non-finite value at sample {int(np.argwhere(~np.isfinite(x))[0][0])}")
    start = x[0] if y0 is None else np.broadcast_to(np.asarray(y0, dtype=float), x.shape[1:])
    if not np.all(np.isfinite(start)):
        raise DataError("lag initial output y0 must be finite")
    if tau == 0.0:
        return x.copy()
    a, b0, b1 = lag_coefficients(dt_f / tau)
    # y[k] = b0 x[k] + b1 x[k-1] + a y[k-1]; zi chosen so that y[0] = start
    zi = np.asarray(start - b0 * x[0], dtype=float)[None, ...]
    y, _ = ss.lfilter([b0, b1], [1.0, -a], x, axis=0, zi=zi)
    return y


# ---------------------------------------------------------------------------
# axial-force perturbation
# ---------------------------------------------------------------------------
def geometric_stiffness(config: BeamConfig, params: Mapping[str, float] | None = None) -> np.ndarray:
    r"""The finite-difference geometric stiffness :math:`K_g = \partial K/\partial N` (n_u × n_u).

    ``K`` of :func:`ebb_model.discretisation.discretise` is affine in ``N``
    (the ghost-node relations included), so the difference quotient
    ``(K(N + s) - K(N))/s`` is exact up to round-off; ``s = EI/h²`` balances the
    two terms of ``K`` to keep that round-off at machine precision.
    """
    p = resolve_parameters(config, params)
    h = config.beam.length / (config.beam.nodes + 1)
    s = float(p["EI"]) / h ** 2
    K0 = discretise(config, p).K
    K1 = discretise(config, p | {"N": float(p["N"]) + s}).K
    return (K1 - K0) / s


def stretch_integral(config: BeamConfig, q: np.ndarray) -> np.ndarray:
    r"""``∫₀ᴸ w_x² dx`` of nodal deflections ``q`` (…, n_u), exact for their piecewise-linear interpolant."""
    beam = discretise(config)
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != beam.n_unknowns:
        raise DataError(f"nodal deflections must have {beam.n_unknowns} values in the last axis, got {q.shape}")
    w = np.zeros(q.shape[:-1] + (beam.x.size,))
    w[..., beam.unknown] = q
    h = config.beam.length / (config.beam.nodes + 1)
    return np.sum(np.diff(w, axis=-1) ** 2, axis=-1) / h


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
    (:func:`diagnosis.axial_modal.simulate_axial_exact`), so candidates and baseline share its accuracy.

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
        from .axial_modal import simulate_axial_exact

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


def simulate_effects(config: BeamConfig, params: Mapping[str, float] | None, inputs: np.ndarray, *,
                     actuator_tau: float = 0.0, sensor_tau: Mapping[str, float] | None = None,
                     drift_rate: float = 0.0, stretching_EA: float = 0.0,
                     check_stability: bool = False) -> np.ndarray:
    """Simulate the beam with the signal-level and axial-force effects of the catalogue.

    Parameters
    ----------
    config, params
        The (possibly structurally augmented) set-up and parameter values.
    inputs
        Measured actuator forces (n_samples, n_inputs).
    actuator_tau
        ``actuator_lag.tau`` [s]: every input passes through ``1/(τ s + 1)``
        (:func:`first_order_lag`, steady start) before reaching the beam.
    sensor_tau
        ``sensor_lag.tau`` [s] per sensor name: that output passes through
        ``1/(τ s + 1)`` (steady start at its first sample).
    drift_rate
        ``axial_drift.rate`` [N/s].
    stretching_EA
        ``geometric_stiffening.EA`` [N], >= 0.
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
    With ``drift_rate == stretching_EA == 0`` the beam is simulated on the
    modal fast path (:func:`ebb_model.simulate.fast_model`), otherwise by
    :func:`simulate_axial`.

    Raises
    ------
    ConfigError
        An unknown sensor name in ``sensor_tau``.
    ParameterError
        A negative or non-finite time constant, rate or ``EA``.
    DataError
        Inputs of the wrong shape or with NaN/inf.
    """
    actuator_tau = finite_scalar("actuator_lag.tau", actuator_tau, minimum=0.0)
    drift_rate = finite_scalar("axial_drift.rate", drift_rate)
    stretching_EA = finite_scalar("geometric_stiffening.EA", stretching_EA, minimum=0.0)
    sensor_tau = dict(sensor_tau or {})
    names = config.output_names
    unknown = sorted(set(sensor_tau) - set(names))
    if unknown:
        raise ConfigError(f"sensor_lag: unknown sensor(s) {', '.join(map(repr, unknown))}; "
                          f"sensors are {', '.join(names)}")
    taus = {k: finite_scalar(f"sensor_lag[{k}].tau", v, minimum=0.0) for k, v in sensor_tau.items()}
    u = _check_inputs(inputs, config)
    dt = config.time.dt
    if actuator_tau > 0.0:
        u = np.ascontiguousarray(first_order_lag(u, dt, actuator_tau))
    if drift_rate == 0.0 and stretching_EA == 0.0:
        p = resolve_parameters(config, params)
        model = fast_model(config, p)
        if check_stability:
            check_stable(config, p, model.spectral_radius())
        y = simulate(model, u).outputs
        if check_stability and not np.all(np.isfinite(y)):
            raise StabilityError("the simulation diverged (non-finite outputs)")
    else:
        y = simulate_axial(config, params, u, rate=drift_rate, EA=stretching_EA,
                           check_stability=check_stability)
    for name, tau in taus.items():
        if tau > 0.0:
            i = names.index(name)
            y[:, i] = first_order_lag(y[:, i], dt, tau)
    return y
