"""A short human-readable report of a diagnosis (:class:`~diagnosis.report.result.GapReport`)."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

from ebb_model.io.htmlio import Section, Table, figures_in

from .result import GapReport

__all__ = ["beam_values", "text_report", "html_sections", "FIGURES"]


def _pct(v: float | None) -> str:
    return "   -" if v is None or v != v else f"{100 * float(v):4.0f}%"


def beam_values(report: GapReport) -> list[str]:
    """The beam's values without an effect (the baseline's) and, when an effect is named, with it (its refit's):
    where they differ, the baseline's compensate what the model lacked and the refit's are the beam's."""
    def values(params: Mapping[str, float]) -> str:
        return ", ".join(f"{k} = {v:.5g}" for k, v in params.items())

    lines = [f"baseline (no effect): {values(report.baseline.parameters)}"]
    label = report.judged.label
    row = next((r for r in report.effects if r.label == label and r.refit is not None), None)
    if row is not None and row.refit is not None:
        lines.append(f"with {label}: {values(row.refit.baseline_parameters)} (the beam once the effect is modelled; "
                     "the baseline's values compensate the effect where they differ)")
    return lines


def text_report(report: GapReport, *, top: int = 6) -> str:
    """Verdict, where the gap lies, and the ranked effects with held-out gap closed, as plain text."""
    lines = [f"verdict: {report.verdict}", f"  {report.reason}"]
    base = report.baseline
    ratios = ", ".join(f"{k} {v:.3g}" for k, v in base.heldout_gap_ratio.items())
    lines.append(f"baseline held-out gap ratio (1 = noise floor): {ratios}")
    lines += beam_values(report)
    if report.priors:
        lines.append("baseline against the priors:")
        lines += [f"  - {c.line()}" for c in report.priors]
    for lab, why in report.implausible.items():
        lines.append(f"not named, implausible: {lab}: " + "; ".join(why))
    lines.append(f"baseline's {base.numerical_adequacy.summary()}")
    lines.append(base.grid_summary)
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
    unseen = [f"  - {row.label}: {row.not_refitted}" for row in report.effects if row.not_refitted]
    if unseen:
        lines.append("significant scores not refitted:")
        lines += unseen
    if report.plausible_readings:
        lines.append("held within plausibility (readings, not a verdict):")
        lines += [f"  - {r.line()}" for r in report.plausible_readings]
    if report.next_experiment is not None:
        lines.append(report.next_experiment.line())
    return "\n".join(lines)


#: The diagnosis' figures and their captions, in the page's order (:func:`html_sections`).
FIGURES = {"effects.png": "The candidates: score-test statistic, and the share of the held-out gap each refit closes",
           "heldout_residuals.png": ("Held-out residuals against the noise floor (running RMS and spectrum), "
                                     "before and after the verdict"),
           "residuals.png": "Where the model and the record disagree: the residual over time",
           "frf.png": "Measured and modelled frequency response",
           "windows.png": "The residual's size window by window",
           "amplitude.png": "The residual against the response amplitude (a nonlinearity's sign)",
           "correlation.png": "The residual's correlation with the input",
           "bands.png": "The residual's power by frequency band",
           "next_experiment.png": "The next experiment: expected log Bayes factor of the designs that separate the "
                                  "leading candidates"}


def html_sections(report: GapReport, out_dir: Path, *, top: int = 10) -> list[Section]:
    """The diagnosis as sections of an HTML page (:func:`ebb_model.io.htmlio.write_page`): the verdict, the
    baseline, where the gap lies, the ranked effects, the corrected model and the figures found in ``out_dir``
    (and its ``localisation`` folder)."""
    base = report.baseline
    verdict = Section("Verdict", lead=f"verdict: {report.verdict}", paragraphs=(report.reason,))
    baseline = Section("Baseline (the identifying model without an effect)", tables=(Table(
        ("sensor", "held-out gap ratio (1 = noise floor)"),
        [(k, f"{v:.4g}") for k, v in base.heldout_gap_ratio.items()]),),
        paragraphs=(*beam_values(report), *(c.line() for c in report.priors),
                    f"baseline's {base.numerical_adequacy.summary()}",
                    base.grid_summary,
                    *(f"not named, implausible: {lab}: " + "; ".join(why) for lab, why in report.implausible.items())))
    rows = []
    for row in report.effects[:top]:
        rf = row.refit
        rows.append((str(row.rank), row.label, "(pair)" if row.score is None else f"{row.score:.4g}",
                     "-" if rf is None else f"{rf.delta_bic:.1f}", "-" if rf is None else _pct(rf.closed).strip(),
                     "" if rf is None else ", ".join(f"{k} = {v:.4g}" for k, v in rf.effect_parameters.items())))
    effects = Section("Effects", tables=(Table(("rank", "effect", "score", "ΔBIC", "held-out gap closed",
                                                "fitted values"), rows,
                                               "score test of every candidate, then the refit of the shortlist"),),
                      paragraphs=tuple(f"{row.label}: {row.not_refitted}" for row in report.effects
                                       if row.not_refitted))
    sections = [verdict, baseline]
    if report.summary:
        sections.append(Section("Where the gap lies", paragraphs=tuple(report.summary)))
    sections.append(effects)
    if report.plausible_readings:
        sections.append(Section("Held within plausibility", lead=(
            "no effect is named; the refits that close the gap, held within the priors, the measured modes and the "
            "effects' ranges — readings, not a verdict"), tables=(Table(
                ("effect", "reading", "values", "held-out gap", "NRMSE", "probability"),
                [(r.label, r.reading, ", ".join(f"{k} = {v:.4g}" for k, v in r.refit.physical.items()),
                  f"{r.heldout_gap:.3g}", f"{r.nrmse:.1%}", f"{r.probability:.2g}")
                 for r in report.plausible_readings],
                "held-out gap in noise variances (1 = the noise floor); probabilities among the readings"),)))
    nxt = report.next_experiment
    if nxt is not None:
        sections.append(Section("The next experiment", lead=nxt.line(), tables=() if not nxt.designs else (Table(
            ("design", "expected ln Bayes factor", "seconds to decide"),
            [(d.design.describe(), f"{d.rate * nxt.seconds:.3g}",
              "-" if (t := d.seconds_for(nxt.decisive)) is None else f"{t:.3g}") for d in nxt.designs],
            f"the worst pair's expected log Bayes factor in a {nxt.seconds:.3g} s record; decisive from "
            f"{nxt.decisive:.3g}"),)))
    if report.corrected_files:
        sections.append(Section("Corrected model", paragraphs=(
            "the baseline with the verdict's effect, in corrected/: " + ", ".join(report.corrected_files),)))
    figures = figures_in(out_dir, FIGURES) + figures_in(out_dir / "localisation", FIGURES)
    if figures:
        sections.append(Section("Figures", figures=tuple(figures)))
    return sections
