"""Terms of the beam's equation the baseline may lack: Kelvin–Voigt damping, rotary inertia, a Winkler
foundation (structural: each is a parameter of the model core, added on top of the baseline's value)."""
from __future__ import annotations

import numpy as np

from ebb_model.config import BeamConfig

from .base import AugmentedModel, Effect, Family, Scales

__all__ = ["FAMILY"]


def _parameter_effect(name: str, param: str, param_unit: str, unit: float, hi: float, var: str,
                      description: str) -> Effect:
    """An effect adding ``s·unit`` to the model parameter ``param`` (in ``param_unit``)."""
    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        p = dict(params)
        p[param] = p.get(param, 0.0) + float(s[0]) * unit
        return AugmentedModel(cfg, p)

    return Effect(name, None, (var,), (0.0,), (hi,), (0.0,), description, {param: param_unit}, apply,
                  lambda s: {param: float(s[0] * unit)})


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """The terms whose parameter is not already a baseline unknown (an identified ``eta`` is no candidate)."""
    sc = scales
    L, EI, rhoA = sc.length, sc.EI, sc.rhoA
    out: list[Effect] = []
    if "eta" not in identified:
        out.append(_parameter_effect("kelvin_voigt", "eta", "s", 1.0, 0.2 / sc.omega_high, "eta",
                                     "Kelvin–Voigt (strain-rate) damping on top of viscous damping"))
    if "rhoI" not in identified:
        out.append(_parameter_effect("rotary_inertia", "rhoI", "kg.m", rhoA * L ** 2, 0.01, "r2_scaled",
                                     "rotary inertia of the cross-section (Rayleigh beam)"))
    if "kf" not in identified:
        out.append(_parameter_effect("foundation", "kf", "N/m2", EI / L ** 4, 2000.0, "kf_scaled",
                                     "Winkler elastic foundation"))
    return tuple(out)


#: This module's entry in the catalogue.
FAMILY = Family(("kelvin_voigt", "rotary_inertia", "foundation"), candidates)
