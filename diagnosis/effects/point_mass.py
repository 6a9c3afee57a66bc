"""Attached masses (structural: config changes).

``point_mass`` (``mass``, ``x``)
    A mass anywhere inside the beam (a shaker's armature through its stinger, a clamp block, a load cell).
``transducer_mass[<sensor>]`` (``mass``)
    A transducer's own mass at its sensor's position (the fitted one when positions are unknowns): the one-variable
    special case of ``point_mass``, as common as it is easily missed.  Being nested in ``point_mass``, it does
    not compete for the score shortlist (a score at the sensor's position would push a physical effect off it);
    it is refitted from the point mass's refit when that lands within :data:`AT_SENSOR` of a sensor
    (:mod:`diagnosis.search.rank`).  Tied with the point mass, it is named when its refit brings the held-out
    records to the noise floor on its own (:func:`diagnosis.judgement.rules.nested`): the free position's further
    gain on the fit window is then below what the held-out records can see — at high signal-to-noise ratios it is
    the model's own representation of a mass between grid nodes that the position absorbs (an 80 g mass on
    accelerometers: 0.05 mm, ΔBIC 70, held-out 1.02 against 1.06).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ebb_model.beam import PointMass
from ebb_model.config import BeamConfig

from .base import AugmentedModel, Effect, Family, Landing, Scales

__all__ = ["AT_SENSOR", "FAMILY", "PLAUSIBLE_MASS_RATIO", "TRANSDUCER"]

#: Heaviest plausible attached mass as a fraction of the beam's nominal mass: transducers, a load cell, a
#: shaker's moving parts through its stinger, a clamp block weigh a few per cent to a quarter of a lab beam; a
#: "mass" beyond that is another effect in disguise (or a wrong density).
PLAUSIBLE_MASS_RATIO = 0.25
#: Distance from a sensor, as a fraction of the beam's length, within which a refitted point mass is tried as
#: that sensor's transducer mass.
AT_SENSOR = 0.05
#: The transducer masses' family name.
TRANSDUCER = "transducer_mass"


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

    plausible = {"mass": (0.0, PLAUSIBLE_MASS_RATIO * nominal_mass)}
    return (Effect("point_mass", None, ("mass_ratio", "x"), (0.0, 0.02 * L), (1.0, 0.98 * L), (0.0, 0.5 * L),
                   "attached point mass (sensor, shaker, load cell, clamp block)", {"mass": "kg", "x": "m"}, apply,
                   lambda s: {"mass": float(s[0] * unit), "x": float(s[1])}, plausible, scaled=(0,)),) + tuple(
        _transducer(sensor.name, unit, plausible) for sensor in config.sensors)


def _transducer(sensor: str, unit: float, plausible: dict[str, tuple[float, float]]) -> Effect:
    """``transducer_mass[sensor]``: ``μ = mass/(ρA L)`` in [0, 1] at the sensor's position in the config it is
    applied to (the baseline's fitted position when positions are unknowns)."""

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        x = next(sn.x for sn in cfg.sensors if sn.name == sensor)
        m = PointMass(f"_diagnosis_transducer_{sensor}", float(x), float(s[0] * unit))
        return AugmentedModel(replace(cfg, masses=tuple(cfg.masses) + (m,)), params)

    return Effect(TRANSDUCER, sensor, ("mass_ratio",), (0.0,), (1.0,), (0.0,),
                  f"the mass of the transducer of sensor {sensor} at its position", {"mass": "kg"}, apply,
                  lambda s: {"mass": float(s[0] * unit)}, plausible, nested_in="point_mass", scaled=(0,),
                  place=lambda cfg: float(next(sn.x for sn in cfg.sensors if sn.name == sensor)),
                  landings=(Landing("point_mass", 1, ((0, 0),), AT_SENSOR),), rig_part="transducer")


#: This module's entry in the catalogue.
FAMILY = Family(("point_mass", TRANSDUCER), candidates)
