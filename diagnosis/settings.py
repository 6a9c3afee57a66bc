"""Every threshold the diagnosis decides with, in one object, each with the reason for its value.

:class:`Thresholds` travels with the problem (:attr:`diagnosis.problem.fitting.GapProblem.settings`) to every stage that
decides — the verdict rule, the pairs, the modal pattern, plausibility, the evidence, the grid — and is written
whole to ``gap.json`` (``settings``: the values and ``reasons``).  A config sets any of them in a ``[diagnosis]``
table (:func:`thresholds_from_config`), checked like the rest of the config::

    [diagnosis]
    bic_margin = 6.0        # a weaker bar for an effect to pay for its parameters
    named_closure = 0.9

Defaults are the values every test and benchmark of the diagnosis is measured with.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Mapping

from ebb_model.space.adequacy import NOISE_FLOOR_EXCESS
from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError

__all__ = ["SECTION", "Thresholds", "thresholds_from_config"]

#: The config's table of diagnosis settings.
SECTION = "diagnosis"


def _reason(text: str, lo: float, hi: float, integer: bool = False) -> dict[str, Any]:
    return {"reason": text, "range": (lo, hi), "integer": integer}


@dataclass(frozen=True)
class Thresholds:
    """The diagnosis' decision thresholds (each field's metadata holds its reason and allowed range)."""

    gap_threshold: float = field(default=NOISE_FLOOR_EXCESS, metadata=_reason(
        "relative excess of the held-out residual variance over the noise floor below which there is no gap "
        "(ebb_model.space.adequacy.NOISE_FLOOR_EXCESS: a gap ratio up to 1.25 is the noise)", 0.0, 1e9))
    explained_share: float = field(default=0.1, metadata=_reason(
        "a refit that leaves at most this share of the baseline's excess over the noise floor on the fit windows "
        "explains the gap: the search stops widening (other basins, continuation refits); what is left is the "
        "noise estimate's and the model's own few per cent (an excess of 0.7 closed to 0.09 is explained)",
        0.0, 1.0))
    bic_margin: float = field(default=10.0, metadata=_reason(
        "BIC improvement an effect must reach to pay for its parameters: 'very strong' on Kass & Raftery's "
        "scale (a Bayes factor of about 150)", 0.0, 1e3))
    named_closure: float = field(default=0.8, metadata=_reason(
        "share of the held-out gap a refit must close for its effect to be named the cause (a smaller share "
        "leaves most of the gap to something else)", 0.0, 1.0))
    tie_gain: float = field(default=0.95, metadata=_reason(
        "share of the named effect's held-out gain a rival must reach to tie with it (closing 95 % of what the "
        "best closes is within what a second, different refit of the same records moves)", 0.0, 1.0))
    tie_excess: float = field(default=0.25, metadata=_reason(
        "a rival ties only when what it leaves exceeds what the named effect leaves by at most the gap threshold "
        "or this share of the named effect's own excess (a rival leaving 349 noise variances where the best leaves "
        "1.1 is decided, though both close 97-100 %)", 0.0, 1e3))
    decisive_odds: float = field(default=20.0, metadata=_reason(
        "posterior odds from which the evidence decides between candidates the fits do not separate, and the "
        "force's sign: a Bayes factor above 20 is 'strong' (Kass & Raftery 1995), 0.95 between two", 1.0, 1e9))
    numerical_share_limit: float = field(default=0.5, metadata=_reason(
        "largest share of the baseline gap that refining the model's grid changes for which a physical effect "
        "is still named (above it the gap is mostly the grid's)", 0.0, 1.0))
    grid_caution: float = field(default=0.1, metadata=_reason(
        "share of the baseline gap that refining the model's grid changes from which a named effect's reason "
        "carries a caution and the grid advice", 0.0, 1.0))
    confounded: float = field(default=1e-3, metadata=_reason(
        "share of an effect's sensitivity (its Jacobian column on the data) the baseline unknowns leave "
        "unexplained, below which the effect is degenerate with them: only a prior separates the two (a sensor's "
        "gain and a common scale of EI, rhoA and c)", 0.0, 1.0))
    pair_minimum: float = field(default=0.25, metadata=_reason(
        "share of the held-out gap the best single effect must close before a pair with it is tried (two effects "
        "of like size each close about half of it alone; one that closes almost nothing is not half of a pair)",
        0.0, 1.0))
    pair_remainder: float = field(default=5.0, metadata=_reason(
        "held-out excess (noise variances above the floor) the best single effect may leave before a second effect "
        "is tried even though it closes nearly all of a large gap (a foundation closing 97.7 % of 405 leaves 9.4: "
        "a sensor's lag); the blind families' single truths leave up to 2.3, the model's own discretisation "
        "against the independent truth on accelerometers", 0.0, 1e9))
    pair_partners: int = field(default=5, metadata=_reason(
        "further candidates tried as the second effect of a pair (a foundation absorbed into the axial load ranked "
        "fourth at an actuator lag's refit, behind three effects that each mimic part of it)", 1, 100, True))
    pair_rival_share: float = field(default=0.9, metadata=_reason(
        "a single effect closing this share of what the best single closes is its near-equal rival: the pairs it "
        "makes are refitted and weighed too (a foundation closing 52.7 % beside a spring closing 54.7 %)", 0.0, 1.0))
    pair_rivals: int = field(default=2, metadata=_reason(
        "near-equal rivals of the best single effect whose pairs are refitted besides its own", 0, 20, True))
    pattern_candidates: int = field(default=2, metadata=_reason(
        "structural effects refitted from the measured modes' pattern, best matches first", 1, 100, True))
    pattern_rival: float = field(default=10.0, metadata=_reason(
        "a further pattern match is refitted only while its chi2 is within this factor of the best match's (or of "
        "2 per mode, a match within the errors)", 1.0, 1e6))
    score_significance: float = field(default=0.01, metadata=_reason(
        "p-value of a score test below which a candidate asks to be refitted: one not refitted is listed with the "
        "reason (gap.json's not_refitted), and a chain's gain under a prior on the beam is refitted", 0.0, 1.0))
    design_candidates: int = field(default=3, metadata=_reason(
        "leading candidates a designed next experiment separates (the ties, or the plausible refits of an "
        "unexplained gap, the most probable first): every pair of them is weighed on every design", 2, 10, True))
    design_top_hz: float = field(default=0.0, metadata=_reason(
        "highest frequency the bench's exciter can drive in a designed next experiment [Hz]; 0: up to 0.4 of the "
        "sampling rate (below an anti-alias filter's edge)", 0.0, 1e9))
    shortlist: int = field(default=4, metadata=_reason(
        "best-scoring effects refitted (the score test ranks; refits decide)", 1, 100, True))

    def to_dict(self) -> dict[str, Any]:
        """The values and, under ``reasons``, why each has its value."""
        out: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["reasons"] = {f.name: f.metadata["reason"] for f in fields(self)}
        return out


def thresholds_from_config(config: BeamConfig, **overrides: Any) -> Thresholds:
    """The thresholds of ``config``'s ``[diagnosis]`` table (the defaults for what it leaves out), then
    ``overrides`` that are not ``None`` (API and command-line arguments).

    Raises
    ------
    ConfigError
        The table is not a table, names an unknown setting, or a value outside its range — every problem at once.
    """
    table = config.extra.get(SECTION, {}) or {}
    if not isinstance(table, Mapping):
        raise ConfigError(f"{SECTION}: must be a table")
    given = dict(table) | {k: v for k, v in overrides.items() if v is not None}
    known = {f.name: f for f in fields(Thresholds)}
    bad = [f"{SECTION}.{k}: unknown setting; allowed: {', '.join(known)}" for k in given if k not in known]
    values: dict[str, Any] = {}
    for k, v in given.items():
        if k not in known:
            continue
        lo, hi = known[k].metadata["range"]
        integer = known[k].metadata["integer"]
        ok = not isinstance(v, bool) and isinstance(v, int if integer else (int, float)) and lo <= v <= hi
        if not ok:
            bad.append(f"{SECTION}.{k}: must be {'a whole number' if integer else 'a number'} in {lo:g} … {hi:g}, "
                       f"got {v!r}")
        else:
            values[k] = int(v) if integer else float(v)
    if bad:
        raise ConfigError(bad)
    return replace(Thresholds(), **values)
