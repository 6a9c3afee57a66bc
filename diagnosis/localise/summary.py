"""The localisation's summary: what is significant, in words."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np


from .results import AmplitudeGap, BandGap, CrossCorrelation, ModeGap, SensorGap, Whiteness, WindowGap

def _fmt_p(p: float) -> str:
    return f"{p:.0e}" if p < 1e-3 else f"{p:.2g}"


def _summary(sensors: Sequence[SensorGap], modes: Sequence[ModeGap], bands: Sequence[BandGap],
             wins: Sequence[WindowGap], amps: Sequence[AmplitudeGap], xcs: Sequence[CrossCorrelation],
             whites: Sequence[Whiteness]) -> list[str]:
    """Short human-readable statements, most important first; empty if no sensor has a gap."""
    out: list[str] = []
    for s in sorted(sensors, key=lambda s: -s.gap_ratio):
        if not s.gap_detected:
            continue
        name = s.sensor
        n_before = len(out)
        out.append(f"sensor {name}: residual variance is {s.gap_ratio:.3g}× the noise variance "
                   f"(NRMSE {s.nrmse:.3g}, {s.model_error_fraction:.0%} of the residual is model error)")
        if s.residual_mean ** 2 >= 0.25 * s.noise_std ** 2:
            out.append(f"sensor {name}: residual has a mean offset of {s.residual_mean:.3g} "
                       f"({abs(s.residual_mean) / s.noise_std:.2g}× the noise std): static/offset error")
        ms = [m for m in modes if m.sensor == name and m.significant]
        ms.sort(key=lambda m: -(m.band_excess_fraction if np.isfinite(m.band_excess_fraction) else 0.0))
        for m in ms[:3]:
            parts = []
            if "frequency" in m.significant:
                parts.append(f"measured {abs(m.freq_shift_rel):.2%} {'below' if m.freq_shift_rel < 0 else 'above'} "
                             f"model")
            if "damping" in m.significant:
                parts.append(f"damping {m.damping_ratio:.2g}× model ({m.measured_damping:.3g} vs "
                             f"{m.model_fit_damping:.3g})")
            share_ok = not np.isfinite(m.band_excess_fraction) or m.band_excess_fraction >= 0.05
            if ("amplitude/phase" in m.significant and not {"frequency", "damping"} & set(m.significant)
                    and share_ok):
                parts.append(f"amplitude ×{m.band_gain:.3g}, phase {m.band_phase_deg:+.1f}°")
            if not parts:
                continue
            share = (f"; {m.band_excess_fraction:.0%} of the model-error energy is in this band"
                     if np.isfinite(m.band_excess_fraction) else "")
            # the records' resonance nearest the model's mode: on a baseline whose frequency scale is off it need not
            # be the same mode (the strip's mid-span mass: the baseline at 0.67 of the records' scale, its fifth mode
            # read against the records' fourth)
            out.append(f"sensor {name}: the resonance nearest mode {m.mode} ({m.model_freq_hz:.4g} Hz) "
                       + ", ".join(parts) + share)
        if not ms:
            bs = [b for b in bands if b.sensor == name and np.isfinite(b.excess_fraction)]
            if bs:
                b = max(bs, key=lambda b: b.excess_fraction)
                if b.excess_fraction >= 0.5:
                    where = f"the band of mode {b.mode}" if b.mode is not None else "above the modes"
                    out.append(f"sensor {name}: {b.excess_fraction:.0%} of the model-error energy lies in "
                               f"{b.f_lo:.4g}–{b.f_hi:.4g} Hz ({where})")
        w = next(w for w in wins if w.sensor == name)
        if w.drift:
            if w.phase_p <= min(w.gain_p, w.rms_p):
                out.append(f"sensor {name}: measured phase relative to a time-invariant linear fit changes by "
                           f"{w.phase_change_deg:+.2f}° over the record (slope p={_fmt_p(w.phase_p)}): "
                           "drift (time-varying dynamics)")
            elif w.gain_p <= w.rms_p:
                out.append(f"sensor {name}: measured gain relative to a time-invariant linear fit changes by "
                           f"{w.gain_change:+.3g} over the record (slope p={_fmt_p(w.gain_p)}): drift")
            else:
                out.append(f"sensor {name}: residual of a time-invariant linear fit "
                           f"{'grows' if w.rms_change > 0 else 'shrinks'} over the record "
                           f"({w.rms_change:+.0%}, slope p={_fmt_p(w.rms_p)}): drift")
        a = next(a for a in amps if a.sensor == name)
        if a.nonlinear:
            if np.isfinite(a.gain_p) and (not np.isfinite(a.phase_p) or a.gain_p <= a.phase_p):
                out.append(f"sensor {name}: gain {'grows' if a.gain_slope > 0 else 'falls'} with "
                           f"amplitude ({a.gain_slope:+.3g} per e-fold, p={_fmt_p(a.gain_p)}): nonlinearity")
            else:
                out.append(f"sensor {name}: phase changes with amplitude ({a.phase_slope_deg:+.2f}° per e-fold, "
                           f"p={_fmt_p(a.phase_p)}): nonlinearity")
        for c in xcs:
            if c.sensor == name and c.significant:
                out.append(f"sensor {name}: residual correlated with input {c.input} (max |r| = {c.max_abs:.2g} "
                           f"at lag {c.max_lag}, 99 % band {c.band:.2g}): input-related model error")
        h = next(h for h in whites if h.sensor == name)
        if not h.white and len(out) == n_before + 1:
            out.append(f"sensor {name}: residual is coloured (Ljung–Box p={_fmt_p(h.ljung_box_p)}): "
                       "unmodelled dynamics rather than noise")
    return out
