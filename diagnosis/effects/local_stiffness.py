"""A local loss of bending stiffness (structural: a config change).

``stiffness_loss`` (``compliance``, ``x``, ``length``, ``factor``)
    A crack, a loose joint, a damaged clamp block: a segment where the beam bends more easily.  What the low
    modes see first is its added flexibility ``(1/f − 1) ℓ / EI`` (``f`` the remaining fraction of EI over the
    length ``ℓ``) — the compliance of a hinge of rotational stiffness ``kr = EI / ((1/f − 1) ℓ)`` at ``x`` —;
    its length shows only where the wavelengths come near it.  The search variables are therefore that
    compliance relative to the beam's, ``c = (1/f − 1) ℓ/L = EI/(kr L)`` (0: no loss; reported as
    ``compliance``, independent of the EI the refit settles on), the centre ``x`` and the length ``ℓ/L`` (start
    :data:`SEGMENT`); the factor follows, ``f = 1/(1 + c L/ℓ)``.  The compliance is what records determine
    best (a 0.04 L segment at 0.3: compliance within 0.4 %, length 17 % and factor 11 % off, on
    accelerometers); its length the records bound but do not fix (a pinned–pinned beam, one velocity sensor, a 4 %
    segment of 0.031 m: with the length held and the rest refitted on 323 nodes, χ² 1396–1413 anywhere from 0.005
    to 0.04 m and 1459 at 0.05 m, the compliance 4 % below to 2.5 % above the truth's along it — the modes in the
    band have wavelengths ten times the segment and more; a linearisation at the refit gives the length 1 % and
    does not describe that χ²), so the length and factor reported are one point of that range.  Its modal
    signature: every mode loses stiffness in proportion to its curvature squared at
    ``x`` — nothing at a mode's inflection point, most at its antinodes of curvature.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ebb_model.beam import WeakSegment
from ebb_model.config import BeamConfig

from .base import AugmentedModel, Effect, Family, Scales

__all__ = ["FAMILY", "SEGMENT", "LOOSEST"]

#: The segment's starting length as a fraction of the beam's length (its bounds: a quarter of it … five times).
SEGMENT = 0.02
#: Upper bound of the compliance ``c = EI/(kr L)``: a hinge as soft as the whole beam's bending.
LOOSEST = 1.0


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """One weak segment: compliance ``c = EI/(kr L)`` in [0, :data:`LOOSEST`], centre anywhere inside, length
    ``0.005 … 0.1 L``."""
    L = scales.length

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        length = float(s[2]) * L
        centre = float(np.clip(s[1], 0.5 * length, L - 0.5 * length))      # the segment stays inside
        w = WeakSegment("_diagnosis_weak", centre, length, 1.0 / (1.0 + float(s[0]) / float(s[2])))
        return AugmentedModel(replace(cfg, weak_segments=tuple(cfg.weak_segments) + (w,)), params)

    def physical(s: np.ndarray) -> dict[str, float]:
        return {"compliance": float(s[0]), "x": float(s[1]), "length": float(s[2] * L),
                "factor": float(1.0 / (1.0 + s[0] / s[2]))}

    return (Effect("stiffness_loss", None, ("compliance", "x", "length_ratio"), (0.0, 0.05 * L, SEGMENT / 4),
                   (LOOSEST, 0.95 * L, 5 * SEGMENT), (0.0, 0.5 * L, SEGMENT),
                   "local loss of bending stiffness (crack, loose joint, damaged clamp)",
                   {"compliance": "1", "x": "m", "length": "m", "factor": "1"}, apply, physical),)


#: This module's entry in the catalogue.
FAMILY = Family(("stiffness_loss",), candidates)
