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
The records also read the delay themselves, from their phase against the baseline's prediction
(:func:`read_delay`): that reading is refitted whatever the delay's score (:attr:`Effect.read`), held near it
first — the baseline that left the delay out can sit in another basin, where no trial at its unknowns shows it.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import signal

from ebb_model.acquisition.channel_delay import delay_outputs
from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig
from ebb_model.statespace import DiscreteStateSpace

from .base import AugmentedModel, Effect, Family, Scales, Signal

__all__ = ["FAMILY", "MEANINGFUL_SAMPLES", "READ_CONCENTRATION", "READ_ERROR", "SEARCHED_SAMPLES", "ChannelDelay",
           "read_delay"]

#: The largest delay searched either way, in samples: a converter's decimation filter delays by up to a few tens
#: of output samples, and the difference between two cards' filters is smaller still.
SEARCHED_SAMPLES = 32

#: The least concentration of the records' phase about one delay (:func:`read_delay`: 1 when every coherent bin
#: of every sensor turns by the same delay) for the delay read to start a refit.  Measured on the hint family's
#: first 64 records, read against the newcomer's own model (configs 30–60 % off): 0.82–0.97 on the 14 of its 16
#: undeclared-delay records that were read, 0.63–0.99 on the others.
READ_CONCENTRATION = 0.7
#: The error of a delay read [samples]: measured at most 0.5 on the records above (9.5 read for 10).
READ_ERROR = 0.5
#: The least delay read (either way) [samples] that starts a refit of its own: of the family's 32 correct and
#: withheld-effect records, 26 read within 0.3 samples of none, which the refit from the best whole-sample trial
#: reaches anyway, three 0.6–0.9 (a refit more, nothing else), three unread; an undeclared low-pass reads as its
#: group delay (0–1.35 samples).
MEANINGFUL_SAMPLES = 0.5
#: The segment of the records' spectra [samples]: a record is read when it is four segments long or more.
_SEGMENT = 256
#: The least number of coherent bins read: a concentration over fewer says nothing (measured: a displacement
#: sensor behind an undeclared low-pass, two coherent bins, concentration 1.0 at 4.65 samples for none).
_LEAST_BINS = 8


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


def read_delay(pairs: Sequence[tuple[np.ndarray, np.ndarray]], searched: int = SEARCHED_SAMPLES,
               step: float = 0.05) -> tuple[float, float] | None:
    """The delay of the records' sensors after a model's prediction of them, read from the phase of their cross
    spectrum, and how concentrated the phase is about it.

    Away from its resonances a lightly damped beam's FRF is real — the model's and the records' alike, whatever
    the model's parameters, the sign of the force or the kind of sensor (the model reads the same kind) — so the
    phase of the records' cross spectrum with the prediction is ``−ω τ`` modulo π: its double, ``−2 ω τ`` modulo
    2π, is summed as unit phasors over the coherent bins (coherence above 1/2) of every sensor after turning them
    back by ``2 ω τ`` on a grid of ``step`` samples, and the delay where the sum is longest is taken (the sum over
    its count: the concentration, 1 for a pure delay).  Near a resonance the phase is anything, but those bins are
    few on a lightly damped beam; an undeclared anti-alias filter reads as its group delay.

    Parameters
    ----------
    pairs
        Per record, the measured outputs and the prediction, both ``(n, n_sensors)``.
    searched
        The largest delay read either way [samples].
    step
        The grid of delays [samples].

    Returns
    -------
    tuple of float or None
        ``(delay, concentration)``; ``None`` when no record is four segments long or fewer than
        :data:`_LEAST_BINS` bins are coherent.
    """
    phases, omegas = [], []
    for y, y_hat in pairs:
        if y.shape[0] < 4 * _SEGMENT:
            continue
        for j in range(y.shape[1]):
            f, s_hy = signal.csd(y_hat[:, j], y[:, j], nperseg=_SEGMENT)
            _, s_yy = signal.welch(y[:, j], nperseg=_SEGMENT)
            _, s_hh = signal.welch(y_hat[:, j], nperseg=_SEGMENT)
            with np.errstate(invalid="ignore", divide="ignore"):
                coherent = np.abs(s_hy) ** 2 > 0.5 * s_yy * s_hh
            coherent &= np.isfinite(s_hy) & (f > 0)
            phases.append(np.angle(s_hy[coherent] ** 2))
            omegas.append(2 * np.pi * f[coherent])       # f in cycles per sample
    phase, omega = np.concatenate(phases or [np.zeros(0)]), np.concatenate(omegas or [np.zeros(0)])
    if phase.size < _LEAST_BINS:
        return None
    taus = np.arange(-searched, searched + step / 2, step)
    lengths = np.abs(np.exp(1j * (phase[None, :] + 2.0 * omega[None, :] * taus[:, None])).sum(axis=1))
    k = int(np.argmax(lengths))
    return float(taus[k]), float(lengths[k] / phase.size)


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
    read = scales.read_delay
    boxes = (((max(read[0] - READ_ERROR, -SEARCHED_SAMPLES),), (min(read[0] + READ_ERROR, SEARCHED_SAMPLES),)),) \
        if read is not None and read[1] >= READ_CONCENTRATION and abs(read[0]) >= MEANINGFUL_SAMPLES else ()
    return (Effect("channel_delay", None, ("samples",), (-float(SEARCHED_SAMPLES),), (float(SEARCHED_SAMPLES),),
                   (0.0,), "a delay of the sensors' channels after the force's (another converter card)",
                   {"delay": "s"}, apply, lambda s: {"delay": float(s[0]) * dt}, trials=whole, read=boxes),)


#: This module's entry in the catalogue.
FAMILY = Family(("channel_delay",), candidates)
