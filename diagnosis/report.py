"""A short human-readable report of a diagnosis (:class:`~diagnosis.result.GapReport`)."""
from __future__ import annotations

from .result import GapReport

__all__ = ["text_report"]


def _pct(v: float | None) -> str:
    return "   -" if v is None or v != v else f"{100 * float(v):4.0f}%"


def text_report(report: GapReport, *, top: int = 6) -> str:
    """Verdict, where the gap lies, and the ranked effects with held-out gap closed, as plain text."""
    lines = [f"verdict: {report.verdict}", f"  {report.reason}"]
    base = report.baseline
    ratios = ", ".join(f"{k} {v:.3g}" for k, v in base.heldout_gap_ratio.items())
    lines.append(f"baseline held-out gap ratio (1 = noise floor): {ratios}")
    if report.priors:
        lines.append("baseline against the priors:")
        lines += [f"  - {c.line()}" for c in report.priors]
    for lab, why in report.implausible.items():
        lines.append(f"not named, implausible: {lab}: " + "; ".join(why))
    lines.append(f"baseline's {base.numerical_adequacy.summary()}")
    lines.append(base.grid_advice.summary())
    if report.summary:
        lines.append("where:")
        lines += [f"  - {s}" for s in report.summary]
    lines.append("effects (score test, then refit of the shortlist):")
    lines.append(f"  {'rank':>4}  {'effect':<32} {'score':>10}  {'dBIC':>9}  {'closed':>6}  parameters")
    for row in report.effects[:top]:
        rf = row.refit
        score = f"{row.score:>10.4g}" if row.score is not None else f"{'(pair)':>10}"
        if rf is not None:
            params = ", ".join(f"{k}={v:.4g}" for k, v in rf.effect_parameters.items())
            lines.append(f"  {row.rank:>4}  {row.label:<32} {score}  {rf.delta_bic:>9.1f}"
                         f"  {_pct(rf.closed)}  {params}")
        else:
            lines.append(f"  {row.rank:>4}  {row.label:<32} {score}  {'-':>9}  {'   -':>6}")
    return "\n".join(lines)
