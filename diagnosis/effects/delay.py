r"""A delay between the force's channel and the sensors' that the config does not declare (signal-level).

``channel_delay`` (``delay``)
    Every sensor reads the beam ``delay`` seconds late against the measured force — the group delay of a
    sigma-delta converter's decimation filter when the sensors sit on another card than the force (or on one
    with a longer filter); negative: the force's channel is the late one.

A record made on such cards and read with a config that declares no delay leaves a residual that no beam explains:
every mode's response turned by ``ω τ``, more the higher the mode — the records' start read it as a reversed force
or a wrong level (:mod:`identification.data_start`), and the diagnosis, without this candidate, as a first-order lag
(which also turns the phase, but rolls off the level) or nothing at all.  Once named, the fix is the config's own
``delay`` of each sensor channel (:mod:`ebb_model.acquisition.channel_delay`), which the corrected model carries.

The delay is one for every sensor (one card's; each card's own delay, sensor by sensor, is not a candidate: it
would add a candidate per sensor for a set-up the records rarely have).  The sensors' outputs are shifted by
:func:`~ebb_model.acquisition.channel_delay.delay_outputs` — whole samples exactly, a fraction by the band-limited
kernel (exact on a band-limited record, a smooth interpolation otherwise, so the refit moves continuously between
whole samples) — and a StateSpace carries it as its ``output_delays`` (delay-line states in an export,
:mod:`ebb_model.acquisition.delay_line`).  Its χ² is periodic in the delay along each dominant mode's period, so
the refit starts from the best whole number of samples in the range (:attr:`Effect.trials`), not from a step.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ebb_model.acquisition.channel_delay import delay_outputs
from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.statespace import DiscreteStateSpace

from .base import AugmentedModel, Effect, Family, Scales, Signal

__all__ = ["FAMILY", "SEARCHED_SAMPLES", "ChannelDelay"]

#: The largest delay searched either way, in samples: a converter's decimation filter delays by up to a few tens
#: of output samples, and the difference between two cards' filters is smaller still.
SEARCHED_SAMPLES = 32


@dataclass(frozen=True)
class ChannelDelay(Signal):
    """Every sensor's reading ``samples`` sample periods after the force's (fractions by the band-limited kernel)."""

    samples: float
    description = "a delay of the sensors' channels after the force's"

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", finite_scalar("channel_delay.delay", self.samples))

    def outputs(self, y: np.ndarray, dt: float, names: tuple[str, ...]) -> np.ndarray:
        return delay_outputs(y, [self.samples] * y.shape[1])

    def in_series(self, sys: DiscreteStateSpace) -> DiscreteStateSpace:
        before = sys.output_delays or (0.0,) * sys.noutputs
        return replace(sys, output_delays=tuple(d + self.samples for d in before))


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """One delay of every sensor against the force, ``±`` :data:`SEARCHED_SAMPLES` sample periods; none without
    a sensor or a force."""
    if not config.sensors or not config.actuators:
        return ()
    dt = config.time.dt

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        d = float(s[0])
        return AugmentedModel(cfg, params, () if d == 0.0 else (ChannelDelay(d),))

    whole = tuple(np.array([float(k)]) for k in range(-SEARCHED_SAMPLES, SEARCHED_SAMPLES + 1) if k)
    return (Effect("channel_delay", None, ("samples",), (-float(SEARCHED_SAMPLES),), (float(SEARCHED_SAMPLES),),
                   (0.0,), "a delay of the sensors' channels after the force's (another converter card)",
                   {"delay": "s"}, apply, lambda s: {"delay": float(s[0]) * dt}, trials=whole),)


#: This module's entry in the catalogue.
FAMILY = Family(("channel_delay",), candidates)
