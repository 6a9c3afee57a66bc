"""Special cases refitted where a general effect's refit put them (:mod:`diagnosis.search.rank`'s last stage).

Two candidates are special cases at a place the set-up fixes, and never compete for the score shortlist (a score
at a fixed place would push a physical effect off it):

* a transducer's mass (:mod:`diagnosis.effects.point_mass`): the point mass at a sensor — refitted from the point
  mass's refit when that lands within :data:`~diagnosis.effects.point_mass.AT_SENSOR` of a sensor, for the
  evidence to weigh against the free position (:mod:`diagnosis.judgement.weigh`);
* a shaker's armature (:mod:`diagnosis.effects.shaker`): a mass and a spring at the drive point — refitted from a
  point mass's or a spring's refit that lands within the same distance of an actuator (and kept from its modal
  match when the pattern stage refitted it).  It stays a candidate only when it pays for each of its parts: its
  BIC beats the mass alone and the suspension alone at the drive point (each refitted from its optimum) by
  the BIC margin (:attr:`~diagnosis.settings.Thresholds.bic_margin`) — a point mass at the drive point is a point
  mass, not an armature with a vanishing suspension.
"""
from __future__ import annotations

import numpy as np

from ..effects import Effect
from ..effects.point_mass import AT_SENSOR, TRANSDUCER
from ..effects.shaker import ARMATURE, parts
from ..problem.fitting import Fit
from .refits import EffectRefit
from .state import Search

__all__ = ["armature_refits", "transducer_refits"]


def transducer_refits(run: Search, refits: dict[str, EffectRefit]) -> dict[str, EffectRefit]:
    """The transducer masses of the sensors within :data:`~diagnosis.effects.point_mass.AT_SENSOR` of the point
    mass's refit, each refitted from it (its mass as the start)."""
    pm = refits.get("point_mass")
    if pm is None:
        return {}
    cfg, _ = run.problem.space.apply(run.problem.config, pm.fit.beta)
    x = float(pm.fit.s[1])
    out = {}
    for sensor in cfg.sensors:
        lab = f"{TRANSDUCER}[{sensor.name}]"
        if lab in run.effects and abs(sensor.x - x) <= AT_SENSOR * cfg.beam.length:
            fit = run.problem.fit(pm.fit.beta, run.effects[lab], pm.fit.s[:1], max_evaluations=run.max_evaluations)
            out[lab] = run.summary(run.effects[lab], fit)
            run.say(f"refit {lab} from the point mass at {x:.4g} m (sensor at {sensor.x:.4g} m)")
    return out


def _starts(run: Search, refits: dict[str, EffectRefit], actuator_x: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Where an armature's refit starts: a point mass's (its mass, no suspension) and a spring's refit (its
    stiffness, no mass) that landed within :data:`AT_SENSOR` of the actuator."""
    starts = []
    reach = AT_SENSOR * run.problem.config.beam.length      # (the length is never a baseline unknown)
    for source, i in (("point_mass", 0), ("grounded_spring", 1)):
        rf = refits.get(source)
        if rf is None:
            continue
        if abs(float(rf.fit.s[1]) - actuator_x) <= reach:
            s0 = np.zeros(2)
            s0[i] = rf.fit.s[0]
            starts.append((rf.fit.beta, s0))
    return starts


def _pays(run: Search, armature: Effect, fit: Fit, rf: EffectRefit) -> tuple[bool, str]:
    """Whether the armature's refit beats its mass alone and its suspension alone (each refitted from its optimum)
    by the BIC margin, and what they gave."""
    said = []
    for i, part in enumerate(parts(armature)):
        alone = run.summary(part, run.problem.fit(fit.beta, part, fit.s[i:i + 1],
                                                  max_evaluations=run.max_evaluations))
        said.append(f"{part.name} alone dBIC {alone.bic - rf.bic:+.1f}")
        if rf.bic >= alone.bic - run.problem.settings.bic_margin:
            return False, "; ".join(said)
    return True, "; ".join(said)


def armature_refits(run: Search, refits: dict[str, EffectRefit]) -> dict[str, EffectRefit]:
    """The refits with each actuator's armature refitted (module docstring) where a point mass or a spring landed
    at it, and kept only where it pays for each of its parts (an armature from its modal match is checked alike)."""
    out = dict(refits)
    for lab, armature in run.effects.items():
        if armature.name != ARMATURE:
            continue
        x = float(next(a.x for a in run.problem.config.actuators if a.name == armature.target))
        fits = [run.problem.fit(beta, armature, s0, max_evaluations=run.max_evaluations)
                for beta, s0 in _starts(run, refits, x)]
        if lab in refits:
            fits.append(refits[lab].fit)
        if not fits:
            continue
        best = min(fits, key=lambda f: f.rss)
        rf = run.summary(armature, best)
        pays, said = _pays(run, armature, best, rf)
        run.say(f"refit {lab} at the drive point ({x:.4g} m): fit RSS/n {best.rss / best.n:.4g}; {said}"
                + ("" if pays else ": not more than its parts, dropped"))
        if pays:
            out[lab] = rf
        else:
            out.pop(lab, None)
    return out
