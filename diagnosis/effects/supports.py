"""Supports inside the span (structural: config changes).

``grounded_spring`` (``k``, ``x``)
    A translational spring from the beam at ``x`` to ground: an intermediate support, a guide, a shaker's
    suspension seen through a stiff stinger, a cable or hose pulling the beam back.  Its modal signature is the
    point mass's turned over: ``δ(ω_i²) = k φ_i(x)²`` (mass-normalised modes) raises every mode by its shape
    squared at the spring — most the low modes, whose ``ω_i²`` it is a larger share of —, where a mass lowers
    ``ω_i²`` by ``ω_i² m φ_i(x)²``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ebb_model.beam import PointSpring
from ebb_model.config import BeamConfig

from .base import AugmentedModel, Effect, Family, Scales

__all__ = ["FAMILY", "STIFFEST"]

#: Upper bound of the dimensionless stiffness ``κ = k L³/EI``: a mid-span spring of κ = 48 doubles a
#: pinned–pinned beam's static stiffness there; at 2000 the support is rigid for the modes of a lab record.
STIFFEST = 2000.0


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """One spring to ground, ``κ = k L³/EI`` in [0, :data:`STIFFEST`] (EI the baseline's), anywhere inside the
    beam."""
    L = scales.length
    unit = scales.EI / L ** 3

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        k = PointSpring("_diagnosis_spring", float(s[1]), float(s[0] * unit))
        return AugmentedModel(replace(cfg, springs=tuple(cfg.springs) + (k,)), params)

    return (Effect("grounded_spring", None, ("stiffness_scaled", "x"), (0.0, 0.02 * L), (STIFFEST, 0.98 * L),
                   (0.0, 0.5 * L), "spring to ground inside the span (intermediate support, suspension, stinger)",
                   {"k": "N/m", "x": "m"}, apply, lambda s: {"k": float(s[0] * unit), "x": float(s[1])},
                   scaled=(0,)),)


#: This module's entry in the catalogue.
FAMILY = Family(("grounded_spring",), candidates)
