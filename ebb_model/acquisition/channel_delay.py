r"""A channel's own delay: the group delay of a sigma-delta converter's decimation filter.

A sigma-delta converter samples far above the output rate and decimates through a linear-phase digital filter:
the sample it reports at ``t_k`` is the (band-limited) signal at ``t_k − τ``, ``τ`` the filter's group delay —
often tens of samples, the same on every channel of one card, different across cards (a force on one card and an
accelerometer on another are offset by the difference).  A channel declares it in the config, in seconds::

    [[sensors]]
    name = "a1"
    x = 0.5
    kind = "acceleration"
    delay = 0.0019           # s: this channel's converter reports the signal 1.9 ms late

    [[actuators]]
    name = "F1"
    x = 0.45
    delay = 0.0019           # the force's channel, if on a card with a delay

What relates a recorded force to a recorded response is the difference: the force recorded ``τ_f`` late and
the response ``τ_s`` late make the model's output ``y(t_k − (τ_s − τ_f))`` (:func:`effective_delays`; the force
channels must share one delay, as one card's do).  Equal delays cancel, as equal anti-alias filters do
(:mod:`ebb_model.acquisition.antialias`); a sensor on a faster card leads the force (a negative difference: the model
reads the force ahead, which a record allows).

The model takes it exactly in time for a band-limited record.  Whole samples shift the output sequence
(exact under any force between samples); a fraction ``f`` of a sample interpolates it with the band-limited
kernel ``φ`` of :mod:`ebb_model.acquisition.bandlimited`,

.. math::

    y(t_k − (q + f)T) = \sum_{i=−M+1}^{M} φ(i − f)\, y[k − q − i],

exact to :data:`~ebb_model.acquisition.bandlimited.RECONSTRUCTION_ERROR` when the response is band-limited to
:data:`~ebb_model.acquisition.bandlimited.BAND` of the sampling rate — which it is when the force is, the premise of
``[time] input = "bandlimited"``.  A fractional delay therefore needs that setting (a polynomial force between
samples has images above the band that the kernel does not reproduce); a converter that delays is a DAQ, whose
records are band-limited anyway.  Before the record the output is held at its first value and after it at its
last (as the force is, :func:`ebb_model.acquisition.bandlimited.lead_in`).

The frequency response of a delayed channel is the beam's times ``e^{−iωτ}`` (:func:`delay_response`).  What is
driven sample by sample — the FMUs, a StateSpace for control design, the exports of an identified or corrected
model — carries the delays as delay-line states (:mod:`ebb_model.acquisition.delay_line`), or, where no causal
delay line exists (a sensor ahead of the force's channel, a fraction of a sample too short to interpolate from the
past), leaves them out and says so.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Sequence, TypeVar

import numpy as np

from .bandlimited import HALF_WIDTH, kernel

if TYPE_CHECKING:
    from ..beam import Actuator, Sensor
    from ..config import BeamConfig

__all__ = ["MAX_DELAY_SAMPLES", "WHOLE", "channel_problems", "effective_delays", "with_channel_delays",
           "without_delays", "delay_outputs", "delay_response"]

S = TypeVar("S")

#: The longest delay a channel may declare, in samples: a converter's decimation filter delays by tens of
#: samples at any output rate (it is counted in output samples); beyond this a config's delay is a unit mistake
#: (ms typed as s).
MAX_DELAY_SAMPLES = 1000
#: A delay within this share of a sample of a whole number of samples is that whole number (a delay given in
#: seconds at a sampling rate whose period is not a binary fraction carries round-off).
WHOLE = 1e-9


def _samples(delay: float, dt: float) -> float:
    """``delay`` [s] in samples, snapped to the nearest whole number within :data:`WHOLE`."""
    d = delay / dt
    return float(round(d)) if abs(d - round(d)) <= WHOLE else d


def channel_problems(actuators: Sequence[Any], sensors: Sequence[Any], dt: float | None, hold: str,
                     scheme: str) -> list[tuple[str, str]]:
    """``(field, message)`` of each channel delay the model cannot take: force channels with different delays, a
    difference of more than :data:`MAX_DELAY_SAMPLES`, a fraction of a sample without the band-limited force
    between samples (module docstring) or with the θ-scheme; empty when consistent."""
    forces = {float(getattr(a, "delay", 0.0)) for a in actuators}
    if len(forces) > 1:
        return [("actuators", "the force channels' delays differ: the model takes one delay on every force channel "
                              "(one card's); record the forces on one card or shift them before the fit")]
    if dt is None:
        return []
    force = next(iter(forces), 0.0)
    out: list[tuple[str, str]] = []
    for s in sensors:
        d = _samples(float(getattr(s, "delay", 0.0)) - force, dt)
        where = f"sensors.{s.name}.delay"
        if abs(d) > MAX_DELAY_SAMPLES:
            out.append((where, f"{d:.6g} samples from the force's channel is more than {MAX_DELAY_SAMPLES} "
                               "(a converter delays by tens of samples: is it in seconds?)"))
        elif d != round(d) and (hold != "bandlimited" or scheme != "exact"):
            out.append((where, f"{d:.6g} samples from the force's channel is a fraction of a sample: a converter's "
                               "delay is exact on a band-limited record — set [time] input = \"bandlimited\" "
                               "(scheme \"exact\"), or give whole samples"))
    return out


def effective_delays(config: BeamConfig) -> tuple[float, ...]:
    """Each sensor's delay after the force's, in samples (module docstring); ``()`` when every one is 0."""
    force = config.actuators[0].delay if config.actuators else 0.0
    d = tuple(_samples(s.delay - force, config.time.dt) for s in config.sensors)
    return d if any(d) else ()


def with_channel_delays(system: S, config: BeamConfig) -> S:
    """``system`` (a :class:`~ebb_model.statespace.DiscreteStateSpace` or
    :class:`~ebb_model.theta.modal_form.ModalStateSpace` of ``config``) carrying the config's :func:`effective_delays`
    as its ``output_delays``; ``system`` itself when there are none."""
    delays = effective_delays(config)
    return replace(system, output_delays=delays) if delays else system  # type: ignore[type-var]


def without_delays(config: BeamConfig) -> BeamConfig:
    """``config`` with every channel's delay 0 (the beam without its records' acquisition delays); ``config``
    itself when it declares none."""
    channels: tuple[Actuator | Sensor, ...] = (*config.actuators, *config.sensors)
    if not any(c.delay for c in channels):
        return config
    return replace(config, actuators=tuple(replace(a, delay=0.0) for a in config.actuators),
                   sensors=tuple(replace(s, delay=0.0) for s in config.sensors))


def delay_outputs(y: np.ndarray, delays: Sequence[float]) -> np.ndarray:
    """``y`` (n, p) with column ``i`` delayed by ``delays[i]`` samples (module docstring); ``y`` itself when
    ``delays`` is empty or all zero."""
    if not len(delays) or not any(delays) or y.shape[0] == 0:
        return y
    out = np.array(y, dtype=float, copy=True)
    n = y.shape[0]
    for i, d in enumerate(delays):
        if d == 0.0:
            continue
        q = math.floor(d)
        f = d - q
        if f == 0.0:
            idx = np.clip(np.arange(n) - q, 0, n - 1)        # held before and after the record
            out[:, i] = y[idx, i]
            continue
        taps = np.arange(-HALF_WIDTH + 1, HALF_WIDTH + 1)
        h = kernel(taps - f)                                  # weight of y[k − q − i], i = taps
        lo, hi = -q - HALF_WIDTH, n - q + HALF_WIDTH          # the samples k − q − i the record's k reach
        src = np.clip(np.arange(lo, hi), 0, n - 1)
        padded = y[src, i]
        # out[k] = Σ_i h[i] padded[k − q − i − lo]: a correlation of the padded column with h reversed
        full = np.convolve(padded, h, mode="full")
        start = -q - int(taps[0]) - lo                        # index in `full` of k = 0 (2M − 1)
        out[:, i] = full[start:start + n]
    return out


def delay_response(H: np.ndarray, f_hz: np.ndarray, dt: float, delays: Sequence[float]) -> np.ndarray:
    """``H[f, output, input]`` with each output's row times ``e^{−i2πf τ}``, ``τ = delays[i] dt``."""
    if not len(delays) or not any(delays):
        return H
    phase = np.exp(-2j * np.pi * np.outer(np.asarray(f_hz, dtype=float), np.asarray(delays, dtype=float) * dt))
    return H * phase[:, :, None]
