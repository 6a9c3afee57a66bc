"""An attached point mass (``point_mass``: mass and position; structural: a config change)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ebb_model.beam import PointMass
from ebb_model.config import BeamConfig

from .base import AugmentedModel, Effect, Family, Scales

__all__ = ["FAMILY", "PLAUSIBLE_MASS_RATIO"]

#: Heaviest plausible attached mass as a fraction of the beam's nominal mass: transducers, a load cell, a
#: shaker's moving parts through its stinger, a clamp block weigh a few per cent to a quarter of a lab beam; a
#: "mass" beyond that is another effect in disguise (or a wrong density).
PLAUSIBLE_MASS_RATIO = 0.25


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """One point mass, ``μ = mass/(ρA L)`` in [0, 1] anywhere inside the beam; plausible up to
    :data:`PLAUSIBLE_MASS_RATIO` of the beam's nominal mass (the config's ρA, not the fitted one: a fit that
    compensates the mass by the beam's density must not widen its own yardstick)."""
    L = scales.length
    unit = scales.rhoA * L
    nominal_mass = config.parameters["rhoA"].value * L

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        m = PointMass("_diagnosis_mass", float(s[1]), float(s[0] * unit))
        return AugmentedModel(replace(cfg, masses=tuple(cfg.masses) + (m,)), params)

    return (Effect("point_mass", None, ("mass_ratio", "x"), (0.0, 0.02 * L), (1.0, 0.98 * L), (0.0, 0.5 * L),
                   "attached point mass (sensor, shaker, load cell, clamp block)", {"mass": "kg", "x": "m"}, apply,
                   lambda s: {"mass": float(s[0] * unit), "x": float(s[1])},
                   {"mass": (0.0, PLAUSIBLE_MASS_RATIO * nominal_mass)}),)


#: This module's entry in the catalogue.
FAMILY = Family(("point_mass",), candidates)
