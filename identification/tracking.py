"""A record that changes during acquisition, tracked: per still segment its modes and the unknowns they fix.

A beam whose axial load is stepped between dwells, a support a motor moves, a structure warming in stages: one
model of the whole record fits none of its parts.  A channel that follows the change (a load cell, a position
sensor) says where the set-up stood still (:func:`identification.segments.stationary_segments`); each still
segment is read without a force — as a free decay or as an ambient record
(:func:`identification.segments.segment_modes`) — and the config's unknowns are fitted to that segment's modes
and the config's priors (:func:`identification.modes_only.identify_from_modes`) — when the model cannot
reproduce them, again without the segment's heavily damped companions of better-shown modes
(:func:`identification.segments.companions`: a rattling support's), which are left out when the model then
reproduces the rest, or matches them better.  The result is a time series:
per segment its time span, the channel's level with its uncertainty, the modes, and every unknown with its
posterior standard deviation — or, where a segment fixes nothing, why (no mode found, a direction the modes and
priors leave free).  What ties the unknowns to the channel (a calibration of the channel's volts) is the user's
to read from the series: :func:`linear_in_channel` fits a straight line and says how well it holds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, EbbError

from .modes_only import identify_from_modes
from .modes_result import ModalIdentification
from .output_modes import OutputModes
from .segments import Segment, companions, segment_modes, stationary_segments

__all__ = ["TrackedSegment", "track", "linear_in_channel", "straight_line"]


@dataclass(frozen=True)
class TrackedSegment:
    """One still segment of a tracked record: samples ``[start, stop)`` and their times [s], the declared
    channel's level and its standard uncertainty, the segment's modes, the unknowns fitted to them
    (``None`` with ``why`` when the segment fixes none)."""

    segment: Segment
    start_s: float
    stop_s: float
    modes: OutputModes
    identified: ModalIdentification | None
    why: str = ""
    #: ``(m,)`` the modes left out of the fit as companions (:func:`identification.segments.companions`)
    left_out: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def evidence(self) -> OutputModes:
        """The modes the fit took: every mode but those :attr:`left_out`."""
        if not np.any(self.left_out):
            return self.modes
        return self.modes.subset(~self.left_out)

    @property
    def left_out_hz(self) -> list[float]:
        """The frequencies [Hz] of the modes left out."""
        return self.modes.frequencies_hz[self.left_out].tolist() if np.any(self.left_out) else []

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (a row of ``tracked.json``)."""
        ident = self.identified
        return {"start_s": self.start_s, "stop_s": self.stop_s, "level": self.segment.level,
                "level_std": self.segment.level_std, "modes": self.modes.to_dict(),
                "parameters": None if ident is None else ident.parameters,
                "std": None if ident is None else {n: (None if n in ident.held or not math.isfinite(s) else s)
                                                   for n, s in ident.std.items()},
                "held": None if ident is None else ident.held,
                "modes_agree": None if ident is None else ident.agreement["agrees"], "why": self.why,
                "left_out_hz": self.left_out_hz}


def track(config: BeamConfig, outputs: np.ndarray, channel: np.ndarray, *, kind: str = "decay",
          skip_seconds: float = 0.1) -> list[TrackedSegment]:
    """The record ``outputs`` ``(n, n_sensors)`` of ``config``'s sensors cut where ``channel`` ``(n,)`` stands
    still, each segment's modes read as ``kind`` (``"decay"`` or ``"ambient"``) and the config's unknowns fitted
    to them (module docstring).

    Raises
    ------
    DataError
        The channel and the outputs differ in length; an unknown ``kind``; no still segment.
    """
    from ebb_model.errors import DataError

    y = np.asarray(outputs, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    x = np.asarray(channel, dtype=float).reshape(-1)
    if x.size != y.shape[0]:
        raise DataError(f"the declared channel has {x.size} samples, the sensors {y.shape[0]}")
    dt = config.time.dt
    segments = stationary_segments(x, dt)
    if not segments:
        raise DataError("the declared channel never stands still: no segment to read")
    found = segment_modes(y, dt, segments, kind=kind, skip_seconds=skip_seconds)
    out = []
    for seg, modes in zip(segments, found):
        ident, why, left = None, "", np.zeros(modes.frequencies_hz.size, dtype=bool)
        if modes.frequencies_hz.size == 0:
            why = "the segment shows no mode"
        else:
            ident, why = _identified(config, modes)
            candidates = companions(modes)
            if np.any(candidates) and not np.all(candidates) and (ident is None or not ident.agreement["agrees"]):
                # the model cannot reproduce the modes with the candidates: without them, does it, or better?
                other, _ = _identified(config, modes.subset(~candidates))
                if other is not None and (other.agreement["agrees"] or ident is None
                                          or _per_mode(other) < _per_mode(ident)):
                    ident, why, left = other, "", candidates
        out.append(TrackedSegment(seg, seg.start * dt, seg.stop * dt, modes, ident, why, left))
    return out


def _per_mode(ident: ModalIdentification) -> float:
    """A fit's χ² per measured mode."""
    return float(ident.agreement["chi2"]) / max(int(ident.agreement["modes"]), 1)


def _identified(config: BeamConfig, modes: OutputModes) -> tuple[ModalIdentification | None, str]:
    """The config's unknowns fitted to ``modes``, or ``None`` and why not."""
    try:
        return identify_from_modes(config, None, modes=modes.modal_data()), ""
    except (ConfigError, EbbError) as exc:        # e.g. a direction the modes and priors leave free
        return None, str(exc)


def linear_in_channel(tracked: Sequence[TrackedSegment], name: str) -> dict[str, float] | None:
    """Unknown ``name`` against the channel's level over the segments that fixed it (and whose model reproduces
    their modes: a value from a fit that does not is no measurement): the weighted straight line
    (``slope``, ``intercept``, each with its standard deviation), its ``r2`` and ``chi2`` per degree of freedom
    (the scatter about the line in the unknown's own uncertainties: near 1 when the line holds); ``None`` with
    fewer than three such segments."""
    rows = [(t.segment.level, t.identified.parameters[name], t.identified.std[name]) for t in tracked
            if t.identified is not None and t.identified.agreement["agrees"] and name in t.identified.parameters
            and name not in t.identified.held and math.isfinite(t.identified.std[name]) and t.identified.std[name] > 0]
    return straight_line(rows)


def straight_line(rows: Sequence[tuple[float, float, float]]) -> dict[str, float] | None:
    """The weighted straight line through ``(level, value, std)`` rows (:func:`linear_in_channel`'s numbers);
    ``None`` with fewer than three rows."""
    rows = [r for r in rows if math.isfinite(r[2]) and r[2] > 0]
    if len(rows) < 3:
        return None
    lvl, val, sd = (np.array(c, dtype=float) for c in zip(*rows))
    A = np.column_stack([lvl, np.ones_like(lvl)]) / sd[:, None]
    coef, *_ = np.linalg.lstsq(A, val / sd, rcond=None)
    cov = np.linalg.inv(A.T @ A)
    resid = val - (coef[0] * lvl + coef[1])
    w = 1.0 / sd ** 2
    mean = float(np.sum(w * val) / np.sum(w))
    r2 = 1.0 - float(np.sum(w * resid ** 2)) / float(np.sum(w * (val - mean) ** 2))
    return {"slope": float(coef[0]), "slope_std": float(math.sqrt(cov[0, 0])), "intercept": float(coef[1]),
            "intercept_std": float(math.sqrt(cov[1, 1])), "r2": r2,
            "chi2_per_dof": float(np.sum((resid / sd) ** 2)) / (len(rows) - 2), "segments": float(len(rows))}


def together_lines(config: BeamConfig, tracked: Sequence[TrackedSegment], varying: list[str], channel: str
                   ) -> tuple[dict[str, Any], list[str]]:
    """The tracked segments that show modes fitted together (:func:`identification.joint_segments.fit_together`,
    ``varying`` per segment, started from the segments' own fits when every one has one): ``tracked.json``'s
    ``together`` and the lines a user reads — the shared unknowns, each segment's own, χ² against its degrees of
    freedom, each segment's modes predicted with the segment held out (:func:`identification.hold_out.hold_out`),
    and each varying unknown's straight line against the channel's level.

    Raises
    ------
    ConfigError
        A ``varying`` name that is not an unknown of ``config``.
    """
    from .hold_out import hold_out
    from .joint_segments import fit_together
    from .parameters import parameter_space

    use = [i for i, t in enumerate(tracked) if t.evidence.frequencies_hz.size]
    if not use:
        return {"why": "no segment shows a mode"}, ["together: no segment shows a mode"]
    names = parameter_space(config).names
    starts = ([np.array([tracked[i].identified.parameters[n] for n in names]) for i in use]   # type: ignore[union-attr]
              if all(tracked[i].identified is not None for i in use) else [])
    data = [tracked[i].evidence.modal_data() for i in use]
    joint = fit_together(config, data, varying, starts)
    shared = ", ".join(f"{n} {v:.5g} ± {joint.shared_std[n]:.2g}" for n, v in joint.shared.items())
    verdict = ("one beam reproduces every segment" if joint.agrees else
               f"beyond its 99.9 % point {joint.chi2_limit:.3g}: one beam of the config's model does not reproduce "
               "every segment, and the σ are the frequencies' alone")
    out = [f"together ({', '.join(varying)} per segment, the rest shared by {len(use)} segments): {shared}; "
           f"chi2 {joint.chi2:.4g} for {joint.dof} degrees of freedom ({verdict})"]
    for i, v, sd, c, hz in zip(use, joint.varying, joint.varying_std, joint.segment_chi2, joint.measured_hz):
        own = ", ".join(f"{n} {x:.5g} ± {sd[n]:.2g}" for n, x in v.items())
        aside = sorted(set(tracked[i].evidence.frequencies_hz.tolist()) - set(hz))
        out.append(f"  segment {i + 1}: {own} (chi2 {c:.3g} for {len(hz)} modes"
                   + (f"; {', '.join(f'{f:.5g}' for f in aside)} Hz set aside: a doublet's other member)"
                      if aside else ")"))
    held = hold_out(config, data, varying, joint)
    if held:
        worst = max(held, key=lambda h: h.largest)
        k = int(np.nanargmax(np.abs(worst.error)))
        out.append(f"held out (each segment's {', '.join(varying)} from one of its modes, the shared unknowns from "
                   f"the other segments): its other modes predicted within {100 * worst.largest:.2g} % (segment "
                   f"{use[worst.segment] + 1}'s mode {k + 1} from its mode {worst.used + 1}: "
                   f"{worst.model_hz[k]:.5g} Hz against {worst.measured_hz[k]:.5g} Hz)")
        for i in sorted({h.segment for h in held}):
            each = "; ".join(f"from mode {h.used + 1}: " + ", ".join(
                f"mode {k + 1} {100 * e:+.2f} %" for k, e in enumerate(h.error) if np.isfinite(e))
                for h in held if h.segment == i)
            out.append(f"  segment {use[i] + 1} held out: {each}")
    fits = {}
    for n in varying:
        fit = straight_line([(tracked[i].segment.level, v[n], sd[n])
                             for i, v, sd in zip(use, joint.varying, joint.varying_std)])
        fits[n] = fit
        if fit is not None:
            out.append(f"{n} (together) against {channel}: slope {fit['slope']:.5g} ± {fit['slope_std']:.2g}, "
                       f"intercept {fit['intercept']:.5g} ± {fit['intercept_std']:.2g}, R² {fit['r2']:.4f}, "
                       f"χ²/dof {fit['chi2_per_dof']:.3g} over {int(fit['segments'])} segments")
    return joint.to_dict() | {"segments": [i + 1 for i in use], "varies": varying, "against_channel": fits,
                              "held_out": [h.to_dict() | {"segment": use[h.segment] + 1} for h in held]}, out
