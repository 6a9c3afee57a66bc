"""The identified model of an identification run as plain text (:func:`identified_lines`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ebb_model.beam import PARAMETER_UNITS

if TYPE_CHECKING:  # pragma: no cover
    from .result import IdentificationResult

__all__ = ["identified_lines"]


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
        unit = PARAMETER_UNITS.get(k, "m" if k.startswith("x_") else "")
        lines.append(f"  {k:<6} = {v:.6g} ± {ident['cramer_rao_std'][k]:.2g} {unit}  (Cramér–Rao std)")
    gap = ident.get("fit_gap_ratio")
    if gap:
        worst = max(gap.values())
        lines.append("  fit residual in noise variances (1 = noise floor): "
                     + ", ".join(f"{k} {v:.3g}" for k, v in gap.items()))
        if not ident["cramer_rao_valid"]:
            lines.append(f"  caution: the fit leaves {worst:.3g} noise variances; the Cramér–Rao bound assumes a fit "
                         "at the noise floor and understates the uncertainty here (model or data do not match yet: "
                         "see `ebb diagnose`)")
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
    return lines
