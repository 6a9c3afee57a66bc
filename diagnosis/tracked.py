"""The diagnosis of each still segment of a tracked record (:mod:`identification.tracking`).

Each segment's modes are weighed as a diagnosis from the modes alone weighs them
(:func:`diagnosis.from_modes.diagnose_from_modes`: the baseline and every structural effect fitted to the
frequencies and the config's priors, judged by BIC): per segment ``none``, the effect with its sizes, ``ambiguous``
or ``unexplained`` — so a series says not only how the tracked unknowns moved but whether some segment shows
what the model lacks (a support that came loose in one dwell, a mass added in another).  A segment without modes,
or whose modes and priors leave the baseline's scale free, gets the reason instead.
"""
from __future__ import annotations

from typing import Any, Sequence

from ebb_model.config import BeamConfig
from ebb_model.errors import EbbError
from identification.tracking import TrackedSegment

from .from_modes import ModalDiagnosis, diagnose_from_modes

__all__ = ["diagnose_segments", "segment_verdict"]


def diagnose_segments(config: BeamConfig, tracked: Sequence[TrackedSegment]) -> list[ModalDiagnosis | str]:
    """Per segment of ``tracked``, the diagnosis of its modes, or why there is none (module docstring)."""
    out: list[ModalDiagnosis | str] = []
    for row in tracked:
        if row.modes.frequencies_hz.size == 0:
            out.append("the segment shows no mode")
            continue
        try:
            out.append(diagnose_from_modes(config, None, modes=row.modes.modal_data()))
        except EbbError as exc:
            out.append(str(exc))
    return out


def segment_verdict(result: ModalDiagnosis | str) -> dict[str, Any]:
    """A segment's diagnosis as a row of ``tracked.json``: the verdict, its reason, the named effect's sizes with
    their standard deviations (or ``verdict`` None and why)."""
    if isinstance(result, str):
        return {"verdict": None, "why": result}
    named = result.named
    return {"verdict": result.verdict, "reason": result.reason, "tied": list(result.tied),
            "sizes": None if named is None else named.sizes, "size_std": None if named is None else named.size_std}
