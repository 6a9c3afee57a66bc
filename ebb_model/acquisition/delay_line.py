r"""The channels' converter delays as states: what is driven sample by sample carries them too.

:func:`ebb_model.simulate` delays a channel's output after the run (:func:`~.channel_delay.delay_outputs`, which
may read the record's later samples).  A model driven one sample at a time — an FMU in a host, a StateSpace in a
control loop — has only the past, so the delay becomes a **delay line**: the channel's undelayed output ``ỹ`` of
each of the last samples kept as states, the delayed output their weighted sum

.. math::

    y[k] = \sum_{j} w_j\, ỹ[k − j],

``j = q`` with ``w = 1`` for a whole delay of ``q`` samples (exact under any force between samples), and for a
fraction ``f`` the band-limited kernel's taps ``j = q + i``, ``w = φ(i − f)``, ``i = −M+1 … M`` (the interpolation
:func:`~.channel_delay.delay_outputs` applies, the same numbers) — causal only when the delay is at least
``M − 1`` whole samples (:data:`MIN_FRACTIONAL`: the kernel reads ``M − 1`` samples after the one it delays).  A
negative delay (a sensor on a faster card than the force's) reads the force ahead, which no causal model can.
Both are refused with one line (:func:`delay_line`).

Before the record the delay line holds the first undelayed output (as :func:`~.channel_delay.delay_outputs` holds
it): a start at rest sets each of its states to ``ỹ[0] = (D − C Γ₁) u[0]``, which the returned system's ``hold``
says in the system's own convention (:class:`~ebb_model.statespace.DiscreteStateSpace`: ``ξ[0] = −hold · u[0]``).
So the delay line realised and iterated equals the native run to round-off (``tests/test_delay_line.py``).

The delays are taken after the force's channel (:func:`~.channel_delay.effective_delays`): the model's input is
the force as its channel recorded it, as for the anti-alias filters.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import ConfigError
from ..statespace import DiscreteStateSpace
from .bandlimited import HALF_WIDTH, kernel
from .channel_delay import effective_delays, without_delays

if TYPE_CHECKING:
    from ..config import BeamConfig

__all__ = ["MIN_FRACTIONAL", "delay_taps", "delay_line", "line_problems", "exported_config", "realised_line"]

#: The shortest delay [samples] whose fraction a causal delay line realises: the kernel reads ``M − 1`` samples
#: after the one it delays.
MIN_FRACTIONAL = HALF_WIDTH - 1


def delay_taps(delay: float) -> tuple[np.ndarray, np.ndarray]:
    """The lags ``j`` (samples, ascending, ``>= 0`` only when causal) and weights ``w_j`` of a delay of ``delay``
    samples (module docstring): ``([q], [1])`` for a whole ``q``, the kernel's ``2M`` taps for a fraction."""
    q = math.floor(delay)
    f = delay - q
    if f == 0.0:
        return np.array([q]), np.array([1.0])
    taps = np.arange(-HALF_WIDTH + 1, HALF_WIDTH + 1)
    return q + taps, kernel(taps - f)


def _refusal(name: str, delay: float) -> str | None:
    """Why the delay of ``delay`` samples on output ``name`` has no causal delay line, or None."""
    if delay < 0.0:
        samples = f"{-delay:g} sample{'s' if delay != -1.0 else ''}"
        return (f"output {name} is {samples} ahead of the force's channel, which a model driven sample by sample "
                "cannot be (it would read the force ahead)")
    if delay != math.floor(delay) and delay < MIN_FRACTIONAL:
        return (f"output {name} is {delay:g} samples late: a fraction of a sample is realised causally from "
                f"{MIN_FRACTIONAL} whole samples on (the band-limited kernel reads {MIN_FRACTIONAL} samples after "
                "the one it delays); give whole samples")
    return None


def line_problems(config: BeamConfig) -> list[str]:
    """Why ``config``'s channel delays have no causal delay line, one sentence per sensor (empty when they have
    one, or there are none): what :func:`delay_line` refuses, read from the config alone."""
    delays = effective_delays(config)
    return [p for p in (_refusal(s.name, d) for s, d in zip(config.sensors, delays)) if p] if delays else []


def delay_line(system: DiscreteStateSpace) -> DiscreteStateSpace:
    """``system`` with its ``output_delays`` realised as delay-line states (module docstring); ``system`` itself
    when it has none.

    Raises
    ------
    ConfigError
        An output's delay is negative, or a fraction of a sample shorter than :data:`MIN_FRACTIONAL` — one line
        naming the output.
    """
    delays: Sequence[float] = system.output_delays
    if not delays:
        return system
    problems = [p for p in (_refusal(n, d) for n, d in zip(system.output_names, delays)) if p]
    if problems:
        raise ConfigError("; ".join(problems))
    A, B, C, D = system.A, system.B, system.C, system.D
    n, m = B.shape
    hold = np.zeros((n, m)) if system.hold is None else system.hold
    rest = C @ hold - D                          # −ỹ[0] per unit u[0]: the line's states at rest (module docstring)
    taps = [delay_taps(d) if d else (np.array([0]), np.array([1.0])) for d in delays]
    lengths = [int(lags.max()) for lags, _ in taps]
    total = sum(lengths)
    Af = np.zeros((n + total, n + total))
    Af[:n, :n] = A
    Bf = np.vstack([B, np.zeros((total, m))])
    Cf = np.zeros((C.shape[0], n + total))
    Df = np.zeros_like(D)
    hf = np.vstack([hold, np.zeros((total, m))])
    names = list(system.state_names)
    start = n
    for i, ((lags, w), length) in enumerate(zip(taps, lengths)):
        if length:                                # states ỹ_i[k−1] … ỹ_i[k−length]
            Af[start, :n] = C[i]                  # ỹ_i[k] enters the line
            Bf[start] = D[i]
            for j in range(1, length):
                Af[start + j, start + j - 1] = 1.0
            hf[start:start + length] = rest[i]
            names += [f"delay({system.output_names[i]})[k-{j}]" for j in range(1, length + 1)]
        for lag, wj in zip(lags, w):
            if lag == 0:                          # the current sample: through C and D
                Cf[i, :n] += wj * C[i]
                Df[i] += wj * D[i]
            else:
                Cf[i, start + lag - 1] += wj
        start += length
    return DiscreteStateSpace(Af, Bf, Cf, Df, system.dt, system.input_names, system.output_names, tuple(names),
                              hf, system.advance)


def realised_line(system: DiscreteStateSpace) -> tuple[DiscreteStateSpace, str]:
    """``system`` with its ``output_delays`` as a delay line (:func:`delay_line`) and ``""`` where that line is
    causal, else ``system`` without them and the sentence that says they are left out and why (the delays a
    system carries of its own, not from a config: a diagnosed delay between the channels)."""
    problems = [p for p in (_refusal(n, d) for n, d in zip(system.output_names, system.output_delays)) if p]
    if not problems:
        return delay_line(system), ""
    return replace(system, output_delays=()), ("the exported models leave the channels' delay out (a model driven "
                                               "sample by sample cannot carry it): " + "; ".join(problems))


def exported_config(config: BeamConfig) -> tuple[BeamConfig, str]:
    """The config an export builds its models from, and what it says: ``config`` itself and ``""`` when its
    channel delays have a causal delay line (the exported StateSpace and FMUs carry them), else ``config``
    without them and the sentence that says they are left out and why."""
    problems = line_problems(config)
    if not problems:
        return config, ""
    return without_delays(config), ("the exported models leave the channels' converter delays out (a model driven "
                                    "sample by sample cannot carry them): " + "; ".join(problems))
