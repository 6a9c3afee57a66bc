"""The truth of the grid's claims on a record: bounded refits on the model's grid and on a finer one.

``identify`` and ``diagnose`` say of the grid "adequate", "undecided", "these records fit it better" or "too coarse
for these records" (:func:`ebb_model.space.adequacy.grid_line`), and the numerical share's line may add "refine
[beam] nodes before blaming physics" — claims made from one Gauss–Newton step on the line's refined grid.  Checked
here against refits (:func:`identification.polish.polish`, bounded, nonlinear) on the model's grid and on a finer
one (``2n + 1`` nodes, at least :data:`FINE` — finer than the line's own for the config's 80; on grids of 1,295
nodes and more the eigen-solver's round-off moves a correct record's answer by deviations: 2,591 nodes moved one of
the hint family's correct records 16 deviations and raised its χ² by 529), both from the identified point.  The
answer moves by ``max |x_fine − x| / σ`` (σ the deviations the line quotes) and the outputs by
``mean((y_fine − y)²) / σ_noise²`` (the line's white noise level).  Refitting on the model's grid too keeps a polish
that stopped short out of it (a record with an undeclared delay: refitted on its own grid the answer moved 21
deviations).  The grid *matters* when the answer moves by more than twice
:data:`~ebb_model.space.adequacy.GRID_SHIFT` or the outputs by twice
:data:`~ebb_model.space.adequacy.NOISE_FLOOR_EXCESS`, does *not* when both stay below half of them; between, the
truth is borderline and no claim there is counted false.  False: "adequate" where the grid matters, "too coarse" or
"refine" where it does not, "fit it better" where the finer grid's refit does not raise χ² decisively; "undecided"
claims nothing.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ebb_model.space.adequacy import DECISIVE_EVIDENCE, GRID_SHIFT, NOISE_FLOOR_EXCESS, ParameterShift
from identification.native import NativeEvaluator
from identification.noise_model import NoiseModel
from identification.polish import ResidualEvaluator, polish

#: The finest grid's least number of nodes (module docstring).
FINE = 647
#: The grid line's claims, by the words it starts with.
CLAIMS = (("adequate", "grid: adequate"), ("undecided", "grid: undecided"),
          ("fit_better", "grid: these records fit it better"), ("too_coarse", "grid: too coarse"))


def grid_claims(line: str, share_line: str) -> tuple[str, bool]:
    """The grid line's claim (``adequate``, ``undecided``, ``fit_better``, ``too_coarse``) and whether the
    numerical share's line says to refine the grid."""
    kind = next(k for k, words in CLAIMS if line.startswith(words))
    return kind, "before blaming physics" in share_line


def grid_truth(evaluator: NativeEvaluator, x: np.ndarray, noise: NoiseModel, shift: ParameterShift | None
               ) -> dict[str, Any]:
    """What the grid does to the answer ``x`` of ``evaluator``'s records (module docstring); ``shift`` the line's,
    for its deviations (none: the answer's move is not counted)."""
    cfg = evaluator.config
    fine_cfg = replace(cfg, beam=replace(cfg.beam, nodes=max(2 * cfg.beam.nodes + 1, FINE)))
    here = NativeEvaluator(cfg, evaluator.space, evaluator.experiments, stabilising=False)
    fine = NativeEvaluator(fine_cfg, evaluator.space, evaluator.experiments, stabilising=False)
    a, b = (polish(ev, x, noise=noise, max_evaluations=300).x for ev in (here, fine))
    moves = 0.0
    if shift is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            sigma = np.abs(shift.step / shift.deviations)
        moves = float(np.nanmax(np.abs(b - a) / sigma, initial=0.0))
    white = np.median(noise.std, axis=0) ** 2
    ya, yb = here.simulate(a).outputs, fine.simulate(b).outputs
    change = float(max(np.max(np.mean((q - p) ** 2, axis=0) / white) for p, q in zip(ya, yb)))
    chi2 = [float(np.sum(ResidualEvaluator(ev, noise).residuals(v) ** 2)) for ev, v in ((here, a), (fine, b))]
    matters = moves > 2 * GRID_SHIFT or change > 2 * NOISE_FLOOR_EXCESS
    not_at_all = moves < GRID_SHIFT / 2 and change < NOISE_FLOOR_EXCESS / 2
    return dict(fine_nodes=fine_cfg.beam.nodes, moves=moves, change=change, raises=chi2[1] - chi2[0],
                truth="matters" if matters else ("does not" if not_at_all else "borderline"))


def false_grid_claims(kind: str, refine: bool, truth: dict[str, Any]) -> list[str]:
    """The grid's claims on a record that its refits contradict (module docstring)."""
    wrong = {"adequate": truth["truth"] == "matters", "too_coarse": truth["truth"] == "does not",
             "fit_better": truth["raises"] < DECISIVE_EVIDENCE, "undecided": False}[kind]
    return ([f"grid: {kind}"] if wrong else []) + (["refine"] if refine and truth["truth"] == "does not" else [])
