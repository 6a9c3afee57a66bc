"""The measurement chain's gains (signal-level): calibration and unit errors of a transducer.

``sensor_gain[<sensor>]`` (``gain``)
    That sensor's reading is ``gain`` times the quantity at its position (a sensitivity entered wrong, a unit
    taken for another: g for m/s², lbf for N).
``actuator_gain`` (``gain``)
    The force the beam feels is ``gain`` times the measured force (the load cell's sensitivity).

Common in real labs, and degenerate with the beam: scaling EI, ρA, c and N by ``k`` scales every receptance by
``1/k`` — exactly an actuator gain ``1/k``, or the same gain on every sensor.  When those are baseline unknowns,
only a prior on them (the strip's documented size and material) separates a chain error from a beam of another
size; the diagnosis says so (:func:`diagnosis.problem.plausibility.confounded`).  A sign error (``gain < 0``) is not a
candidate here: no continuous refit passes from +1 to −1 through a reading of zero — the force's sign is weighed
before, by fitting the baseline both ways (:mod:`diagnosis.baseline.polarity`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable, cast

import numpy as np

from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.statespace import DiscreteStateSpace

from .base import Effect, Family, Scales, Signal, sensor_index, signal_effect

__all__ = ["FAMILY", "GAIN_RANGE", "ActuatorGain", "SensorGain"]

#: Search range of a gain: from a unit error one way (lbf for N: 4.45; g for m/s²: 9.81; in for m: 39.4) to the
#: other.
GAIN_RANGE = (0.02, 50.0)


@dataclass(frozen=True)
class SensorGain(Signal):
    """Sensor ``sensor`` reads ``gain`` times its quantity."""

    sensor: str
    gain: float
    description = "a sensor's gain (calibration or unit) error"

    def __post_init__(self) -> None:
        object.__setattr__(self, "gain", finite_scalar(f"sensor_gain[{self.sensor}].gain", self.gain))

    def _index(self, names: tuple[str, ...]) -> int:
        return sensor_index("sensor_gain", self.sensor, names)

    def outputs(self, y: np.ndarray, dt: float, names: tuple[str, ...]) -> np.ndarray:
        i = self._index(tuple(names))
        y = y.copy()
        y[:, i] *= self.gain
        return y

    def in_series(self, sys: DiscreteStateSpace) -> DiscreteStateSpace:
        i = self._index(tuple(sys.output_names))
        C, D = sys.C.copy(), sys.D.copy()
        C[i] *= self.gain
        D[i] *= self.gain
        return DiscreteStateSpace(sys.A, sys.B, C, D, sys.dt, sys.input_names, sys.output_names,
                                  sys.state_names, sys.hold, sys.advance, sys.output_delays)


@dataclass(frozen=True)
class ActuatorGain(Signal):
    """The beam feels ``gain`` times the measured force(s)."""

    gain: float
    description = "the actuator's (load cell's) gain error"

    def __post_init__(self) -> None:
        object.__setattr__(self, "gain", finite_scalar("actuator_gain.gain", self.gain))

    def inputs(self, u: np.ndarray, dt: float) -> np.ndarray:
        return u * self.gain

    def in_series(self, sys: DiscreteStateSpace) -> DiscreteStateSpace:
        hold = None if sys.hold is None else sys.hold * self.gain     # at rest under the scaled force
        return DiscreteStateSpace(sys.A, sys.B * self.gain, sys.C, sys.D * self.gain, sys.dt, sys.input_names,
                                  sys.output_names, sys.state_names, hold, sys.advance, sys.output_delays)


#: The beam's unknowns whose common scale ``k`` scales every receptance by ``1/k`` (η, a time constant, and the
#: positions do not take part).
SCALED = ("EI", "rhoA", "c", "N")


def rescaled_start(names: tuple[str, ...], beta: np.ndarray, s: np.ndarray, prior: Any
                   ) -> tuple[np.ndarray, np.ndarray] | None:
    """The point of the data's flat valley — the beam's unknowns ``β_i`` (i in :data:`SCALED`) times ``k``, the
    gain times ``k`` — where the priors on them are best: ``k = Σ β_i μ_i/σ_i² / Σ β_i²/σ_i²``.  Local fits
    crawl along that curved valley (the data's curvature across it dwarfs the priors' along it); a start at its
    best point needs no crawl.  ``None`` without a prior on a scaled unknown."""
    idx = [i for i, n in enumerate(names) if n in SCALED]
    with_prior = [i for i in idx if np.isfinite(prior.std[i])]
    if not with_prior:
        return None
    b, mu, sd = beta[with_prior], prior.mean[with_prior], prior.std[with_prior]
    k = float(np.sum(b * mu / sd ** 2) / np.sum(b * b / sd ** 2))
    moved = np.array(beta, dtype=float)
    moved[idx] *= k
    return moved, np.asarray(s, dtype=float) * k


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """The actuators' common gain and each sensor's, in :data:`GAIN_RANGE` (off: 1)."""
    effects = ((signal_effect("actuator_gain", None, "gain", GAIN_RANGE, 1.0,
                              "gain (calibration or unit) error of the measured force", ActuatorGain, "gain", "1"),)
               # typed by the cast: mypy cannot infer a lambda with a default argument in context (python/mypy#15459)
               + tuple(signal_effect("sensor_gain", s.name, "gain", GAIN_RANGE, 1.0,
                                     f"gain (calibration or unit) error of sensor {s.name}",
                                     cast("Callable[[float], Signal]", lambda g, name=s.name: SensorGain(name, g)),
                                     "gain", "1")
                       for s in config.sensors))
    return tuple(replace(e, rescale=rescaled_start, scale_degenerate=True) for e in effects)


#: This module's entry in the catalogue.
FAMILY = Family(("actuator_gain", "sensor_gain"), candidates)
