"""From a config and parameter values to a validated, stable discrete system.

The data flow Beam → Discretisation → StateSpace in one call:
:func:`~ebb_model.space.discretisation.discretise` (finite differences in space),
:func:`~ebb_model.theta.theta_scheme.discretise_time` (θ-scheme in time), then the
stability check of the *finite* beam (spectral radius of Φ), whose error
message names the parameters that violate the Bistritz bounds of the
dispersion relation (:mod:`ebb_model.stability.dispersion`).
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .acquisition.channel_delay import with_channel_delays
from .acquisition.delay_line import delay_line
from .config import BeamConfig
from .space.discretisation import discretise
from .errors import StabilityError
from .exact.exact_modal import exact_model
from .parameter_values import resolve_parameters
from .statespace import DiscreteStateSpace
from .theta.theta_scheme import discretise_time

__all__ = ["assemble", "assemble_modal", "buckling_load", "field_config", "field_matrix", "check_stable"]


def buckling_load(config: BeamConfig, params: Mapping[str, float] | None = None) -> float | None:
    """The compressive axial force at which the discretised beam buckles.

    The largest ``N < 0`` at which the stiffness matrix ``K(N)`` of :func:`~ebb_model.space.discretisation.discretise`
    (bending, axial force, ends, foundation) stops being positive definite, found by bracketing and bisection
    (relative tolerance 1e-7) on the Cholesky factorisation of its symmetric part.

    Returns
    -------
    float or None
        The buckling load [N] (negative), or ``None`` when ``K(0)`` is not positive definite (a beam with rigid
        motions) or no compression up to 1e30 N buckles it.
    """
    p = dict(resolve_parameters(config, params))

    def stiff(n_axial: float) -> bool:
        K = discretise(config, p | {"N": n_axial}).K
        try:
            np.linalg.cholesky(0.5 * (K + K.T))
        except np.linalg.LinAlgError:
            return False
        return True

    if not stiff(0.0):
        return None
    hi, lo = 0.0, -1.0
    while stiff(lo):
        hi, lo = lo, 2.0 * lo
        if lo < -1e30:
            return None
    while hi - lo > 1e-7 * abs(lo):
        mid = 0.5 * (hi + lo)
        hi, lo = (mid, lo) if stiff(mid) else (hi, mid)
    return lo


def check_stable(config: BeamConfig, params: Mapping[str, float], spectral_radius: float,
                 *, tol: float = 1e-9) -> None:
    """Raise :class:`StabilityError` if ``spectral_radius > 1 + tol``, naming the culprits."""
    if spectral_radius <= 1.0 + tol:
        return
    from .stability.dispersion import stability_bounds

    p = resolve_parameters(config, params)
    bounds = stability_bounds(config, p)
    culprits = [f"{k} = {p[k]:g} lies outside the Bistritz bounds [{lo:g}, {hi:g}]"
                for k, (lo, hi) in bounds.items() if lo == lo and not lo <= p[k] <= hi]
    n_cr = buckling_load(config, p) if p["N"] < 0 else None
    if n_cr is not None and p["N"] <= n_cr:   # the cause first; the bounds it breaks follow from it
        culprits = [f"N = {p['N']:g} N exceeds the buckling load {n_cr:.6g} N of this beam"
                    + (f" (and so {', '.join(culprits)})" if culprits else "")]
    elif not culprits and p["N"] < 0:
        culprits = [f"N = {p['N']:g} N is beyond the buckling load of the discretised beam"]
    why = "; ".join(culprits) if culprits else "no single parameter is out of its bounds"
    raise StabilityError(f"unstable scheme (spectral radius of Phi {spectral_radius:.9g} > 1): {why}")


def assemble(config: BeamConfig, params: Mapping[str, float] | None = None, *,
             check_stability: bool = True) -> DiscreteStateSpace:
    """The beam as a discrete state-space system (Φ, Γ, C, D, dt).

    Parameters
    ----------
    config
        The validated set-up.
    params
        Parameter values overriding the config's nominal ones.
    check_stability
        Raise :class:`~ebb_model.errors.StabilityError` when the finite beam's
        scheme is unstable (spectral radius of Φ above one).

    Returns
    -------
    DiscreteStateSpace
        ``scheme = "theta"``: state ``x[k] = (q^{mk}, v^{mk-1/2})`` of nodal unknowns;
        ``scheme = "exact"``: the modal block state of :func:`ebb_model.exact.exact_modal.exact_modal`.
        Inputs named after the actuators, outputs after the sensors.

    Raises
    ------
    ParameterError, StabilityError
    """
    p = resolve_parameters(config, params)
    ts = config.time
    if ts.scheme == "exact":
        model = exact_model(config, p)
        sys = model if isinstance(model, DiscreteStateSpace) else model.to_statespace()
    else:
        sys = with_channel_delays(discretise_time(discretise(config, p), ts.dt, ts.theta, ts.substeps,
                                                  ts.input_hold), config)
    if check_stability:
        check_stable(config, p, sys.spectral_radius())
    return sys


def field_matrix(config: BeamConfig) -> tuple[np.ndarray, np.ndarray]:
    """Grid node positions and the matrix mapping the state to the deflection at every node.

    Returns
    -------
    x : numpy.ndarray
        Positions of all ``nodes + 2`` grid points [m].
    Cf : numpy.ndarray
        Shape (nodes + 2, n_states); boundary nodes that cannot move have zero rows.
    """
    beam = discretise(config)
    P = beam.field_rows()
    Cf = np.hstack([P, np.zeros_like(P)])
    return beam.x.copy(), Cf


def assemble_modal(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                   field: bool = False, check_stability: bool = True) -> DiscreteStateSpace:
    """The beam in its real block-diagonal (modal) realisation, as a dense system.

    Same input–output behaviour as :func:`assemble`, better conditioned: each
    mode's contribution to an output is formed separately, instead of
    cancelling large nodal terms (acceleration outputs with sub-steps have
    ``C`` entries ~1e8 summing to outputs ~1e2 in nodal coordinates).  This is
    what the FMU iterates (rebuilt for every new parameter set); the channels' converter delays as delay-line
    states (:func:`ebb_model.acquisition.delay_line.delay_line`).

    Parameters
    ----------
    field
        Append outputs ``w[0] … w[nodes+1]``: the deflection at every grid node (undelayed).

    Raises
    ------
    ConfigError
        A channel's delay has no causal delay line (:func:`~ebb_model.acquisition.delay_line.delay_line`).
    """
    from .simulate import fast_model

    p = resolve_parameters(config, params)
    # the field comes as extra displacement outputs at every grid node, so it gets
    # the same (first-order-hold) feedthrough as the sensors
    modal = fast_model(field_config(config) if field else config, p)
    if check_stability:
        check_stable(config, p, modal.spectral_radius())
    return delay_line(modal if isinstance(modal, DiscreteStateSpace) else modal.to_statespace())


def field_config(config: BeamConfig) -> BeamConfig:
    """``config`` with displacement outputs ``w[0] … w[nodes+1]`` at every grid node appended to its sensors.

    A hat function evaluated at a grid node is that node's unit vector, so
    these outputs are exactly the rows of :func:`field_matrix` (zero at a
    boundary node that cannot move).
    """
    from dataclasses import replace

    from .beam import Sensor

    xs = np.linspace(0.0, config.beam.length, config.beam.nodes + 2)
    extra = tuple(Sensor(f"w[{i}]", float(x), "displacement") for i, x in enumerate(xs))
    return replace(config, sensors=tuple(config.sensors) + extra)
