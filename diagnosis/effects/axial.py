r"""Laws of an axial force the baseline does not have (signal-level: the beam is no longer time-invariant).

``axial_drift`` (``rate``)
    :math:`N(t) = N + \text{rate}\cdot t`, ``t`` from the record start (e.g. thermal).
``geometric_stiffening`` (``EA``)
    :math:`N(t) = N + \frac{EA}{2L}\int_0^L w_x^2\,dx` (mid-plane stretching; a candidate only when both ends are
    axially restrained).

Both are terms of :class:`~diagnosis.effects.base.AxialLoad`, integrated by
:func:`diagnosis.problem.augmented.simulate_axial`; neither has a StateSpace.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ebb_model.checks import finite_scalar
from ebb_model.config import BeamConfig

from .base import AxialLoad, Effect, Family, Scales, Signal, signal_effect

__all__ = ["FAMILY", "AxialDrift", "Stretching"]


@dataclass(frozen=True)
class AxialDrift(Signal):
    """The axial force drifts at ``rate`` [N/s] over the record."""

    rate: float
    description = "axial drift"

    def __post_init__(self) -> None:
        object.__setattr__(self, "rate", finite_scalar("axial_drift.rate", self.rate))

    def axial(self) -> AxialLoad:
        return AxialLoad(rate=self.rate)


@dataclass(frozen=True)
class Stretching(Signal):
    """Mid-plane stretching of axial stiffness ``EA`` [N] (>= 0)."""

    EA: float
    description = "geometric stiffening"

    def __post_init__(self) -> None:
        object.__setattr__(self, "EA", finite_scalar("geometric_stiffening.EA", self.EA, minimum=0.0))

    def axial(self) -> AxialLoad:
        return AxialLoad(EA=self.EA)


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """Drift up to one Euler load over the record either way; stretching up to ten Euler loads at the record's
    largest response, with both ends axially fixed only."""
    sc = scales
    euler = sc.EI * math.pi ** 2 / sc.length ** 2
    r = euler / max(sc.duration, 1e-12)
    out = [signal_effect("axial_drift", None, "rate", (-r, r), 0.0,
                         "slow drift of the axial load over the record (e.g. thermal)", AxialDrift, "rate", "N/s")]
    if config.beam.left.translation_fixed and config.beam.right.translation_fixed:
        hi = 10.0 * euler * 2.0 * sc.length / sc.stretch_max if sc.stretch_max > 0 else 1e12 * sc.EI
        out.append(signal_effect("geometric_stiffening", None, "EA", (0.0, hi), 0.0,
                                 "mid-plane stretching: amplitude-dependent axial force EA/(2L)∫w_x²dx",
                                 Stretching, "EA", "N"))
    return tuple(out)


#: This module's entry in the catalogue.
FAMILY = Family(("axial_drift", "geometric_stiffening"), candidates)
