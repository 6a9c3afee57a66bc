"""What an identification from measured natural frequencies alone found (:func:`identification.modes_only.
identify_from_modes`): each unknown with its posterior standard deviation or why it was held, what rests on the
priors, and the model's frequencies against the measured ones — as a user reads it and as ``identified.json``."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .prior import PriorCheck

__all__ = ["ModalIdentification"]


@dataclass(frozen=True)
class ModalIdentification:
    """What :func:`identification.modes_only.identify_from_modes` found.

    Attributes
    ----------
    parameters, std
        Every unknown's value and posterior standard deviation (a held unknown: its nominal value, std ``nan``).
    held
        The unknowns held at their nominal values, each with why.
    from_priors
        The unknowns whose common scale the frequencies leave free, so that it rests on their priors (EI and ρA
        of a free beam, say); empty when the frequencies fix every free unknown.
    root_ratio
        ``√(EI/ρA)`` and its standard deviation, when both are unknowns: what the frequencies fix.
    priors
        Each prior's check at the result (:class:`identification.prior.PriorCheck`).
    agreement
        The model's frequencies against the measured ones (:meth:`identification.modal_data.ModalData.agreement`).
    n_evaluations
        Frequency evaluations of the search.
    out_dir
        Where ``identified.json`` was written (``None``: nothing written).
    """

    parameters: dict[str, float]
    std: dict[str, float]
    held: dict[str, str]
    priors: tuple[PriorCheck, ...]
    agreement: dict[str, Any]
    n_evaluations: int
    from_priors: tuple[str, ...] = ()
    root_ratio: tuple[float, float] | None = None
    out_dir: Path | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``identified.json``)."""
        return {"evidence": "measured natural frequencies only (no time record)",
                "parameters": self.parameters,
                "std": {n: (None if n in self.held else s) for n, s in self.std.items()}, "held": self.held,
                "scale_from_priors": list(self.from_priors),
                "root_EI_over_rhoA": None if self.root_ratio is None else {"value": self.root_ratio[0],
                                                                           "std": self.root_ratio[1]},
                "priors": [p.to_dict() for p in self.priors], "modes": self.agreement,
                "n_evaluations": self.n_evaluations}

    def lines(self) -> list[str]:
        """What a user reads: each unknown with its uncertainty, what was held and why, the priors, the modes."""
        out = []
        for n, v in self.parameters.items():
            s = self.std[n]
            out.append(f"{n} = {v:.6g}" + (f" (held: {self.held[n]})" if n in self.held else f" ± {s:.2g} (1σ)"))
        if self.root_ratio is not None:
            v, sd = self.root_ratio
            out.append(f"√(EI/ρA) = {v:.6g} ± {sd:.2g} (1σ, {100 * sd / v:.2g} %): what the frequencies fix")
        if self.from_priors:
            out.append(f"the common scale of {', '.join(self.from_priors)} rests on their priors: the frequencies fix "
                       f"their ratios only (a record with its force would fix it)")
        for p in self.priors:
            if p.name in self.from_priors and p.status != "conflict":     # not the data's alone: say whose it is
                head = p.line().rsplit("): ", 1)[0]
                out.append(f"{head}): its ratio to {', '.join(n for n in self.from_priors if n != p.name)} from the "
                           f"frequencies, its scale from the prior")
            else:
                out.append(p.line())
        a = self.agreement
        aside = (f" ({', '.join(f'{v:.5g}' for v in a['aside_hz'])} Hz set aside: a doublet's other member)"
                 if a.get("aside_hz") else "")
        out.append(f"measured modes {np.round(a['measured_hz'], 4).tolist()} Hz{aside}, the model's "
                   f"{np.round(a['model_hz'], 4).tolist()} Hz: chi2 {a['chi2']:.3g} for {a['modes']} modes "
                   + ("(agree)" if a["agrees"] else f"(beyond its 99.9 % point {a['chi2_limit']:.3g}: the model "
                                                    f"does not reproduce them)"))
        return out
