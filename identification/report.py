"""The identified model of an identification run as plain text (:func:`identified_lines`) and as sections of
the run's HTML page (:func:`html_sections`)."""
from __future__ import annotations

import json
from typing import TYPE_CHECKING

from ebb_model.io.htmlio import Section, Table, figures_in
from .parameters import unit

if TYPE_CHECKING:  # pragma: no cover
    from .result import IdentificationResult

__all__ = ["identified_lines", "html_sections", "FIGURES"]


def identified_lines(res: IdentificationResult) -> list[str]:
    """The identified model as text lines: values with Cramér–Rao standard deviations, units and the fit
    quality the bound assumes (what ``ebb identify`` prints).

    Parameters
    ----------
    res : IdentificationResult
        Result of :func:`identification.run.identify`.

    Returns
    -------
    list of str
    """
    ident = res.identified
    lines = [f"identified model ({ident['from']}):"]
    for k, v in ident["parameters"].items():
        u = unit(k)
        lines.append(f"  {k:<6} = {v:.6g} ± {ident['cramer_rao_std'][k]:.2g} {u}  (Cramér–Rao std)")
    for k, b in (ident.get("on_bounds") or {}).items():
        lines.append(f"  caution: {k} ended on its {b['bound']} bound {b['value']:.6g}: the value is the search "
                     "range's, not the data's (widen the bound, or check the model and the records)")
    if ident.get("cramer_rao_note"):
        lines.append(f"  Cramér–Rao std {ident['cramer_rao_note']}")
    gap = ident.get("fit_gap_ratio")
    if gap:
        worst = max(gap.values())
        lines.append("  fit residual in noise variances (1 = noise floor): "
                     + ", ".join(f"{k} {v:.3g}" for k, v in gap.items()))
        if not ident["cramer_rao_valid"]:
            lines.append(f"  caution: the fit leaves {worst:.3g} noise variances; the Cramér–Rao bound assumes a fit "
                         "at the noise floor and understates the uncertainty here (model or data do not match yet: "
                         "see `ebb diagnose`)")
    lines += [f"  hint: {h}" for h in ident.get("hints") or ()]
    if res.priors:
        lines.append("  against the priors:")
        lines += [f"    {c.line()}" for c in res.priors]
    a = ident.get("against_measured_modes")
    if a:
        lines.append(f"  against the {a['modes']} measured modes: {'agrees' if a['agrees'] else 'DISAGREES'} "
                     f"(chi2 {a['chi2']:.3g}, limit {a['chi2_limit']:.3g}; model "
                     + ", ".join(f"{v:.4g}" for v in a["model_hz"] or []) + " Hz)")
    if res.adequacy is not None:
        lines.append("  " + res.adequacy.summary())
    if res.grid_advice is not None:
        lines.append("  " + str(res.grid_advice["summary"]))
    return lines


#: The identification's figures and their captions, in the page's order (:func:`html_sections`).
FIGURES = {"knee_fit.png": "Measured and simulated outputs (the knee, and the identified model: the polished knee)",
           "pareto_front.png": "The GA's front (or its convergence, for a single objective)",
           "parameter_spread.png": "The unknowns over the front, with the knee and the identified model"}


def html_sections(res: IdentificationResult) -> list[Section]:
    """The identification as sections of an HTML page (:func:`ebb_model.io.htmlio.write_page`): the identified
    model with its standard deviations, the fit, the uncertainty written beside it, the search, the figures."""
    from .uncertainty import FOLDER

    ident = res.identified
    names = list(ident["parameters"])
    rows = [(k, f"{v:.6g}", f"{ident['cramer_rao_std'][k]:.2g}",
             unit(k)) for k, v in ident["parameters"].items()]
    lines = identified_lines(res)[1 + len(names):]
    sections = [Section("Identified model", lead=f"identified model ({ident['from']})",
                        tables=(Table(("parameter", "value", "Cramér–Rao std", "unit"), rows),),
                        paragraphs=tuple(line.strip() for line in lines))]
    bound = res.out_dir / FOLDER / "bound.json"
    if bound.is_file():
        doc = json.loads(bound.read_text())
        if doc.get("band_hz"):
            lo, hi = doc["band_hz"]
            sections.append(Section("Uncertainty", paragraphs=(
                f"multiplicative bound |G − G0| ≤ w |G0| per output in the excited band {lo:.3g}–{hi:.3g} Hz, "
                f"covering {doc['samples']} models sampled from the parameters' covariance and the fit residual's "
                f"part coherent with the force; files in {FOLDER}/",), tables=(Table(
                    ("output", "median w", "largest w"),
                    [(s, f"{v['median']:.3g}", f"{v['max']:.3g}")
                     for s, v in doc["multiplicative_bound_in_band"].items()]),)))
    f, p = res.fisher_nominal, res.pareto
    fisher = () if f is None else (f"Fisher information at the nominal point: rank {f.rank}/{len(f.names)}, "
                                   f"condition number {f.condition_number:.3g}", *f.messages)
    sections.append(Section("Search", paragraphs=(
        *fisher, f"{len(p.X)} Pareto points after {p.generations} generations, {p.n_evaluations} evaluations",
        *(f"noise: {line}" for line in res.noise_model))))
    figures = figures_in(res.out_dir, FIGURES)
    if figures:
        sections.append(Section("Figures", figures=tuple(figures)))
    return sections
