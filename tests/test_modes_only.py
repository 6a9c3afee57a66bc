"""Identification from measured natural frequencies alone (identification.modes_only): no record, no force.

Truth: the free decay of ``tests/test_output_modes.py`` — the Hermite FE cantilever of DROPBEAR's size integrated
exactly in time (converged there: its first three frequencies within 1.6e-7 of the continuous beam's, below a
tenth of the uncertainty the estimator states), read by two accelerometers under 1 % noise — whose modes the
output-only estimator gives with their uncertainties (:func:`identification.output_modes.free_decay_modes`).  The
config is a newcomer's: EI 40 % high and ρA 40 % low to start, bounds ×0.25…×4, and the strip's documents as a
geometry prior whose thickness is 5 % off.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ebb_model.io.tomlio import dumps as dumps_toml
from ebb_model.reference.analytic import analytic_frequencies_hz
from identification.modes_only import ModesOnlyError, identify_from_modes
from identification.output_modes import free_decay_modes

from test_output_modes import DT, EI, RHOA, C, L, SENSORS, _decay

WIDTH, THICKNESS = 0.051, 0.00666        # the truth's EI and ρA are steel's (E 200 GPa... ρ 7850) of this strip


def _config(folder: Path, modes, geometry: bool = True, damping_unknown: bool = True, dt: float = DT) -> Path:
    """A newcomer's config of the strip with the measured modes as ``[identification.modes]`` (none when
    ``modes`` is None), sampled at ``dt``."""
    doc = {"beam": {"length": L, "nodes": 80, "left": "clamped", "right": "free"}, "time": {"dt": dt},
           "parameters": {"EI": {"value": 1.4 * EI, "bounds": [0.25 * EI, 4 * EI], "identify": True},
                          "rhoA": {"value": 0.6 * RHOA, "bounds": [0.25 * RHOA, 4 * RHOA], "identify": True},
                          "c": {"value": 0.5, "bounds": [0.0, 40.0], "identify": damping_unknown}, "N": {"value": 0.0}},
           "actuators": [{"name": "F1", "x": 0.48}],
           "sensors": [{"name": "a1", "x": SENSORS[0], "kind": "acceleration"},
                       {"name": "a2", "x": SENSORS[1], "kind": "acceleration"}],
           "identification": {} if modes is None else {
               "modes": {"frequencies_hz": [float(v) for v in modes.frequencies_hz],
                         "std_hz": [float(v) for v in modes.std_hz]}}}
    if geometry:       # the documents: a thickness 5 % thicker than the strip's, E and ρ of a data sheet
        doc["identification"]["geometry"] = {
            "E": {"value": 200e9, "std": 10e9}, "density": {"value": 7850.0, "std": 50.0},
            "width": {"value": WIDTH, "std": 0.0002}, "thickness": {"value": 1.05 * THICKNESS, "std": 0.0004}}
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "config.toml"
    path.write_text(dumps_toml(doc), encoding="utf-8")
    return path


def test_the_root_ratio_from_a_free_decay_is_within_its_uncertainty(tmp_path):
    """Six noise realisations of the free decay: its three modes → √(EI/ρA) off the truth's by normal deviates
    (every |z| below 4 for a calibrated estimate) and within 1 % (measured: at most 9e-7 off, its σ 3.6e-7, z
    from −0.7 to 2.5 — the 80-node model's own frequency error is part of the offset); the
    model's frequencies agree with the measured (χ² below its 99.9 % point); the damping is held (the undamped
    frequencies do not depend on c) and said; the scale is said to rest on the prior."""
    truth = math.sqrt(EI / RHOA)
    z = []
    for seed in range(6):
        modes = free_decay_modes(_decay(seed), DT).modal_data()
        assert modes.count == 3
        r = identify_from_modes(_config(tmp_path / str(seed), modes), tmp_path / str(seed) / "out")
        value, std = r.root_ratio
        assert abs(value / truth - 1.0) <= 0.01, (value, truth)
        z.append((value - truth) / std)
        assert r.agreement["agrees"], r.agreement
        assert set(r.held) == {"c"} and r.from_priors == ("EI", "rhoA"), (r.held, r.from_priors)
        doc = json.loads((tmp_path / str(seed) / "out" / "identified.json").read_text())
        assert doc["std"]["c"] is None and doc["root_EI_over_rhoA"]["value"] == pytest.approx(value)
    assert np.all(np.abs(z) < 4.0), np.round(z, 2)


def test_without_a_prior_or_a_force_the_scale_is_refused_in_one_line(tmp_path):
    """No geometry, no prior_std, no record: the frequencies leave the common scale of EI and ρA free — refused
    with one line naming it (exit 2), nothing written; no measured modes and no record: one line too."""
    modes = free_decay_modes(_decay(0), DT).modal_data()
    cfg = _config(tmp_path / "a", modes, geometry=False)
    with pytest.raises(ModesOnlyError, match="common scale of EI, rhoA"):
        identify_from_modes(cfg, tmp_path / "a" / "out")
    assert not (tmp_path / "a" / "out").exists()
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(cfg), "--out", str(tmp_path / "a" / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "give [identification.geometry], a prior_std, or a record with its force" in r.stderr
    assert not (tmp_path / "a" / "o").exists()
    doc = tomllib.loads(cfg.read_text(encoding="utf-8"))
    del doc["identification"]["modes"]
    bare = tmp_path / "b" / "config.toml"
    bare.parent.mkdir()
    bare.write_text(dumps_toml(doc), encoding="utf-8")
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(bare), "--out", str(tmp_path / "b" / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "no measured natural frequencies" in r.stderr and len(r.stderr.splitlines()) == 1


def test_the_command_line_identifies_from_the_config_modes(tmp_path):
    """``ebb identify CONFIG --out DIR`` with the modes in the config and no record: exit 0, the lines a user
    reads (√(EI/ρA) with its σ, the scale resting on the prior, the damping held) and ``identified.json``."""
    modes = free_decay_modes(_decay(1), DT).modal_data()
    cfg = _config(tmp_path, modes)
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(cfg), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "√(EI/ρA) = " in r.stdout and "rests on their priors" in r.stdout and "c = 0.5 (held" in r.stdout
    doc = json.loads((tmp_path / "o" / "identified.json").read_text())
    assert abs(doc["root_EI_over_rhoA"]["value"] / math.sqrt(EI / RHOA) - 1.0) <= 0.01


def test_the_command_line_reads_a_free_decay_record(tmp_path):
    """``ebb identify CONFIG --decay RECORD --out DIR``: the free decay as a DAQ writes it (time and the two
    accelerometers, no force column), its modes printed and taken — the same √(EI/ρA) as the modes the estimator
    gives from the same samples put in the config (to 1e-9: one estimator, one fit); a record that does not exist:
    one line, exit 2, nothing written."""
    y = _decay(1)
    rec = tmp_path / "decay.csv"
    np.savetxt(rec, np.column_stack([np.arange(y.shape[0]) * DT, y]), delimiter=",", header="time,a1,a2",
               comments="", fmt="%.17g")
    bare = _config(tmp_path / "bare", None)
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(bare), "--decay", str(rec), "--out",
                        str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "(a free decay)" in r.stderr and r.stderr.count(" Hz (ζ ") == 3, r.stderr
    via_record = json.loads((tmp_path / "o" / "identified.json").read_text())["root_EI_over_rhoA"]["value"]
    direct = identify_from_modes(_config(tmp_path / "direct", free_decay_modes(y, DT).modal_data()),
                                 tmp_path / "direct" / "o").root_ratio[0]
    assert via_record == pytest.approx(direct, rel=1e-9)
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "identify", str(bare), "--decay", str(tmp_path / "none.csv"),
                        "--out", str(tmp_path / "o2")], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "o2").exists()


@pytest.mark.parametrize("damping, strength", [(2.0, 0.5), (0.5, 2.0)])
def test_a_doublet_beside_a_mode_leaves_the_root_ratio_where_it_was(tmp_path, damping, strength):
    """A second line 3 % above the strip's second mode — a torsional mode an accelerometer off the centre line
    picks up — damped twice as heavily and half as strong as the record, or half as heavily and twice as strong:
    the estimator resolves both (135.57 and 139.63 Hz), and the two are one mode's candidates
    (:data:`identification.output_modes.DOUBLET`).  From a newcomer's config (EI 40 % high, ρA 40 % low) the fit
    takes the bending member in three noise realisations each — √(EI/ρA) off the truth by a normal deviate
    (measured |z| ≤ 1.0; allowed 4) and within 1 %, the model agreeing, the other member set aside — where the same
    modes as the lowest in order leave χ² above 1e11 (measured 3.5e11 and 1.7e12) and √(EI/ρA) 9 or 37 % off."""
    from identification.modal_data import ModalData

    fa = analytic_frequencies_hz("clamped", "free", length=L, EI=EI, rhoA=RHOA, N=0.0, n_modes=3)
    truth = math.sqrt(EI / RHOA)
    w = 2 * math.pi * 1.03 * fa[1]
    zeta = damping * C / (2 * RHOA * 2 * math.pi * fa[1])
    for seed in range(3):
        y = _decay(seed).copy()
        t = np.arange(y.shape[0]) * DT
        line = np.exp(-zeta * w * t) * np.sin(w * math.sqrt(1 - zeta ** 2) * t)
        y[:, 0] += strength * np.std(y[:, 0]) * line
        y[:, 1] -= 0.6 * strength * np.std(y[:, 1]) * line
        modes = free_decay_modes(y, DT).modal_data()
        assert modes.frequencies_hz.size == 4 and modes.groups is not None and modes.count == 3, modes
        r = identify_from_modes(_config(tmp_path / str(seed), None), None, modes=modes)
        value, std = r.root_ratio
        assert abs(value - truth) < 4 * std and abs(value / truth - 1) < 0.01, (value, std, truth)
        assert r.agreement["agrees"] and len(r.agreement["aside_hz"]) == 1, r.agreement
        assert abs(r.agreement["aside_hz"][0] / (w / 2 / math.pi) - 1) < 1e-3, r.agreement
        plain = identify_from_modes(_config(tmp_path / f"{seed}p", None), None,
                                    modes=ModalData(modes.frequencies_hz, modes.std_hz))
        assert not plain.agreement["agrees"] and plain.agreement["chi2"] > 1e11, plain.agreement
