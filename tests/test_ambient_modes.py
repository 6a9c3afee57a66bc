"""Records under a force nobody measured (identification.ambient_modes): their modes and uncertainties against an
independent truth, and ``ebb identify`` / ``ebb diagnose CONFIG --ambient RECORD`` from them alone.

Truth: the Hermite FE cantilever of ``tests/test_output_modes.py`` (DROPBEAR's size, 64 elements exact in time,
its frequencies within 1.6e-7 of the continuous beam's — checked there and, against this estimator's own stated
uncertainties, below), here at ζ₁ = 1 % (mass-proportional: ζ_n = c / (2 ρA ω_n)), driven near the tip by a
white random force the tool is not given, read by two accelerometers through a DAQ's anti-alias filter (8th
order at 0.4 fs) with 1 % white noise, sampled at 2 kHz; the record starts after a warm-up of five seconds
(eleven time constants of the first mode), so it is stationary.  (Without the filter the fifth mode, 1,230 Hz,
shows at its alias 770 Hz — the estimator reads what the record holds.)
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ebb_model.errors import DataError
from ebb_model.reference import hermite_beam
from ebb_model.reference.analytic import analytic_frequencies_hz
from ebb_model.reference.synthetic import synthesize
from identification.ambient_modes import SEGMENTS, ambient_modes
from identification.output_modes import SIGNIFICANCE
from identification.segments import segment_modes, stationary_segments, track

from ebb_model.acquisition.antialias import AntiAlias

from conftest import make_config
from test_modes_only import _config
from test_output_modes import EI, RHOA, L, SENSORS, _cantilever_shape, deviates

DT = 1 / 2000
C = 2 * 0.01 * (2 * math.pi * 21.6) * RHOA           # ζ_1 = 1 %
WARM, SECONDS = 5.0, 48.0


def _ambient(seed: int, seconds: float = SECONDS, ei: float = EI) -> np.ndarray:
    """The truth's stationary response to a white force at 0.48 m, ``seconds`` after a 5 s warm-up, 1 % noise
    (bending stiffness ``ei``)."""
    cfg = make_config("clamped", "free", length=L, dt=DT, EI=EI, rhoA=RHOA, c=C, actuators=[("F1", 0.48)],
                      sensors=[("a1", SENSORS[0], "acceleration"), ("a2", SENSORS[1], "acceleration")])
    cfg = replace(cfg, sensors=tuple(replace(s, antialias=AntiAlias(8, 0.4 / DT)) for s in cfg.sensors))
    warm = int(WARM / DT)
    u = np.random.default_rng(100 + seed).standard_normal(warm + int(seconds / DT))
    return synthesize(cfg, u, params={"EI": ei}, noise=0.01, seed=seed).outputs[warm:]


def _truth(k: int) -> tuple[np.ndarray, np.ndarray]:
    fa = analytic_frequencies_hz("clamped", "free", length=L, EI=EI, rhoA=RHOA, N=0.0, n_modes=k)
    return fa, C / (2 * RHOA * 2 * np.pi * fa)


def test_ambient_modes_are_within_their_stated_uncertainties():
    """Six records: the first four modes (21.6, 135.6, 379.6, 743.8 Hz) found in each, significant; frequencies and
    damping ratios off the truth by deviates of their jackknife uncertainties — every |z| below 5 and their spread
    within [0.6, 1.6] (24 values each; with 8 segments the deviates follow Student's t with 7 degrees of freedom,
    spread 1.18, |t| > 5 at odds 0.0016, and each stated σ is itself known to about a quarter; measured: |z| at
    most 1.9 and 3.4, spreads 0.86 and 1.11); the shape ratios of the first three modes at the two accelerometers
    within 5 of theirs of the closed-form shapes' (measured: at most 2.0).  The truth's 64 elements leave each
    frequency within a tenth of the smallest uncertainty stated for it."""
    fa, za = _truth(4)
    fe = hermite_beam(L, 64, EI=EI, rhoA=RHOA, right=(0.0, 0.0)).natural_frequencies_hz(4)
    shape_truth = [_cantilever_shape(k, np.array(SENSORS)) for k in range(3)]
    zf, zz, zs, smallest = [], [], [], np.full(4, np.inf)
    for seed in range(6):
        m = ambient_modes(_ambient(seed), DT)
        assert m.kind == "ambient" and m.frequencies_hz.size == 4, m.frequencies_hz
        assert np.all(m.significance >= SIGNIFICANCE), m.significance
        f, z, sh = deviates(m, fa, za, shape_truth)
        zf, zz, zs = zf + f, zz + z, zs + sh
        smallest = np.minimum(smallest, m.frequency_std)
    for z in (np.array(zf), np.array(zz)):
        assert np.all(np.abs(z) < 5.0) and 0.6 < np.std(z) < 1.6, np.round(z, 2)
    assert np.all(np.abs(zs) < 5.0), np.round(zs, 2)
    assert np.all(np.abs(fe - fa) < 0.1 * smallest), (fe - fa, smallest)


def test_noise_alone_shows_no_mode_and_bad_records_are_refused():
    """White noise has no significant mode; a record too short for eight segments, a NaN, a constant sensor, a
    bad interval, fewer than four segments are refused in one line."""
    rng = np.random.default_rng(7)
    assert ambient_modes(rng.standard_normal((40000, 2)), DT).frequencies_hz.size == 0
    bad = rng.standard_normal((4000, 2))
    bad[10, 1] = np.nan
    for y, dt, seg, said in ((bad, DT, SEGMENTS, "NaN"), (np.ones((4000, 1)), DT, SEGMENTS, "constant"),
                             (np.ones((100, 1)), DT, SEGMENTS, "at least 2048"),
                             (rng.standard_normal(4000), -1.0, SEGMENTS, "sample interval"),
                             (rng.standard_normal(4000), DT, 3, "4 segments")):
        with pytest.raises(DataError, match=said):
            ambient_modes(y, dt, seg)


def _record(folder: Path, seed: int) -> Path:
    """The ambient record as a CSV a DAQ writes without the force: time and the two accelerometers."""
    y = _ambient(seed)
    t = np.arange(y.shape[0]) * DT
    path = folder / "ambient.csv"
    folder.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="time,a1,a2", comments="", fmt="%.10g")
    return path


def test_identify_and_diagnose_from_an_ambient_record_alone(tmp_path):
    """``ebb identify CONFIG --ambient RECORD --out DIR`` with no record that has a force: a newcomer's config (EI
    40 % high, ρA 40 % low, the documents' thickness 5 % off as the geometry prior) — the record's four modes
    printed, √(EI/ρA) within 1 % of the truth and within 4 of its stated σ; ``ebb diagnose`` of the same: no
    effect (``none``: the truth has none).  The record's CSV names no force column: none is asked for."""
    rec = _record(tmp_path, 0)
    cfg = _config(tmp_path, None, dt=DT)
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(cfg), "--ambient", str(rec), "--out",
                        str(tmp_path / "id")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "an ambient record" in r.stderr and r.stderr.count(" Hz (ζ ") == 4, r.stderr
    doc = json.loads((tmp_path / "id" / "identified.json").read_text())
    value, std = doc["root_EI_over_rhoA"]["value"], doc["root_EI_over_rhoA"]["std"]
    truth = math.sqrt(EI / RHOA)
    assert abs(value / truth - 1.0) < 0.01 and abs(value - truth) < 4 * std, (value, std, truth)
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "diagnose", str(cfg), "--ambient", str(rec), "--out",
                        str(tmp_path / "gap")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    gap = json.loads((tmp_path / "gap" / "gap.json").read_text())
    assert gap["verdict"] == "none", r.stdout


def test_an_unreadable_ambient_record_is_refused_in_one_line(tmp_path):
    """A record without the config's sensors' columns: one line naming what is missing, exit 2, nothing written."""
    path = tmp_path / "wrong.csv"
    np.savetxt(path, np.column_stack([np.arange(5000) * DT, np.ones(5000)]), delimiter=",", header="time,b1",
               comments="")
    cfg = _config(tmp_path, None, dt=DT)
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(cfg), "--ambient", str(path), "--out",
                        str(tmp_path / "id")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "missing" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "id").exists()


def test_an_ambient_record_that_changes_is_read_per_segment():
    """An ambient record whose beam stiffens by 21 % halfway (24 s each, each part stationary), a declared channel
    stepping from 1 V to 2 V over 90 ms between them with 2.5 mV of noise: two segments, each read as an ambient
    record; the first mode followed through them rises by the truth's √1.21 = 1.1 within 4 of the two estimates'
    combined uncertainty, each within 4 of its own of the truth's."""
    first, second = _ambient(11, 24.0), _ambient(12, 24.0, 1.21 * EI)
    ramp = int(0.09 / DT)
    y = np.vstack([first, first[-1] + np.outer(np.linspace(0, 1, ramp), second[0] - first[-1]), second])
    rng = np.random.default_rng(3)
    channel = np.concatenate([np.full(first.shape[0], 1.0), np.linspace(1.0, 2.0, ramp),
                              np.full(second.shape[0], 2.0)]) + 0.0025 * rng.standard_normal(y.shape[0])
    segs = stationary_segments(channel, DT)
    assert len(segs) == 2 and [round(s.level, 2) for s in segs] == [1.0, 2.0], segs
    modes = segment_modes(y, DT, segs, kind="ambient")
    assert all(m.kind == "ambient" for m in modes)
    k = track(modes, 21.0)
    assert all(i is not None for i in k), k
    f = np.array([m.frequencies_hz[i] for m, i in zip(modes, k)])
    sd = np.array([m.frequency_std[i] for m, i in zip(modes, k)])
    fa = _truth(1)[0][0]
    assert np.all(np.abs(f - fa * np.array([1.0, 1.1])) < 4 * sd), (f, sd)
    ratio_sd = f[1] / f[0] * math.hypot(sd[0] / f[0], sd[1] / f[1])
    assert abs(f[1] / f[0] - 1.1) < 4 * ratio_sd, (f, sd)


ARTS = Path(__file__).resolve().parents[2] / "shared" / "data" / "arts-lab-cantilever" / "test_1_3200Hz.lvm"


def test_a_tone_in_the_force_is_not_a_mode():
    """The truth under the white force plus a strong 60 Hz tone (a machine nearby): the same four modes, and the
    tone apart as a line that does not decay, not a fifth mode."""
    cfg = make_config("clamped", "free", length=L, dt=DT, EI=EI, rhoA=RHOA, c=C, actuators=[("F1", 0.48)],
                      sensors=[("a1", SENSORS[0], "acceleration"), ("a2", SENSORS[1], "acceleration")])
    cfg = replace(cfg, sensors=tuple(replace(s, antialias=AntiAlias(8, 0.4 / DT)) for s in cfg.sensors))
    warm = int(WARM / DT)
    n = warm + int(SECONDS / DT)
    u = np.random.default_rng(100).standard_normal(n) + 3.0 * np.sin(2 * np.pi * 60.0 * np.arange(n) * DT)
    m = ambient_modes(synthesize(cfg, u, noise=0.01, seed=0).outputs[warm:], DT)
    fa = _truth(4)[0]
    assert m.frequencies_hz.size == 4 and np.all(np.abs(m.frequencies_hz - fa) < 5 * m.frequency_std), m
    assert m.tones_hz.size == 1 and abs(m.tones_hz[0] - 60.0) < 0.01, m.tones_hz


@pytest.mark.skipif(not ARTS.is_file(), reason="../shared/data/arts-lab-cantilever is not available")
def test_the_arts_shaker_record_read_as_ambient_holds_tones_and_no_mode(tmp_path):
    """The real bench's three-tone shaker record (CC BY-SA 4.0, read in place) through ``--ambient``: its lines at
    100, 120 and 150 Hz (and their sums) do not decay — tones, not modes — so no mode: one line saying so, exit 2,
    nothing written.  (Read as an ambient record before, the six lines were taken for six modes.)"""
    cfg = Path(__file__).resolve().parents[1] / "examples" / "arts_identify.toml"
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(cfg), "--ambient", str(ARTS), "--out",
                        str(tmp_path / "o")], capture_output=True, text=True, timeout=300)
    errors = [ln for ln in r.stderr.splitlines() if ": warning: " not in ln]
    assert r.returncode == 2 and len(errors) == 1, r.stderr
    assert "the record shows no mode (lines at 100, 120, 150," in errors[0] and "not modes" in errors[0], errors
    assert not (tmp_path / "o").exists()
