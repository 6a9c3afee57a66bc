"""What ``corrected.json`` says of the corrected model besides its files: the effect and its refitted parameters
with units, the baseline without it, and the held-out gap before and after (:func:`corrected_summary`)."""
from __future__ import annotations

from typing import Any, Mapping

from ebb_model.config import BeamConfig
from identification.parameters import unit

from ..effects import Effect
from ..report.result import EffectRow

__all__ = ["corrected_summary"]


def corrected_summary(config: BeamConfig, baseline: Mapping[str, float], row: EffectRow | None, effect: Effect
                      ) -> dict[str, Any]:
    """What ``corrected.json`` says: the effect and its parameters with units (the effect's own,
    :attr:`Effect.units`), the refitted baseline, and the held-out gap before/after.

    Raises
    ------
    ValueError
        ``row`` has no refit (only a refitted effect is exported).
    """
    rf = None if row is None else row.refit
    if row is None or rf is None:
        raise ValueError(f"{effect.label}: only a refitted effect is exported")
    units = effect.units
    return {"effect": row.label, "description": row.description,
            "effect_parameters": {k: {"value": v, "unit": units.get(k, "")} for k, v in rf.effect_parameters.items()},
            "parameters": {k: {"value": v, "unit": unit(k)} for k, v in rf.baseline_parameters.items()},
            "baseline_without_effect": {k: {"value": v, "unit": unit(k)} for k, v in baseline.items()},
            "heldout_gap_ratio_before": dict(rf.heldout_gap_ratio_before),
            "heldout_gap_ratio_after": dict(rf.heldout_gap_ratio_after), "closed": rf.closed,
            "sensors": {s.name: s.unit for s in config.sensors}}
