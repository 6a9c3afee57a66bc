"""Per-mode comparison of the measured and the model FRF (see :mod:`diagnosis.localise.core`): band complex gain,
local SDOF fits (frequency shift, damping ratio, amplitude and phase at the mode) or, for an unresolved peak, the
peak locations with the scatter between the record's halves; significance with a Bonferroni correction."""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from .results import ModeGap
from .spectra import FrfEstimate, _fit_sdof, _peak_bin, _peak_location, _Sdof
from .thresholds import DAMPING_BINS, MIN_DAMPING_RATIO, MIN_GAIN, MIN_PHASE_DEG, MIN_SHIFT, PAD

__all__ = ["FrfSet", "mode_gaps"]


@dataclass(frozen=True)
class FrfSet:
    """Measured and model H1 FRFs at the analysis resolution (``fr_m``, ``fr_h``), zero-padded ``PAD`` times
    (``fp_m``, ``fp_h``), and the padded pairs of the record's two halves (for an empirical peak-location error)."""

    fr_m: FrfEstimate
    fr_h: FrfEstimate
    fp_m: FrfEstimate
    fp_h: FrfEstimate
    halves: tuple[tuple[FrfEstimate, FrfEstimate], ...]


def mode_gaps(frfs: FrfSet, u2: np.ndarray, mf: np.ndarray, md: np.ndarray | None, mode_no: Sequence[int],
              edges: Sequence[float], excess_by_mode: dict[tuple[int, int], float], snames: Sequence[str],
              inames: Sequence[str], alpha: float) -> list[ModeGap]:
    """One :class:`ModeGap` per sensor and mode (``mf`` sorted, ``mode_no`` the caller's numbering)."""
    n_out = frfs.fr_m.H.shape[1]
    n_mode_tests = max(1, n_out * len(mf) * 3)
    return [_mode_gap(frfs, u2, mf, md, mode_no, edges, excess_by_mode, snames, inames, o, k, n_mode_tests, alpha)
            for o in range(n_out) for k in range(len(mf))]


def _mode_gap(frfs: FrfSet, u2: np.ndarray, mf: np.ndarray, md: np.ndarray | None, mode_no: Sequence[int],
              edges: Sequence[float], excess_by_mode: dict[tuple[int, int], float], snames: Sequence[str],
              inames: Sequence[str], o: int, k: int, n_mode_tests: int, alpha: float) -> ModeGap:
    """The :class:`ModeGap` of sensor ``o`` and (sorted) mode ``k``: the input that excites it most, the band's
    complex gain, local SDOF fits (or peak locations) of measured and model FRFs, and which differences are
    significant at family-wise level ``alpha`` over ``n_mode_tests`` tests."""
    fr_m, fr_h, fp_h = frfs.fr_m, frfs.fr_h, frfs.fp_h
    f = fr_m.f
    df = float(f[1] - f[0])
    fk = mf[k]
    lo_s = edges[k] if k > 0 else 0.0
    hi_s = edges[k + 1]
    lo_s, hi_s = max(lo_s, 0.85 * fk), min(hi_s, 1.15 * fk)
    zk = max(float(md[k]), 1e-3) if md is not None else 0.02
    # input with the largest model response around the mode
    band_sel = (f >= lo_s) & (f <= hi_s)
    contrib = [float(np.max(np.abs(fr_h.H[band_sel & fr_h.excited[:, j], o, j]), initial=0.0))
               * math.sqrt(float(np.var(u2[:, j]))) for j in range(u2.shape[1])]
    j = int(np.argmax(contrib))
    exc = fr_m.excited[:, j]
    hm = fr_m.H[:, o, j]
    hh = fr_h.H[:, o, j]
    mode_kw: dict[str, Any] = {"sensor": snames[o], "mode": mode_no[k], "input": inames[j],
                               "model_freq_hz": float(fk), "model_damping": None if md is None else float(md[k])}
    nan = float("nan")
    empty: dict[str, Any] = {
        "observed": False, "fit_ok": False, "freq_method": "none", "model_fit_freq_hz": nan,
        "measured_freq_hz": nan, "freq_shift_rel": nan,
        "freq_shift_std": nan, "freq_shift_p": nan, "model_fit_damping": nan, "measured_damping": nan,
        "damping_ratio": nan, "damping_ratio_std": nan, "damping_p": nan, "damping_resolved": False,
        "amplitude_ratio": nan, "phase_diff_deg": nan, "band_gain": nan, "band_phase_deg": nan,
        "band_gain_p": nan, "coherence": nan,
        "band_excess_fraction": excess_by_mode.get((o, mode_no[k]), nan), "significant": ()}
    if contrib[j] <= 0 or np.count_nonzero(band_sel & exc) < 3:
        return ModeGap(excited=False, **{**mode_kw, **empty})
    hw = min(max(4.0 * zk * fk, 6.0 * df), 0.15 * fk)
    ph = _peak_bin(f, np.where(exc, np.abs(hh), np.nan), lo_s, hi_s)
    pm = _peak_bin(f, np.where(exc, np.abs(hm), np.nan), lo_s, hi_s)
    res = dict(empty)
    # band complex gain over the model window (excited bins)
    fc = f[ph] if ph is not None else fk
    wsel = (f >= max(fc - hw, lo_s)) & (f <= min(fc + hw, hi_s)) & exc
    if np.count_nonzero(wsel) < 2:
        wsel = band_sel & exc
    res.update(_band_gain(hh[wsel], hm[wsel], fr_m.coherence[wsel, o]))
    # is the mode visible in the model FRF at this sensor (not at a node)?
    pad_exc = fp_h.excited[:, j]
    pk_h = _peak_location(fp_h.f, fp_h.H[:, o, j], fp_h.coherence[:, o], pad_exc, fp_h.n_segments, PAD, lo_s, hi_s)
    pk_m = _peak_location(frfs.fp_m.f, frfs.fp_m.H[:, o, j], frfs.fp_m.coherence[:, o], pad_exc,
                          frfs.fp_m.n_segments, PAD, lo_s, hi_s)
    observed = pk_h is not None and abs(pk_h[0] - fk) <= max(2.0 * df, 0.02 * fk)
    res["observed"] = bool(observed)
    # local SDOF fits, each centred on its own peak
    fits: list[_Sdof | None] = []
    for pk, hx in ((ph, hh), (pm, hm)):
        if pk is None or not observed:
            fits.append(None)
            continue
        sel = (f >= max(f[pk] - hw, lo_s)) & (f <= min(f[pk] + hw, hi_s)) & exc
        full = (f >= max(f[pk] - hw, lo_s)) & (f <= min(f[pk] + hw, hi_s))
        if np.count_nonzero(sel) < max(6, 0.6 * np.count_nonzero(full)):
            fits.append(None)  # too few excited lines for a peak fit (e.g. sparse multisine)
            continue
        ft = _fit_sdof(f[sel], hx[sel], float(f[pk]), zk)
        fits.append(ft if ft is not None and ft.rel_resid < 0.3 else None)
    sh, sm = fits
    if sh is not None and sm is not None:
        res.update(_sdof_comparison(sh, sm, df))
    elif observed and pk_m is not None and pk_h is not None:
        res.update(_peak_comparison(frfs, pk_m, pk_h, o, j, lo_s, hi_s))
    res["significant"] = _significant(res, n_mode_tests, alpha)
    return ModeGap(excited=True, **{**mode_kw, **res})


def _band_gain(a: np.ndarray, b_: np.ndarray, coherence: np.ndarray) -> dict[str, float]:
    """The complex gain ``c`` of the measured FRF ``b_`` over the model's ``a`` on a band's bins (least squares),
    its test against 1 and the mean coherence; nothing when the model's FRF vanishes there."""
    den = float(np.sum(np.abs(a) ** 2))
    if den <= 0:
        return {}
    c = complex(np.sum(b_ * a.conj()) / den)
    e = b_ - c * a
    m_ = len(a)
    var_c = 2.0 * float(np.sum(np.abs(e) ** 2)) / max(m_ - 1, 1) / den
    zc = abs(c - 1.0) / math.sqrt(var_c) if var_c > 0 else (math.inf if c != 1 else 0.0)
    # |c - 1| is Rayleigh-distributed under H0 (complex Gaussian, variance var_c)
    return {"band_gain": abs(c), "band_phase_deg": math.degrees(np.angle(c)), "band_gain_p": float(math.exp(-zc ** 2)),
            "coherence": float(np.mean(coherence))}


def _sdof_comparison(sh: _Sdof, sm: _Sdof, df: float) -> dict[str, Any]:
    """Frequency shift, damping ratio and peak amplitude/phase of the measured SDOF fit ``sm`` against the
    model's ``sh``, with their errors and p-values."""
    nan = float("nan")
    shift = sm.fn / sh.fn - 1.0
    sshift = math.hypot(sm.fn_std, sh.fn_std) / sh.fn
    dr = sm.zeta / sh.zeta
    sl = math.hypot(sm.zeta_std / sm.zeta, sh.zeta_std / sh.zeta)
    hr = sm.h_at_fn / sh.h_at_fn if sh.h_at_fn != 0 else complex(nan)
    return dict(fit_ok=True, freq_method="sdof_fit", model_fit_freq_hz=sh.fn, measured_freq_hz=sm.fn,
                freq_shift_rel=shift, freq_shift_std=sshift,
                freq_shift_p=float(2 * stats.norm.sf(abs(shift) / sshift)) if sshift > 0 else 0.0,
                model_fit_damping=sh.zeta, measured_damping=sm.zeta, damping_ratio=dr,
                damping_ratio_std=dr * sl,
                damping_p=float(2 * stats.norm.sf(abs(math.log(dr)) / sl)) if sl > 0 else 0.0,
                damping_resolved=bool(2 * min(sh.zeta * sh.fn, sm.zeta * sm.fn) >= DAMPING_BINS * df),
                amplitude_ratio=abs(hr), phase_diff_deg=math.degrees(np.angle(hr)))


def _peak_comparison(frfs: FrfSet, pk_m: tuple, pk_h: tuple, o: int, j: int, lo_s: float, hi_s: float
                     ) -> dict[str, Any]:
    """An unresolved or poorly fitting peak: the peak locations of the two identically smeared FRFs compared
    (the damping is not measurable).  Leakage of modes that outlast a segment makes these locations scatter
    more than the H1 random error says, so the error is also taken from the two halves of the record."""
    fp_m, fp_h = frfs.fp_m, frfs.fp_h
    shift = pk_m[0] / pk_h[0] - 1.0
    sshift = math.hypot(pk_m[1], pk_h[1]) / pk_h[0]
    sh_half = []
    for hm_, hh_ in frfs.halves:
        a_ = _peak_location(hm_.f, hm_.H[:, o, j], hm_.coherence[:, o], hm_.excited[:, j],
                            hm_.n_segments, PAD, lo_s, hi_s)
        b_ = _peak_location(hh_.f, hh_.H[:, o, j], hh_.coherence[:, o], hh_.excited[:, j],
                            hh_.n_segments, PAD, lo_s, hi_s)
        sh_half.append(math.nan if a_ is None or b_ is None else a_[0] / b_[0] - 1.0)
    # var(full) ≈ var(half) / 2 ≈ (d_A - d_B)² / 4; a failed half counts as a 15 % scatter
    sshift = max(sshift, abs(sh_half[0] - sh_half[1]) / 2 if all(map(np.isfinite, sh_half)) else 0.15)
    hr = fp_m.H[pk_m[2], o, j] / fp_h.H[pk_h[2], o, j]
    return dict(freq_method="peak", model_fit_freq_hz=pk_h[0], measured_freq_hz=pk_m[0],
                freq_shift_rel=shift, freq_shift_std=sshift,
                freq_shift_p=float(2 * stats.norm.sf(abs(shift) / sshift)),
                amplitude_ratio=float(abs(hr)), phase_diff_deg=math.degrees(np.angle(hr)))


def _significant(res: dict[str, Any], n_mode_tests: int, alpha: float) -> tuple[str, ...]:
    """Which of frequency, damping and amplitude/phase differ significantly (Bonferroni over ``n_mode_tests``)
    and by more than the smallest differences worth naming."""
    sig_list = []
    if res["freq_method"] != "none" and res["freq_shift_p"] * n_mode_tests < alpha \
            and abs(res["freq_shift_rel"]) >= MIN_SHIFT:
        sig_list.append("frequency")
    if (res["fit_ok"] and res["damping_resolved"] and res["damping_p"] * n_mode_tests < alpha
            and abs(math.log(res["damping_ratio"])) >= math.log(MIN_DAMPING_RATIO)):
        sig_list.append("damping")
    if np.isfinite(res["band_gain_p"]) and res["band_gain_p"] * n_mode_tests < alpha and (
            abs(res["band_gain"] - 1) >= MIN_GAIN or abs(res["band_phase_deg"]) >= MIN_PHASE_DEG):
        sig_list.append("amplitude/phase")
    return tuple(sig_list)
