"""The shaker at the drive point (structural: config changes).

``shaker_armature[<actuator>]`` (``mass``, ``k``)
    The moving parts of an electrodynamic shaker — armature, table, stinger, the load cell's top — rigidly
    attached at the actuator's position and held by the shaker's suspension: a mass and a spring to ground at
    the drive point at once.  The beam feels them whenever the force the record gives is not the one at the
    beam (the shaker's current or command, a load cell on the shaker's side of the stinger).  The dynamic
    stiffness it adds at the drive point is ``k − ω² m``: below the armature's own resonance ``√(k/m)`` the
    modes rise as under a spring, above it they fall as under a mass — a pattern neither a point mass nor a
    spring alone makes.  The stinger is taken as rigid in the band (its axial resonance above it); a compliant
    stinger would add a degree of freedom the catalogue does not have.

Like a transducer's mass it is a special case — of the pair ``point_mass+grounded_spring`` at one position —
and does not compete for the score shortlist: it is refitted where a point mass's or a spring's refit lands
within :data:`~diagnosis.effects.point_mass.AT_SENSOR` of an actuator, or from its modal match
(:mod:`diagnosis.search.nested`), and it stays a candidate only when it pays for each of its parts
(:func:`parts`: the mass alone and the suspension alone at the drive point).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ebb_model.beam import PointMass, PointSpring
from ebb_model.config import BeamConfig

from .base import PAIR_SEPARATOR, AugmentedModel, Effect, Family, Landing, Scales
from .point_mass import AT_SENSOR, PLAUSIBLE_MASS_RATIO
from .supports import STIFFEST

__all__ = ["ARMATURE", "FAMILY", "parts"]

#: The family's name.
ARMATURE = "shaker_armature"


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """One armature per actuator: ``μ = mass/(ρA L)`` in [0, 1] and ``κ = k L³/EI`` in [0, :data:`STIFFEST`]
    at the actuator's position in the config it is applied to; plausible up to
    :data:`~diagnosis.effects.point_mass.PLAUSIBLE_MASS_RATIO` of the beam's nominal mass."""
    L = scales.length
    mass_unit, spring_unit = scales.rhoA * L, scales.EI / L ** 3
    plausible = {"mass": (0.0, PLAUSIBLE_MASS_RATIO * config.parameters["rhoA"].value * L)}
    return tuple(_armature(actuator.name, mass_unit, spring_unit, plausible) for actuator in config.actuators)


def _armature(actuator: str, mass_unit: float, spring_unit: float, plausible: dict[str, tuple[float, float]]
              ) -> Effect:
    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0 and s[1] == 0.0:
            return AugmentedModel(cfg, params)
        x = float(next(a.x for a in cfg.actuators if a.name == actuator))
        masses, springs = tuple(cfg.masses), tuple(cfg.springs)
        if s[0] != 0.0:
            masses += (PointMass(f"_diagnosis_armature_{actuator}", x, float(s[0] * mass_unit)),)
        if s[1] != 0.0:
            springs += (PointSpring(f"_diagnosis_suspension_{actuator}", x, float(s[1] * spring_unit)),)
        return AugmentedModel(replace(cfg, masses=masses, springs=springs), params)

    return Effect(ARMATURE, actuator, ("mass_ratio", "stiffness_scaled"), (0.0, 0.0), (1.0, STIFFEST), (0.0, 0.0),
                  f"the shaker's moving mass and suspension at actuator {actuator} (rigid stinger)",
                  {"mass": "kg", "k": "N/m"}, apply,
                  lambda s: {"mass": float(s[0] * mass_unit), "k": float(s[1] * spring_unit)}, plausible,
                  nested_in=f"point_mass{PAIR_SEPARATOR}grounded_spring", scaled=(0, 1),
                  place=lambda cfg: float(next(a.x for a in cfg.actuators if a.name == actuator)),
                  landings=(Landing("point_mass", 1, ((0, 0),), AT_SENSOR),
                            Landing("grounded_spring", 1, ((1, 0),), AT_SENSOR)), parts=parts, rig_part="shaker")


def parts(armature: Effect) -> tuple[Effect, Effect]:
    """The armature's mass alone and its suspension alone (each a one-variable effect, the other part off): what
    the armature must beat, each by the BIC margin, to be more than a point mass or a spring at the drive
    point."""

    def part(i: int, name: str) -> Effect:
        def full(s: np.ndarray) -> np.ndarray:
            z = np.zeros(2)
            z[i] = s[0]
            return z

        def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
            return armature.apply(cfg, params, full(s))

        def physical(s: np.ndarray) -> dict[str, float]:
            key = ("mass", "k")[i]
            return {key: armature.physical(full(s))[key]}

        return replace(armature, name=name, variables=(armature.variables[i],), lower=(armature.lower[i],),
                       upper=(armature.upper[i],), off=(armature.off[i],), _apply=apply, _physical=physical,
                       nested_in=armature.label, scaled=(0,), place=None, landings=(), parts=None)

    return part(0, f"{ARMATURE}_mass"), part(1, f"{ARMATURE}_suspension")


#: This module's entry in the catalogue.
FAMILY = Family((ARMATURE,), candidates)
