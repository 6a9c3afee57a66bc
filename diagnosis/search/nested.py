"""Special cases refitted where a general effect's refit put them (:mod:`diagnosis.search.rank`'s last stage).

Some candidates are special cases at a place the set-up fixes, and never compete for the score shortlist (a score
at a fixed place would push a physical effect off it).  Each declares what this stage needs
(:class:`~diagnosis.effects.Effect`: ``place``, ``landings``, ``parts``) — nothing here names an effect:

* its refit starts from every general effect's refit that landed within the landing's reach of its place (a
  transducer's mass from a point mass's refit near its sensor; a shaker's armature from a point mass's or a
  spring's near its actuator), and from its own earlier refit (its modal match) when there is one: the best of
  them is kept;
* when it declares parts (an armature: its mass alone and its suspension alone at the drive point), it stays a
  candidate only when it beats each of them, refitted from its optimum, by the BIC margin
  (:attr:`~diagnosis.settings.Thresholds.bic_margin`) — a point mass at the drive point is a point mass, not an
  armature with a vanishing suspension.

Tied with its general effect, a special case that explains the held-out records on its own is then named
instead of it (:func:`diagnosis.judgement.rules.nested`).
"""
from __future__ import annotations

import numpy as np

from ..effects import Effect
from ..problem.fitting import Fit
from .refits import EffectRefit
from .state import Search

__all__ = ["landing_refits"]


def _starts(run: Search, effect: Effect, refits: dict[str, EffectRefit]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(beta, s0)`` of every declared landing near the effect's place (the place read in the config at the
    landing's baseline unknowns: a sensor's position may be one of them)."""
    starts = []
    assert effect.place is not None
    for landing in effect.landings:
        rf = refits.get(landing.source)
        if rf is None:
            continue
        cfg, _ = run.problem.space.apply(run.problem.config, rf.fit.beta)
        if abs(float(rf.fit.s[landing.position]) - effect.place(cfg)) <= landing.reach * cfg.beam.length:
            s0 = np.asarray(effect.off, dtype=float).copy()
            for mine, theirs in landing.copy:
                s0[mine] = rf.fit.s[theirs]
            starts.append((rf.fit.beta, s0))
    return starts


def _pays(run: Search, effect: Effect, fit: Fit, rf: EffectRefit) -> tuple[bool, str]:
    """Whether the refit beats each of the effect's parts (each refitted from its optimum, its own variable's
    value as the start) by the BIC margin, and what they gave."""
    said = []
    assert effect.parts is not None
    for i, part in enumerate(effect.parts(effect)):
        alone = run.summary(part, run.problem.fit(fit.beta, part, fit.s[i:i + 1],
                                                  max_evaluations=run.max_evaluations))
        said.append(f"{part.name} alone dBIC {alone.bic - rf.bic:+.1f}")
        if rf.bic >= alone.bic - run.problem.settings.bic_margin:
            return False, "; ".join(said)
    return True, "; ".join(said)


def landing_refits(run: Search, refits: dict[str, EffectRefit]
                   ) -> tuple[dict[str, EffectRefit], dict[str, str]]:
    """The refits with every special case refitted where a general effect landed near its place (module
    docstring), kept only where it pays for each of its parts; and the ones dropped, with why."""
    out, dropped = dict(refits), {}
    for lab, effect in run.effects.items():
        if effect.place is None or not effect.landings:
            continue
        fits = [run.problem.fit(beta, effect, s0, max_evaluations=run.max_evaluations)
                for beta, s0 in _starts(run, effect, refits)]
        if lab in refits:
            fits.append(refits[lab].fit)
        if not fits:
            continue
        best = min(fits, key=lambda f: f.rss)
        rf = run.summary(effect, best)
        pays, said = (True, "") if effect.parts is None else _pays(run, effect, best, rf)
        run.say(f"refit {lab} at its place ({effect.place(run.problem.config):.4g} m) from "
                f"{len(fits)} start(s): fit RSS/n {best.rss / best.n:.4g}" + (f"; {said}" if said else "")
                + ("" if pays else ": not more than its parts, dropped"))
        if pays:
            out[lab] = rf
        else:
            out.pop(lab, None)
            dropped[lab] = f"not more than its parts ({said})"
    return out, dropped
