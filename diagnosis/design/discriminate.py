"""The next experiment, computed: the record that would separate the leading candidates best (:func:`next_experiment`).

When the verdict leaves candidates tied, or says ``unexplained`` with plausible candidates refitted, the
diagnosis asks which record the bench can make (:mod:`diagnosis.design.space`) would tell them apart.  When
fewer than two refits are plausible but several close the records' gap, each needing implausible values (a real
bench whose records no catalogued structure explains with the values its documents allow), the design separates
those: which of the readings that fit — a mass, a chain gain, a softened section — is the one to question next.
When those refits, held within the plausibility limits, leave two or more plausible readings
(:mod:`diagnosis.search.plausible`), the design separates the readings instead, each at its held refit.

For a design ``d`` and two candidates A and B (each at its refit), the expected log Bayes factor of A over B on a
record of ``d`` when A is true is, for Gaussian noise, half the non-centrality of B's misfit to A's prediction
once B has adapted its unknowns to it (Atkinson & Fedorov's T-optimality; Box & Hill's discrimination):

    E_A[ln B_AB](d) ≈ ½ ‖(I − P_B) (y_A(d) − y_B(d))‖²,

``y`` the whitened outputs, ``P_B`` the projection on B's Jacobian on the design record (all its unknowns: the
beam's and the effect's, free on the new record alone — a conservative figure, the records at hand constrain
them too).  A design must decide whichever candidate is true, so its worth is the smaller of the two directions,
and, with more than two candidates, the smallest over the pairs.  The figure grows with the record's duration
(a stationary excitation): it is given per second and for a record as long as the fit windows at hand, and the
duration that reaches the decisive odds (:attr:`~diagnosis.settings.Thresholds.decisive_odds`) is stated.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..effects import Effect
from ..judgement.rules import Judgement
from ..judgement.verdict import Kind
from ..problem.fitting import Fit, GapProblem
from ..search.plausible import PlausibleReading
from ..search.rank import Ranking
from .space import Design, DesignBench, bench_designs

__all__ = ["NextExperiment", "ScoredDesign", "leading_candidates", "next_experiment"]

#: Designs kept in the result (best first), each the best of its set-up, band and kind of added sensor.
KEPT = 12
#: The shortest record a design's figure holds for: this many periods of its band's lowest frequency (the figure
#: is a stationary response's; a record shorter than a few periods is mostly the transient).
MIN_PERIODS = 10


@dataclass(frozen=True)
class ScoredDesign:
    """A design and its expected log Bayes factors per second of record: the worst pair and direction (``rate``),
    and per ordered pair ``"A>B"`` (A true, B its rival)."""

    design: Design
    rate: float
    pairs: dict[str, float]

    def seconds_for(self, log_odds: float) -> float | None:
        """The record's duration whose expected log Bayes factor reaches ``log_odds`` (at least
        :data:`MIN_PERIODS` periods of the band's lowest frequency); ``None`` when the design cannot separate."""
        if self.rate <= 0:
            return None
        return max(log_odds / self.rate, MIN_PERIODS / self.design.band_hz[0])

    def to_dict(self, seconds: float, decisive: float) -> dict[str, Any]:
        """JSON values at a record of ``seconds``, with the duration the decisive log odds ``decisive`` need."""
        return self.design.to_dict() | {
            "expected_log_bayes_factor": self.rate * seconds,
            "per_pair": {k: v * seconds for k, v in self.pairs.items()},
            "seconds_for_decisive": self.seconds_for(decisive)}


@dataclass(frozen=True)
class NextExperiment:
    """The leading candidates, the designs ranked by the worst pair's expected log Bayes factor, and the record
    duration the figures refer to; ``reason`` says why nothing was designed (then ``designs`` is empty)."""

    candidates: tuple[str, ...]
    probabilities: dict[str, float]
    seconds: float
    decisive: float
    designs: tuple[ScoredDesign, ...] = ()
    as_recorded: ScoredDesign | None = None        # the records' own band and sensors, for comparison
    reason: str | None = None
    #: how many designs were weighed
    weighed: int = 0
    #: the candidates among them whose refits need implausible values (designed for when fewer than two are
    #: plausible but these close the records' gap)
    implausible: tuple[str, ...] = ()
    #: whether the candidates are the plausible readings held within the limits (:mod:`diagnosis.search.plausible`)
    held: bool = False

    @property
    def best(self) -> ScoredDesign | None:
        """The design that separates the candidates best."""
        return self.designs[0] if self.designs else None

    def line(self) -> str:
        """One sentence for the console."""
        if self.best is None:
            return f"next experiment: none designed ({self.reason})"
        b = self.best
        need = b.seconds_for(self.decisive)
        reach = "never" if need is None else f"from a {need:.3g} s record"
        now = "" if self.as_recorded is None else (
            f"; the records' own design: {self.as_recorded.rate * self.seconds:.3g}")
        which = ' / '.join(self.candidates)
        if self.implausible:
            which += f" (refits that close the gap; {', '.join(self.implausible)} need implausible values)"
        if self.held:
            which += " (the plausible readings, held within the limits)"
        return (f"next experiment to separate {which}: {b.design.describe()} — expected "
                f"ln Bayes factor {b.rate * self.seconds:.3g} in {self.seconds:.3g} s (decisive {self.decisive:.3g}, "
                f"{reach}){now}; its diagnosis weighed with these records: --earlier this gap.json")

    def to_dict(self) -> dict[str, Any]:
        """JSON values (``gap.json``'s ``next_experiment``)."""
        return {"candidates": list(self.candidates), "posterior_probability": dict(self.probabilities),
                "record_seconds": self.seconds, "decisive_log_odds": self.decisive, "designs_weighed": self.weighed,
                "best": None if self.best is None else self.best.to_dict(self.seconds, self.decisive),
                "as_recorded": None if self.as_recorded is None else self.as_recorded.to_dict(self.seconds,
                                                                                                self.decisive),
                "designs": [d.to_dict(self.seconds, self.decisive) for d in self.designs],
                "reason": self.reason, "implausible": list(self.implausible), "plausible_readings": self.held}


def leading_candidates(judgement: Judgement, ranking: Ranking, most: int, closure: float) -> tuple[str, ...]:
    """The candidates a next record should separate: the verdict's ties (with the named effect), or — for
    ``unexplained`` — the refits nothing implausible is found in, the most probable first; when fewer than two are,
    the refits that close at least ``closure`` of the records' gap follow, implausible or not (the most probable,
    then the most closing first); at most ``most``."""
    v, weighed = judgement.verdict, judgement.weighed
    if v.kind is Kind.INDISTINGUISHABLE or (v.kind is Kind.EFFECT and v.ties):
        labels = ((v.label,) if v.label is not None else ()) + tuple(t for t in v.ties if t != v.label)
    elif v.kind is Kind.UNEXPLAINED:
        labels = tuple(lab for lab in weighed.evidence if lab in ranking.refits and lab not in weighed.implausible)
        if len(labels) < 2:
            order = list(weighed.evidence)
            closing = sorted((lab for lab, rf in ranking.refits.items() if rf.closed >= closure
                              and lab not in labels),
                             key=lambda lab: (order.index(lab) if lab in order else len(order),
                                              -ranking.refits[lab].closed))
            labels += tuple(closing)
    else:
        return ()
    return tuple(lab for lab in labels if lab in ranking.refits)[:most]


def _divergence(ya: np.ndarray, yb: np.ndarray, jb: np.ndarray, cols: list[int]) -> float:
    """½‖(I − P_B)(y_A − y_B)‖² over the output columns ``cols`` (module docstring)."""
    r = (ya[:, cols] - yb[:, cols]).ravel()
    J = jb[:, cols, :].reshape(r.size, -1)
    x, *_ = np.linalg.lstsq(J, r, rcond=1e-10)
    res = r - J @ x
    return 0.5 * float(res @ res)


def next_experiment(problem: GapProblem, ranking: Ranking, judgement: Judgement, band: tuple[float, float],
                    mode_hz: np.ndarray, readings: Sequence[PlausibleReading] = ()) -> NextExperiment | None:
    """The designs that would separate the leading candidates (module docstring), best first; ``None`` when the
    verdict leaves nothing to separate.  Given two or more plausible readings (:mod:`diagnosis.search.plausible`:
    the refits that close the gap held within the plausibility limits), the design separates those, each at its
    held refit."""
    s = problem.settings
    held: dict[str, PlausibleReading] = {}
    for r in readings:                       # most probable first; one per effect
        held.setdefault(r.label, r)
    if len(held) >= 2:
        labels = tuple(held)[:s.design_candidates]
        return _designed(problem, band, mode_hz, labels, {lab: held[lab].probability for lab in labels},
                         {lab: held[lab].effect for lab in labels}, {lab: held[lab].refit.fit for lab in labels}, (),
                         held=True)
    labels = leading_candidates(judgement, ranking, s.design_candidates, s.named_closure)
    implausible = tuple(lab for lab in labels if lab in judgement.weighed.implausible)
    v = judgement.verdict
    if not labels and v.kind not in (Kind.UNEXPLAINED, Kind.INDISTINGUISHABLE):
        return None
    probs = {lab: float(judgement.weighed.evidence.get(lab, 0.0)) for lab in labels}
    if len(labels) < 2:
        return NextExperiment(labels, probs, _seconds(problem), math.log(s.decisive_odds),
                              reason="fewer than two candidates to separate (no other refit is plausible or closes "
                                     f"{s.named_closure:.0%} of the records' gap)", implausible=implausible)
    return _designed(problem, band, mode_hz, labels, probs, {lab: ranking.effects[lab] for lab in labels},
                     {lab: ranking.refits[lab].fit for lab in labels}, implausible)


def _seconds(problem: GapProblem) -> float:
    """The fit windows' total duration, s."""
    return float(sum(r.fit_end for r in problem.records) * problem.config.time.dt)


def _designed(problem: GapProblem, band: tuple[float, float], mode_hz: np.ndarray, labels: tuple[str, ...],
              probs: dict[str, float], effects: dict[str, Effect], fits: dict[str, Fit],
              implausible: tuple[str, ...], *, held: bool = False) -> NextExperiment:
    """The designs that separate ``labels``, each candidate (its effect in ``effects``) at its fit in ``fits``."""
    s = problem.settings
    seconds = _seconds(problem)
    decisive = math.log(s.decisive_odds)
    z = {lab: np.concatenate([fits[lab].beta, fits[lab].s]) for lab in labels}
    parts = sorted({m.rig_part for e in effects.values() for m in (e.members or (e,)) if m.rig_part is not None})
    setups = ("as recorded",) + tuple(f"without the {p}" for p in parts)
    designs = bench_designs(problem, band, mode_hz, setups, s.design_top_hz)
    pairs = list(itertools.permutations(labels, 2))
    scored: list[ScoredDesign] = []
    for (setup, band_hz), group in itertools.groupby(designs, key=lambda d: (d.setup, d.band_hz)):
        lack = frozenset(p for p in parts if setup == f"without the {p}")
        bench = DesignBench.build(problem, band_hz, lack)
        y, J = {}, {}
        for lab in labels:
            out = bench.outputs(z[lab], effects[lab])
            if out is None:
                break
            y[lab], J[lab] = out, bench.jacobian(z[lab], effects[lab], out)
        else:
            for design in group:
                cols = bench.columns(design.sensor)
                per = {f"{a}>{b}": _divergence(y[a], y[b], J[b], cols) / bench.duration for a, b in pairs}
                scored.append(ScoredDesign(design, min(per.values()), per))
    if not scored:
        return NextExperiment(labels, probs, seconds, decisive, reason="no design could be simulated",
                              implausible=implausible, held=held)
    recorded = next((d for d in scored if d.design.setup == "as recorded" and d.design.band_name == "the records' "
                     "band" and d.design.sensor is None), None)
    # the best of each kind of design (set-up, band, kind of added sensor), so that the list shows the choices
    best: dict[tuple, ScoredDesign] = {}
    for d in scored:
        key = (d.design.setup, d.design.band_name, None if d.design.sensor is None else d.design.sensor[0])
        if key not in best or d.rate > best[key].rate:
            best[key] = d
    ranked = tuple(sorted(best.values(), key=lambda d: -d.rate)[:KEPT])
    return NextExperiment(labels, probs, seconds, decisive, ranked, recorded, weighed=len(scored),
                          implausible=implausible, held=held)
