r"""Blind data generator: synthetic "measured" records with an optional withheld effect.

The *truth* of the blind check of issue 5.  It reads a
:class:`~ebb_model.config.BeamConfig` (geometry, ends, point masses,
actuators, sensors, ``dt`` and parameters) but shares **no code** with the
identifying finite-difference model (``discretisation`` / ``theta_scheme`` /
``assemble`` / ``simulate`` / ``exact_modal``): the beam is discretised with
cubic Hermite finite elements (:mod:`ebb_model.reference.hermite_fe`, default
64 elements).  A time-invariant truth (no effect, or any effect but
``axial_drift`` and ``geometric_stiffening``; lags included) is integrated
**exactly** in time — matrix exponential per sample under the spline force
(:mod:`ebb_model.reference.exact_fe`): lightly damped accelerometer records
judge a model to a fraction of a per cent in frequency, which Newmark
accelerations do not resolve.  The two time-varying effects are integrated
with the Newmark average-acceleration rule at its own sub-step (default 8 per
sample, Richardson-extrapolated with a 16-sub-step run) by
:mod:`ebb_model.reference.newmark_banded` (``integrator`` chooses).

Every effect of the catalogue (:mod:`ebb_model.reference.withheld`) is built
into the finite-element model or the integrator (settings assembled by
:mod:`ebb_model.reference.truth_model`):

==================================  =============================================================
effect                              implementation
==================================  =============================================================
``boundary_rotational_*``           end rotational spring: replaces ``kr = inf`` of a fixed end,
                                    else is added to the end's ``kr``
``boundary_translational_*``        same for ``kt``
``point_mass``                      :math:`m\,\phi(x)\phi(x)^T` added to :math:`M`
``grounded_spring``                 :math:`k\,\phi(x)\phi(x)^T` added to :math:`K`
``stiffness_loss``                  the elements of the segment with ``factor`` × EI (compliance-
                                    averaged where an element is partly covered)
``kelvin_voigt``                    :math:`\eta` added to the config's: :math:`C \mathrel{+}= \eta K_b`
``rotary_inertia``                  :math:`\rho I` added to the config's: :math:`M \mathrel{+}= \rho I\int N'^TN'`
``foundation``                      :math:`k_f` added to the config's: :math:`K \mathrel{+}= k_f\int N^TN`
``actuator_lag``                    force felt = measured force through :math:`1/(\tau s+1)`:
                                    extra states of the exact integrator (Newmark: integrated
                                    exactly per sub-step, force linear within a sub-step)
``sensor_lag``                      the sensor's quantity through :math:`1/(\tau s+1)`, same rule
``axial_drift``                     :math:`N(t) = N + r t`: effective matrix refactorised (banded
                                    Cholesky) every sub-step
``geometric_stiffening``            :math:`N = N_0 + \frac{EA}{2L} q^T G q`: Newton iteration per
                                    sub-step (tolerance ``1e-12``, Sherman–Morrison tangent)
``cubic_spring``, ``dry_friction``, (outside the diagnosis catalogue) a local element on
``contact_stop``                    :math:`\xi = w(x)`: force :math:`k_3\xi^3`,
                                    :math:`F_c\tanh(\dot\xi/v_0)` or :math:`k\max(\xi - g, 0)`;
                                    Newton per sub-step as above
==================================  =============================================================

Conventions
-----------
* The record starts at rest with zero force before :math:`t_0 = 0`; sample
  ``k`` is at :math:`t_k = k\,\Delta t` with ``dt`` from the config.
* ``inputs`` are the **measured** forces (returned unchanged).  Between
  samples the force is reconstructed at the sub-step nodes by a cubic
  interpolating spline (default, ``interpolation="cubic"``) or linearly
  (``"linear"``).  The spline is the better model of a smooth band-limited
  force: the kinks of the linear reconstruction put spectral images of the
  input near multiples of the sample rate, which excite high modes whose
  sampled accelerations alias into the band and depend on the mesh.
  Measured against a converged truth driven by the exactly band-limited
  (Fourier-interpolated) force, clamped–free beam, band 1–300 Hz at
  ``dt = 2e-4``: defaults with the spline 3–6e-5 (displacement), 4–8e-4
  (velocity), 0.7–1.4e-3 (acceleration) relative RMS error; with linear
  reconstruction 3e-4, 3e-3 and 1.5–1.8e-2, and 4–5e-2 for acceleration with
  a finer mesh (no convergence).  The finite-difference model holds each
  sample over its interval instead; the difference is part of the "physical"
  truth.
* Inputs should start at zero and be smooth (as :func:`band_limited_input`'s
  are).  A force step (e.g. :math:`u_0 \ne 0`) excites every finite-element
  mode, and the average-acceleration rule does not damp modes it cannot
  resolve (:math:`\omega h \gg 1`): velocity and especially acceleration
  outputs then carry mesh-dependent high-frequency content.
* Outputs are the displacement, velocity or acceleration at each sensor's
  position, sampled at :math:`t_k`.
* Noise: independent white Gaussian noise on each sensor with standard
  deviation ``noise`` times the RMS of that sensor's clean output.

Accuracy
--------
The exact integrator has no time error for the reconstructed force (checked
against an adaptive 8th-order Runge–Kutta solve to 1e-7,
``tests/test_exact_scheme.py``); on a clamped–free case (band 1–300 Hz,
``dt = 2e-4``) the default mesh differs from 192 elements by 3.5e-5
(displacement), 3.5e-4 (velocity), 6e-4 (acceleration) relative RMS, and the
two integrators agree to 3e-5 on the fine mesh (``tests/test_synthetic.py``).
Newmark's error is :math:`O(h^2)` (period error :math:`(\omega h)^2/12`) with
a smooth expansion in :math:`h^2`, so with ``richardson=True`` (default) the
record is :math:`(4 y_{2m} - y_m)/3` from runs with ``m = substeps`` and
``2m`` sub-steps: fourth order in time at three times the cost of one run.
On the case above the time error of the defaults is below 1e-4 relative
(plain Newmark with 8 sub-steps: 4–7e-4 displacement, 0.9–1.7e-2
acceleration); the mesh error of 64 elements is 3–6e-5 (displacement) and
0.7–1.4e-3 (acceleration), of 48 elements 1–2e-4 and 2–4e-3.  Free
vibrations reproduce closed-form pinned–pinned frequencies (with rotary
inertia, foundation, axial drift) to ~1e-5 and the exact Duffing backbone of
geometric stiffening to ~1e-6 (``tests/test_synthetic.py``).

Cost (one core, 8000 samples, 64 elements, defaults): about 0.6 s CPU for a
linear time-invariant truth (1.2 s with a sensor lag), 1.2 s with axial
drift, 2.9 s with geometric stiffening.

Example
-------
::

    from ebb_model.reference.synthetic import band_limited_input, synthesize, WithheldEffect
    u = band_limited_input(4000, cfg.time.dt, 5.0, 400.0, n_inputs=len(cfg.actuators), seed=1)
    rec = synthesize(cfg, u, effect=WithheldEffect("foundation", {"kf": 2e4}), noise=0.01, seed=2)
    rec.outputs          # noisy; rec.outputs_clean without noise
"""
from __future__ import annotations

import math
from functools import partial
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from ..arrays import as_matrix
from ..checks import finite_scalar
from ..config import BeamConfig
from ..errors import ConfigError, DataError, ParameterError
from .exact_fe import exact_fe_response
from .excitation import EXCITATION_KINDS, band_limited_input
from .hermite_fe import SENSOR_KINDS, HermiteBeam
from .newmark_banded import newmark_banded
from .record import SyntheticRecord
from .truth_model import Truth, apply_effects, build_beam, uses_exact
from .withheld import EFFECT_CATALOGUE, EFFECT_NAMES, WithheldEffect

__all__ = [
    "SyntheticRecord",
    "synthesize",
    "band_limited_input",
    "WithheldEffect",
    "EFFECT_CATALOGUE",
    "EFFECT_NAMES",
    "EXCITATION_KINDS",
    "GENERATOR_PARAMETERS",
    "DEFAULT_N_ELEMENTS",
    "DEFAULT_SUBSTEPS",
    "INTERPOLATIONS",
    "INTEGRATORS",
]

#: Physical parameters the generator reads (``rhoI`` and ``kf`` default to 0).
GENERATOR_PARAMETERS: tuple[str, ...] = ("EI", "rhoA", "c", "eta", "N", "rhoI", "kf")
#: Default number of cubic Hermite elements.
DEFAULT_N_ELEMENTS = 64
#: Default Newmark steps per sample interval.
DEFAULT_SUBSTEPS = 8
#: Reconstructions of the force between samples.
INTERPOLATIONS: tuple[str, ...] = ("cubic", "linear", "bandlimited")
#: ``interpolation="bandlimited"``: the force resampled this many times finer by its Fourier series (the record
#: taken as one period), then the spline through the fine samples (at 0.4 fs its error is that of the spline at
#: 0.05 of the fine rate: ~1e-6).
BANDLIMITED_OVERSAMPLING = 8
#: Time integrators of the generator ("auto": exact for time-invariant truths, else Newmark).
INTEGRATORS: tuple[str, ...] = ("auto", "exact", "newmark")


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def _parameters(config: BeamConfig, params: Mapping[str, float] | None) -> dict[str, float]:
    values = dict(config.parameter_values())
    base = {k: float(values.get(k, 0.0)) for k in GENERATOR_PARAMETERS}
    if params is not None:
        if not isinstance(params, Mapping):
            raise ParameterError(f"params must be a mapping, got {type(params).__name__}")
        unknown = sorted(set(params) - set(GENERATOR_PARAMETERS))
        if unknown:
            raise ParameterError(
                [f"params.{k}: unknown parameter; allowed: {', '.join(GENERATOR_PARAMETERS)}" for k in unknown]
            )
        for k, v in params.items():
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ParameterError(f"params.{k}: must be a number, got {v!r}")
            base[k] = float(v)
    problems = []
    for k, v in base.items():
        if not math.isfinite(v):
            problems.append(f"params.{k}: must be finite, got {v!r}")
        elif k in ("EI", "rhoA") and not v > 0.0:
            problems.append(f"params.{k}: must be > 0, got {v:g}")
        elif k in ("c", "eta", "rhoI", "kf") and v < 0.0:
            problems.append(f"params.{k}: must be >= 0, got {v:g}")
    if problems:
        raise ParameterError(problems)
    return base


def _effects(effect: WithheldEffect | Sequence[WithheldEffect] | None) -> tuple[WithheldEffect, ...]:
    if effect is None:
        return ()
    items = (effect,) if isinstance(effect, WithheldEffect) else tuple(effect)
    for e in items:
        if not isinstance(e, WithheldEffect):
            raise ConfigError(f"effect must be a WithheldEffect (or a sequence of them), got {e!r}")
    names = [e.name for e in items]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"effect: {', '.join(dup)} given more than once")
    return items


def _force_at_substeps(U: np.ndarray, m: int, interpolation: str) -> np.ndarray:
    """The measured force at the Newmark sub-step nodes ``j dt/m`` (``j = 0 .. (n-1) m``)."""
    n = U.shape[0]
    s = np.arange(m) / m
    if interpolation == "linear" or n < 3:
        F = (U[:-1, None, :] * (1.0 - s)[None, :, None] + U[1:, None, :] * s[None, :, None]).reshape(-1, U.shape[1])
    else:
        spline = CubicSpline(np.arange(n), U, axis=0, bc_type="not-a-knot")
        F = spline((np.arange(n - 1)[:, None] + s[None, :]).ravel())
        F[::m] = U[:-1]  # the knots exactly
    return np.vstack([F, U[-1:]])


def _check_options(config: BeamConfig, n_elements: int, substeps: int, noise: float, seed: int,
                   richardson: bool, interpolation: str, integrator: str) -> None:
    """Check the scalar arguments of :func:`synthesize` (same names), the first bad one raising.

    Raises
    ------
    ConfigError
        ``config`` is not a :class:`BeamConfig`.
    ParameterError
        Another argument is invalid.
    """
    if not isinstance(config, BeamConfig):
        raise ConfigError(f"config must be a BeamConfig, got {type(config).__name__}")
    if isinstance(n_elements, bool) or not isinstance(n_elements, (int, np.integer)) or n_elements < 2:
        raise ParameterError(f"n_elements must be an integer >= 2, got {n_elements!r}")
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ParameterError(f"substeps must be an integer >= 1, got {substeps!r}")
    finite_scalar("noise", noise, minimum=0.0, numbers_only=True)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ParameterError(f"seed must be an integer, got {seed!r}")
    if not isinstance(richardson, (bool, np.bool_)):
        raise ParameterError(f"richardson must be True or False, got {richardson!r}")
    if interpolation not in INTERPOLATIONS:
        raise ParameterError(f"interpolation must be one of {', '.join(INTERPOLATIONS)}, got {interpolation!r}")
    if integrator not in INTEGRATORS:
        raise ParameterError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")


def _newmark_operators(beam: HermiteBeam, config: BeamConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The actuators' load vectors ``Phi``, the sensors' displacement ``rows`` and ``kinds`` (:data:`SENSOR_KINDS`).

    Parameters
    ----------
    beam, config
        Finite-element model and beam set-up.

    Returns
    -------
    tuple of numpy.ndarray
        ``Phi`` ``(n_dof, n_actuators)``, ``rows`` ``(n_sensors, n_dof)``, ``kinds`` (``int64``).
    """
    Phi = np.column_stack([beam.load_vector(a.x) for a in config.actuators])
    rows = np.vstack([beam.displacement_row(s.x) for s in config.sensors])
    kinds = np.array([SENSOR_KINDS.index(s.kind) for s in config.sensors], dtype=np.int64)
    return Phi, rows, kinds


def _newmark_run(beam: HermiteBeam, operators: tuple[np.ndarray, np.ndarray, np.ndarray], truth: Truth,
                 U: np.ndarray, dt: float, interpolation: str, length: float, k: int) -> np.ndarray:
    """The clean outputs of one Newmark run (:func:`newmark_banded`), ``k`` sub-steps per sample interval.

    Parameters
    ----------
    beam, operators, truth
        Finite-element model, its :func:`_newmark_operators`, effect settings.
    U, dt, interpolation
        Measured forces ``(n_samples, n_actuators)``, sample interval, force reconstruction.
    length
        Beam length (stretching stiffness ``EA / L``).
    k
        Sub-steps per sample interval.

    Returns
    -------
    numpy.ndarray
        ``(n_samples, n_sensors)``.
    """
    assert beam.K_axial is not None
    Phi, rows, kinds = operators
    F = _force_at_substeps(U, k, interpolation)
    return newmark_banded(
        beam.M, beam.C, beam.K, beam.K_axial, Phi, rows, kinds, F, dt, k,
        rate=truth.rate, ea_over_l=truth.ea / length, actuator_tau=truth.act_tau, lag_sensor=truth.lag_sensor,
        sensor_tau=truth.sen_tau, local_row=None if truth.local_x is None else beam.displacement_row(truth.local_x),
        k3=truth.k3, friction=truth.friction, slip_velocity=truth.slip, stop_k=truth.stop_k, stop_gap=truth.stop_gap,
    )


def _simulate(beam: HermiteBeam, config: BeamConfig, truth: Truth, U: np.ndarray, dt: float,
              operators: tuple[np.ndarray, np.ndarray, np.ndarray], *, exact: bool, substeps: int,
              interpolation: str, richardson: bool) -> np.ndarray:
    """The clean outputs of the truth, integrated exactly or by Newmark (Richardson-combined if asked).

    Parameters
    ----------
    beam, config, truth
        Finite-element model, beam set-up, effect settings.
    U, dt
        Measured forces ``(n_samples, n_actuators)`` and sample interval.
    operators
        :func:`_newmark_operators` of ``beam`` (Newmark only).
    exact, substeps, interpolation, richardson
        Exact integration (:func:`exact_fe_response`) or Newmark; the options of :func:`synthesize`.

    Returns
    -------
    numpy.ndarray
        ``(n_samples, n_sensors)``.
    """
    if any(a.antialias is not None for a in config.actuators):
        raise DataError("a filter on the force's channel: the truth takes the forces the beam felt, not a filtered "
                        "record of them (declare the sensors' filters only)")
    if exact:
        y = exact_fe_response(beam, U, dt, [a.x for a in config.actuators],
                              [(s.x, s.kind) for s in config.sensors], interpolation=interpolation,
                              actuator_tau=truth.act_tau, lag_sensor=truth.lag_sensor, sensor_tau=truth.sen_tau,
                              filters=[None if s.antialias is None else (s.antialias.order, s.antialias.corner)
                                       for s in config.sensors])
    else:
        if any(s.antialias is not None for s in config.sensors):
            raise DataError("an anti-alias filter on a sensor needs the exact integrator (a time-invariant truth)")
        run = partial(_newmark_run, beam, operators, truth, U, dt, interpolation, float(config.beam.length))
        y = (4.0 * run(2 * substeps) - run(substeps)) / 3.0 if richardson else run(substeps)
    if not np.all(np.isfinite(y)):  # pragma: no cover - guarded by the positive-definiteness checks
        raise DataError("the simulated outputs are not finite")
    return y


def _add_noise(y: np.ndarray, noise: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Add white Gaussian noise, ``noise`` times each column's RMS (seed ``seed``), to the clean outputs ``y``.

    Returns
    -------
    tuple of numpy.ndarray
        The noisy outputs and the noise standard deviation per column.
    """
    rms = np.sqrt(np.mean(y * y, axis=0))
    std = float(noise) * rms
    rng = np.random.default_rng(int(seed))
    noisy = y + rng.standard_normal(y.shape) * std
    return noisy, std


def _pack_record(config: BeamConfig, U: np.ndarray, y: np.ndarray, noisy: np.ndarray, std: np.ndarray, dt: float,
                 *, p: Mapping[str, float], effects: tuple[WithheldEffect, ...], n_elements: int, substeps: int,
                 richardson: bool, interpolation: str, exact: bool) -> SyntheticRecord:
    """The :class:`SyntheticRecord` of a simulation, its arrays read-only (``U`` copied first).

    Parameters
    ----------
    config, U, y, noisy, std, dt
        Beam set-up, measured forces, clean and noisy outputs, noise level per sensor, sample interval.
    p, effects, n_elements, substeps, richardson, interpolation, exact
        What was simulated (``exact``: by the exact integrator).

    Returns
    -------
    SyntheticRecord
    """
    U_out = U.copy()
    for a in (U_out, y, noisy, std):
        a.setflags(write=False)
    time = np.arange(U.shape[0]) * dt
    time.setflags(write=False)
    return SyntheticRecord(
        time=time, inputs=U_out, outputs_clean=y, outputs=noisy, noise_std=std, input_names=config.input_names,
        output_names=config.output_names, parameters=MappingProxyType(dict(p)), effects=effects,
        n_elements=int(n_elements), substeps=substeps, richardson=bool(richardson) and not exact,
        interpolation=interpolation, integrator="exact" if exact else "newmark",
    )


# --------------------------------------------------------------------------
# generator
# --------------------------------------------------------------------------
def synthesize(
    config: BeamConfig,
    inputs: np.ndarray,
    *,
    params: Mapping[str, float] | None = None,
    effect: WithheldEffect | Sequence[WithheldEffect] | None = None,
    n_elements: int = DEFAULT_N_ELEMENTS,
    substeps: int = DEFAULT_SUBSTEPS,
    noise: float = 0.01,
    seed: int = 0,
    interpolation: str = "cubic",
    richardson: bool = True,
    integrator: str = "auto",
) -> SyntheticRecord:
    """Simulate a "measured" record of the beam in ``config`` with an optional withheld effect.

    Parameters
    ----------
    config
        Beam set-up; its ``dt`` is the sample interval, its ``theta``,
        ``substeps`` and ``nodes`` (settings of the finite-difference model)
        are ignored.
    inputs
        Measured actuator forces [N], shape ``(n_samples, n_actuators)``
        (1-D for one actuator), sample ``k`` at ``k dt``; linearly
        interpolated between samples.
    params
        Overrides of the physical parameters ``EI, rhoA, c, eta, N, rhoI, kf``
        (default: the config's values; ``rhoI``, ``kf`` are 0 if the config
        has none).
    effect
        A :class:`WithheldEffect` (or several with different names) added to
        the truth; ``None`` for none.
    n_elements
        Number of cubic Hermite elements (>= 2).
    substeps
        Newmark steps per sample interval (>= 1; not used by the exact integrator).
    interpolation
        Reconstruction of the force between samples: ``"cubic"`` (spline,
        default), ``"linear"``, or ``"bandlimited"`` — the record's
        trigonometric interpolant (its Fourier series, the record one period:
        a force faded in and out, band-limited below the Nyquist frequency),
        by :data:`BANDLIMITED_OVERSAMPLING`-fold resampling and the spline
        through the fine samples; independent of the model's kernel
        (:mod:`ebb_model.acquisition.bandlimited`).
    richardson
        Newmark only: combine runs with ``substeps`` and ``2 * substeps`` to
        cancel the :math:`O(h^2)` Newmark error (default ``True``).
    integrator
        ``"exact"``: matrix exponential of the finite-element system (with
        lag states) under the reconstructed force, per sample interval
        (:mod:`ebb_model.reference.exact_fe`) — no time error of its own;
        for time-invariant truths only.  ``"newmark"``:
        the average-acceleration rule (any effect).  ``"auto"`` (default):
        exact unless the truth varies in time (``axial_drift``,
        ``geometric_stiffening``).
    noise
        Noise standard deviation relative to each sensor's clean RMS (>= 0).
    seed
        Seed of the noise generator (:func:`numpy.random.default_rng`).

    Returns
    -------
    SyntheticRecord

    Raises
    ------
    ConfigError
        Unknown/duplicate effect, ``sensor_lag`` of a sensor not in the config.
    ParameterError
        Invalid parameter, effect value (e.g. a point mass outside the
        beam), ``n_elements``, ``substeps``, ``noise`` or ``seed``.
    DataError
        Inputs of the wrong shape or with non-finite values.
    StabilityError
        The truth is not a small vibration: the (drifting) axial force exceeds
        the buckling load within the record, or the stiffening Newton
        iteration did not converge.
    """
    _check_options(config, n_elements, substeps, noise, seed, richardson, interpolation, integrator)
    p = _parameters(config, params)
    effects = _effects(effect)
    U = as_matrix(inputs, "inputs", shape=(None, len(config.actuators)), columns=config.input_names, min_rows=2,
                  column="actuator")
    dt = float(config.time.dt)
    truth = apply_effects(config, p, effects)
    beam = build_beam(config, p, truth, n_elements, U.shape[0], dt)
    operators = _newmark_operators(beam, config)
    exact = uses_exact(integrator, truth)
    m = int(substeps)
    if interpolation == "bandlimited":
        from scipy.signal import resample

        R = BANDLIMITED_OVERSAMPLING
        y = _simulate(beam, config, truth, resample(U, U.shape[0] * R, axis=0), dt / R, operators, exact=exact,
                      substeps=m, interpolation="cubic", richardson=richardson)[::R]
    else:
        y = _simulate(beam, config, truth, U, dt, operators, exact=exact, substeps=m, interpolation=interpolation,
                      richardson=richardson)
    noisy, std = _add_noise(y, noise, seed)
    return _pack_record(config, U, y, noisy, std, dt, p=p, effects=effects, n_elements=n_elements, substeps=m,
                        richardson=richardson, interpolation=interpolation, exact=exact)
