"""A short human-readable report of a ``gap.json`` document."""
from __future__ import annotations

from typing import Any, Mapping

from ebb_model.adequacy import adequacy_line

__all__ = ["text_report"]


def _pct(v: Any) -> str:
    return "   -" if v is None else f"{100 * float(v):4.0f}%"


def text_report(doc: Mapping[str, Any], *, top: int = 6) -> str:
    """Verdict, where the gap lies, and the ranked effects with held-out gap closed, as plain text."""
    lines = [f"verdict: {doc['verdict']}", f"  {doc['reason']}"]
    base = doc["baseline"]
    ratios = ", ".join(f"{k} {v:.3g}" for k, v in base["heldout_gap_ratio"].items())
    lines.append(f"baseline held-out gap ratio (1 = noise floor): {ratios}")
    if base.get("numerical_adequacy"):
        lines.append(f"baseline's {adequacy_line(base['numerical_adequacy'])}")
    if base.get("grid_advice"):
        lines.append(base["grid_advice"]["summary"])
    if doc.get("summary"):
        lines.append("where:")
        lines += [f"  - {s}" for s in doc["summary"]]
    lines.append("effects (score test, then refit of the shortlist):")
    lines.append(f"  {'rank':>4}  {'effect':<32} {'score':>10}  {'dBIC':>9}  {'closed':>6}  parameters")
    for row in doc["effects"][:top]:
        rf = row.get("refit")
        score = f"{row['score']:>10.4g}" if row["score"] is not None else f"{'(pair)':>10}"
        if rf:
            params = ", ".join(f"{k}={v:.4g}" for k, v in rf["effect_parameters"].items())
            lines.append(f"  {row['rank']:>4}  {row['label']:<32} {score}  {rf['delta_bic']:>9.1f}"
                         f"  {_pct(rf['closed'])}  {params}")
        else:
            lines.append(f"  {row['rank']:>4}  {row['label']:<32} {score}  {'-':>9}  {'   -':>6}")
    return "\n".join(lines)
