"""End springs: the compliance of a constrained end's rotation or translation, or a spring to ground at a free
one (``boundary_rotational_<side>``, ``boundary_translational_<side>``; structural: a config change)."""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, cast

import numpy as np

from ebb_model.beam import End
from ebb_model.config import BeamConfig

from .base import AugmentedModel, Effect, Family, Scales

__all__ = ["FAMILY"]


def _with_end(config: BeamConfig, side: str, end: End) -> BeamConfig:
    # as dict[str, Any]: mypy matches a dict[str, End] against every field of the geometry (side is left or right)
    return replace(config, beam=replace(config.beam, **cast("dict[str, Any]", {side: end})))


def _boundary(config: BeamConfig, sc: Scales, side: str, dof: str) -> Effect:
    end: End = getattr(config.beam, side)
    L, EI = sc.length, sc.EI
    power = 1 if dof == "rotational" else 3
    unit = EI / L ** power              # kr in EI/L, kt in EI/L³
    key = "kr" if dof == "rotational" else "kt"
    fixed = end.rotation_fixed if dof == "rotational" else end.translation_fixed
    base = getattr(end, key)

    if fixed:
        # compliance c = unit/k: 0 is the constrained end, c = 1 is a very soft spring
        def stiffness(s: np.ndarray) -> float:
            return math.inf if s[0] <= 0 else unit / s[0]
        var, hi, what = f"compliance_{key}", (2.0 if dof == "rotational" else 0.5), "compliance of the constraint"
    else:
        def stiffness(s: np.ndarray) -> float:
            return base + unit * s[0]
        var, hi, what = f"{key}_scaled", 500.0, "spring to ground"

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        e: End = getattr(cfg.beam, side)
        kt, kr = e.kt, e.kr
        if key == "kr":
            kr = stiffness(s)
        else:
            kt = stiffness(s)
        return AugmentedModel(_with_end(cfg, side, End.of("elastic", kt, kr)), params)

    def physical(s: np.ndarray) -> dict[str, float]:
        return {key: stiffness(s)}

    return Effect(f"boundary_{dof}_{side}", None, (var,), (0.0,), (hi,), (0.0,),
                  f"{dof} {what} at the {side} end ({end.kind})", {key: "N.m/rad" if key == "kr" else "N/m"},
                  apply, physical)


def candidates(config: BeamConfig, scales: Scales, identified: tuple[str, ...]) -> tuple[Effect, ...]:
    """Both ends' rotational and translational springs."""
    return tuple(_boundary(config, scales, side, dof)
                 for side in ("left", "right") for dof in ("rotational", "translational"))


#: This module's entry in the catalogue.
FAMILY = Family(("boundary_rotational_left", "boundary_rotational_right",
         "boundary_translational_left", "boundary_translational_right"), candidates)
