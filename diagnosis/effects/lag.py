r"""First-order lags between the measured signals and the beam (signal-level).

``actuator_lag`` (``tau``)
    The force the beam feels is the measured force through ``1/(τ s + 1)``.
``sensor_lag[<sensor>]`` (``tau``)
    That sensor's reading is the simulated quantity (displacement, velocity or acceleration — the filter is
    LTI, so it acts on the quantity itself) through ``1/(τ s + 1)``.

Both are simulated by :func:`first_order_lag`, the exact discretisation for a piecewise-linear signal, and as a
StateSpace by the same recursion as states in series (:meth:`ActuatorLag.in_series`,
:meth:`SensorLag.in_series`), so the corrected model reproduces the diagnosis' refit to round-off.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, cast

import numpy as np
import scipy.signal as ss

from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.errors import DataError, ParameterError
from ebb_model.statespace import DiscreteStateSpace

from .base import Effect, Family, Scales, Signal, sensor_index, signal_effect

__all__ = ["FAMILY", "first_order_lag", "lag_coefficients", "ActuatorLag", "SensorLag"]


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


def _actuator_lag(sys: DiscreteStateSpace, tau: float) -> DiscreteStateSpace:
    """``sys`` driven through ``1/(τ s + 1)`` on every input (lag first, in series)."""
    a, b0, b1 = lag_coefficients(sys.dt / tau)
    m, n = sys.ninputs, sys.nstates
    eye = np.eye(m)
    # lag: w[k+1] = a w + (a b0 + b1) u[k], f = w + b0 u  (w = f − b0 u)
    A = np.block([[a * eye, np.zeros((m, n))], [sys.B, sys.A]])
    B = np.vstack([(a * b0 + b1) * eye, b0 * sys.B])
    C = np.hstack([sys.D, sys.C])
    D = b0 * sys.D
    gamma1 = sys.hold if sys.hold is not None else np.zeros((n, m))
    hold = np.vstack([-(1.0 - b0) * eye, gamma1])        # at rest: steady lag (f[0] = u[0]), beam as before
    states = tuple(f"lag({u})" for u in sys.input_names) + tuple(sys.state_names)
    return DiscreteStateSpace(A, B, C, D, sys.dt, sys.input_names, sys.output_names, states, hold, sys.advance,
                              sys.output_delays)


def _sensor_lag(sys: DiscreteStateSpace, sensor: str, tau: float) -> DiscreteStateSpace:
    """``sys`` with output ``sensor`` through ``1/(τ s + 1)`` (in series)."""
    a, b0, b1 = lag_coefficients(sys.dt / tau)
    i = sys.output_names.index(sensor)
    n, m = sys.nstates, sys.ninputs
    ci, di = sys.C[i], sys.D[i]
    A = np.block([[sys.A, np.zeros((n, 1))], [(a * b0 + b1) * ci[None, :], np.array([[a]])]])
    B = np.vstack([sys.B, (a * b0 + b1) * di[None, :]])
    C = np.hstack([sys.C, np.zeros((sys.noutputs, 1))])
    D = sys.D.copy()
    C[i] = np.concatenate([b0 * ci, [1.0]])
    D[i] = b0 * di
    gamma1 = sys.hold if sys.hold is not None else np.zeros((n, m))
    # at rest: the lag starts steady at the sensor's first sample, y[0] = C_i ξ0 + D_i u0 with ξ0 = −Γ1 u0
    hold = np.vstack([gamma1, ((1.0 - b0) * (ci @ gamma1 - di))[None, :]])
    return DiscreteStateSpace(A, B, C, D, sys.dt, sys.input_names, sys.output_names,
                              tuple(sys.state_names) + (f"lag({sensor})",), hold, sys.advance, sys.output_delays)


@dataclass(frozen=True)
class ActuatorLag(Signal):
    """Every input reaches the beam through ``1/(τ s + 1)`` (steady start at the first sample)."""

    tau: float
    description = "the actuator's first-order lag"

    def __post_init__(self) -> None:
        object.__setattr__(self, "tau", finite_scalar("actuator_lag.tau", self.tau, minimum=0.0))

    def inputs(self, u: np.ndarray, dt: float) -> np.ndarray:
        return np.ascontiguousarray(first_order_lag(u, dt, self.tau)) if self.tau > 0.0 else u

    def in_series(self, sys: DiscreteStateSpace) -> DiscreteStateSpace:
        return _actuator_lag(sys, self.tau) if self.tau > 0.0 else sys


@dataclass(frozen=True)
class SensorLag(Signal):
    """Sensor ``sensor`` records its quantity through ``1/(τ s + 1)`` (steady start at its first sample)."""

    sensor: str
    tau: float
    description = "a sensor's first-order lag"

    def __post_init__(self) -> None:
        object.__setattr__(self, "tau", finite_scalar(f"sensor_lag[{self.sensor}].tau", self.tau, minimum=0.0))

    def _index(self, names: tuple[str, ...]) -> int:
        return sensor_index("sensor_lag", self.sensor, names)

    def outputs(self, y: np.ndarray, dt: float, names: tuple[str, ...]) -> np.ndarray:
        i = self._index(tuple(names))
        if self.tau == 0.0:
            return y
        y = y.copy()
        y[:, i] = first_order_lag(y[:, i], dt, self.tau)
        return y

    def in_series(self, sys: DiscreteStateSpace) -> DiscreteStateSpace:
        self._index(tuple(sys.output_names))
        return _sensor_lag(sys, self.sensor, self.tau) if self.tau > 0.0 else sys


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """The actuator's lag and each sensor's, ``τ`` up to ``3/ω`` of the highest mode in the band."""
    hi = 3.0 / scales.omega_high
    return ((signal_effect("actuator_lag", None, "tau", (0.0, hi), 0.0,
                           "first-order lag between the measured force and the force the beam feels",
                           ActuatorLag, "tau", "s"),)
            # typed by the cast: mypy cannot infer a lambda with a default argument in context (python/mypy#15459)
            + tuple(signal_effect("sensor_lag", s.name, "tau", (0.0, hi), 0.0, f"first-order lag of sensor {s.name}",
                                  cast("Callable[[float], Signal]", lambda tau, name=s.name: SensorLag(name, tau)),
                                  "tau", "s")
                    for s in config.sensors))


#: This module's entry in the catalogue.
FAMILY = Family(("actuator_lag", "sensor_lag"), candidates)
