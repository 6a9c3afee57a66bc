"""The library of candidate unmodelled effects (what the diagnosis can name).

Each :class:`Effect` is an extension of the identified beam model with its own
search variables, bounds and an "off" value at which the model reduces to the
baseline exactly.  Applying an effect to a baseline (config, parameters) gives
an :class:`AugmentedModel`: a config (structural effects are plain config
changes — end springs, a point mass, Kelvin–Voigt damping, rotary inertia, a
Winkler foundation — so the native fast path and the FMU both simulate them)
plus signal-level parts (:class:`Signal`: actuator/sensor lag, axial-load
drift, geometric stiffening) that say themselves what they do to the inputs,
the outputs, the axial force and a StateSpace.

Search variables are dimensionless where that makes bounds independent of the
beam at hand (:class:`Scales` carries the beam's own scales); every effect
reports its physical parameters (:meth:`Effect.physical`) in the units of the
catalogue:

=============================  ===================  ==========================================
effect                         physical parameters  search variable (off value)
=============================  ===================  ==========================================
boundary_rotational_<side>     kr [N m/rad]         constrained end: c = EI/(kr L) (0);
                                                    free rotation: s = kr L/EI (0)
boundary_translational_<side>  kt [N/m]             constrained: c = EI/(kt L³) (0);
                                                    free: s = kt L³/EI (0)
point_mass                     mass [kg], x [m]     μ = mass/(ρA L) (0), x
transducer_mass[<sensor>]      mass [kg]            μ = mass/(ρA L) (0) at the sensor's position
grounded_spring                k [N/m], x [m]       κ = k L³/EI (0), x
shaker_armature[<actuator>]    mass [kg], k [N/m]   μ (0), κ (0) at the actuator's position
stiffness_loss                 compliance [1],      c = (1/f − 1) ℓ/L (0), x, ℓ/L: EI f over ℓ,
                               x [m], length [m],   f = 1/(1 + c L/ℓ)
                               factor f [1]
kelvin_voigt                   eta [s]              eta (0)
rotary_inertia                 rhoI [kg m]          r² = rhoI/(ρA L²) (0)
foundation                     kf [N/m²]            κ = kf L⁴/EI (0)
actuator_lag                   tau [s]              tau (0)
sensor_lag[<sensor>]           tau [s]              tau (0)
channel_delay                  delay [s]            delay in sample periods (0, two-sided)
actuator_gain                  gain [1]             gain (1)
sensor_gain[<sensor>]          gain [1]             gain (1)
axial_drift                    rate [N/s]           rate (0, two-sided)
geometric_stiffening           EA [N]               EA (0); only with both ends axially fixed
=============================  ===================  ==========================================

Adding an effect
----------------
One module in this package ending in its :class:`Family` (the family names and
``candidates(config, scales, identified) -> tuple[Effect, ...]``), and its line
in :data:`FAMILIES`.  A structural effect changes the config or parameters in
its ``apply``; a signal-level effect returns a :class:`Signal` subclass of its
own (see :mod:`.lag` and :mod:`.axial`).  Nothing else in the diagnosis names
an effect.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from ebb_model.config import BeamConfig

from . import axial, beam_terms, boundary, chain, delay, lag, local_stiffness, point_mass, shaker, supports
from .base import (
    PAIR_SEPARATOR,
    AugmentedModel,
    AxialLoad,
    Effect,
    Family,
    Landing,
    Scales,
    Signal,
    mirror_image,
    on_top_of,
    pair_effect,
    signal_effect,
    variables_for,
)

__all__ = ["Scales", "Effect", "AugmentedModel", "AxialLoad", "Signal", "Family", "Landing", "Catalogue",
           "candidate_effects", "pair_effect", "on_top_of", "mirror_image", "variables_for",
           "signal_effect", "FAMILIES", "EFFECT_NAMES",
           "PAIR_SEPARATOR"]

#: The catalogue, in report order: one entry per family module.
FAMILIES: tuple[Family, ...] = (
    boundary.FAMILY,
    point_mass.FAMILY,
    supports.FAMILY,
    shaker.FAMILY,
    local_stiffness.FAMILY,
    beam_terms.FAMILY,
    lag.FAMILY,
    delay.FAMILY,
    chain.FAMILY,
    axial.FAMILY,
)

#: Names of the effect families of the catalogue.
EFFECT_NAMES: tuple[str, ...] = tuple(name for family in FAMILIES for name in family.names)


@dataclass(frozen=True)
class Catalogue:
    """The candidate effects of one baseline, built once and looked up by label (the one index of effects).

    Picklable, unlike the effects themselves (their maps are closures): worker processes receive the
    catalogue's inputs and rebuild the same effects from them.

    Attributes
    ----------
    config, scales, identified
        What :func:`candidate_effects` builds the candidates from.
    families
        The catalogue's families (default: :data:`FAMILIES` as registered when the catalogue is made).
    absent
        Rig parts the records' set-up did not have (:mod:`diagnosis.setups`): the effects modelling them are no
        candidates.
    """

    config: BeamConfig
    scales: Scales
    identified: tuple[str, ...] = ()
    families: tuple[Family, ...] = field(default_factory=lambda: FAMILIES)
    absent: frozenset[str] = frozenset()

    @cached_property
    def _index(self) -> dict[str, Effect]:
        return {e.label: e for family in self.families
                for e in family.candidates(self.config, self.scales, tuple(self.identified))
                if e.rig_part is None or e.rig_part not in self.absent}

    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k != "_index"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    def effects(self) -> tuple[Effect, ...]:
        """The single candidates, in catalogue order."""
        return tuple(e for lab, e in self._index.items() if PAIR_SEPARATOR not in lab)

    def pair(self, first: str, second: str) -> Effect:
        """The pair of the candidates ``first`` and ``second`` (``second`` acting on the model ``first``
        makes), made once."""
        label = f"{first}{PAIR_SEPARATOR}{second}"
        if label not in self._index:
            self._index[label] = pair_effect(self.effect(first), self.effect(second))
        return self._index[label]

    def effect(self, label: str) -> Effect:
        """The candidate or pair called ``label`` (a pair's label: two labels joined by :data:`PAIR_SEPARATOR`).

        Raises
        ------
        KeyError
            No such candidate on this set-up.
        """
        if label not in self._index and PAIR_SEPARATOR in label:
            return self.pair(*label.split(PAIR_SEPARATOR))
        return self._index[label]


def candidate_effects(config: BeamConfig, scales: Scales, *, identified: tuple[str, ...] = ()
                      ) -> tuple[Effect, ...]:
    """The catalogue's effects that can be tested on this set-up.

    Parameters
    ----------
    config
        Baseline set-up (ends, sensors, masses).
    scales
        Beam and record scales (:class:`Scales`) fixing the search bounds.
    identified
        Names of the baseline unknowns: an effect whose parameter is already
        identified (e.g. ``eta``) is not a candidate.

    Returns
    -------
    tuple of Effect
    """
    return Catalogue(config, scales, tuple(identified)).effects()
