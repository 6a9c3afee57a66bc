"""The examples of issue 4 run end to end (``--quick``) and show what they claim.

Each example runs as a subprocess, as a user would run it; the assertions
re-derive the claims from the files it wrote (``pareto.json``,
``identifiability.json``) with the model's own stability machinery, rather
than trusting the example's printed verdicts.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ebb_model as em
from identification.objectives import nrmse
from identification.run import load_identification_config, read_data

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
ARTS_DATA = ROOT.parent / "shared" / "data" / "arts-lab-cantilever" / "test_1_3200Hz.lvm"


def run_example(name: str, out: Path, *args: str, timeout: float = 300) -> str:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, str(EXAMPLES / name), "--quick", "--out", str(out), *args],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def test_seed_undamped_stability_objective_removes_marginal_sets(tmp_path):
    stdout = run_example("seed_undamped.py", tmp_path)
    assert "without_stability" in stdout and "with_stability" in stdout
    cfg = load_identification_config(EXAMPLES / "seed_undamped.toml")
    # the time step makes part of the search box unstable (explicit-leaning theta = 1/12) ...
    assert em.max_growth_factor(cfg, {"EI": 20.0, "rhoA": 0.5}) > 1.0
    # ... but not the truth (undamped: exactly on the unit circle)
    assert em.max_growth_factor(cfg, {"EI": 10.0, "rhoA": 1.0, "N": 50.0, "c": 0.0}) == pytest.approx(1.0, abs=1e-12)

    without = json.loads((tmp_path / "without_stability" / "pareto.json").read_text())
    with_ = json.loads((tmp_path / "with_stability" / "pareto.json").read_text())
    assert without["objective_names"] == ["nrmse_y1"]
    assert with_["objective_names"] == ["nrmse_y1", "growth_factor"]

    # without the stabilising objective: the output-error optimum is undamped, i.e. marginal
    opt = without["polished"][0]["parameters"]
    assert opt["c"] < 0.02
    g_opt = em.max_growth_factor(cfg, opt)
    assert g_opt > 1.0 - 1e-6
    # ... and it fits the data well (the fit is not the problem, the margin is)
    assert without["polished"][0]["objectives"]["nrmse_y1"] < 0.05

    # with it: the knee is strictly stable (grid and finite beam) and no front point is unstable
    knee = with_["points"][with_["knee"]]["parameters"]
    g_knee = em.max_growth_factor(cfg, knee)
    assert g_knee < 1.0 - 1e-6
    assert em.fast_model(cfg, cfg.parameter_values() | knee).spectral_radius() < 1.0
    assert all(em.max_growth_factor(cfg, p["parameters"]) <= 1.0 for p in with_["points"])
    # the stability objective is genuinely traded: its front spans a range of growth factors
    g = [p["objectives"]["growth_factor"] for p in with_["points"]]
    assert max(g) - min(g) > 1e-6


def test_seed_two_sensors_recovers_the_truth_with_cramer_rao_bounds(tmp_path):
    run_example("seed_two_sensors.py", tmp_path)
    doc = json.loads((tmp_path / "identify" / "pareto.json").read_text())
    assert doc["objective_names"] == ["nrmse_y1", "nrmse_y2", "growth_factor"]
    pol = doc["polished"][0]
    p, sd = pol["parameters"], pol["cramer_rao_std"]
    truth = {"EI": 10.0, "rhoA": 1.0, "N": 50.0, "c": 0.5}
    rel = {k: abs(p[k] / v - 1) for k, v in truth.items()}
    # tolerances: EI, rhoA 1 %; N 1.5 % (the finite-difference grid biases N by ~0.9 %, measured by
    # refinement); c 10 %
    assert rel["EI"] < 0.01 and rel["rhoA"] < 0.01 and rel["N"] < 0.015 and rel["c"] < 0.10, rel
    assert all(0 < sd[k] < np.inf for k in truth)
    # the noise the Cramér–Rao bounds use is estimated from the data: within 10 % of the true level
    summary = json.loads((tmp_path / "summary.json").read_text())
    np.testing.assert_allclose(summary["estimated_noise_std"], summary["true_noise_std"], rtol=0.1)
    assert pol["stable"]


@pytest.mark.skipif(not ARTS_DATA.is_file(), reason="ARTS-Lab record not available")
def test_arts_identification_reports_identifiability_and_improves_the_fit(tmp_path):
    run_example("arts_identify.py", tmp_path, str(ARTS_DATA))
    ident = json.loads((tmp_path / "identify" / "identifiability.json").read_text())
    assert ident["parameters"] == ["EI", "rhoA", "c", "eta", "x_force", "x_accel"]
    assert ident["condition_number"] > 1e4          # three tones, one sensor: ill-conditioned
    doc = json.loads((tmp_path / "identify" / "pareto.json").read_text())
    # the nominal model's NRMSE, computed here from the data and the config
    cfg = load_identification_config(EXAMPLES / "arts_identify.toml")
    exp = read_data(cfg, [ARTS_DATA])[0]
    y_nom = em.simulate(em.fast_model(cfg), np.asarray(exp.inputs)).outputs
    e_nom = nrmse(y_nom, np.asarray(exp.outputs))[0]
    e_knee = doc["points"][doc["knee"]]["objectives"]["nrmse_accel"]
    e_pol = doc["polished"][0]["objectives"]["nrmse_accel"]
    assert e_knee < 0.5 * e_nom and e_pol <= e_knee
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["reciprocity_difference"] < 1e-9   # swapping the transducers changes nothing


@pytest.mark.skipif(not ARTS_DATA.is_file(), reason="ARTS-Lab record not available")
def test_arts_diagnosis_names_nothing_implausible_and_says_what_would_decide(tmp_path):
    # (184 s alone on 2 cores: the search runs again with the set-ups apart and the sign is weighed with the refits;
    # beside the rest of the suite it took more than 300 s)
    stdout = run_example("arts_diagnose.py", tmp_path, str(ARTS_DATA), timeout=900)
    s = json.loads((tmp_path / "summary.json").read_text())
    # the impulse test's peaks are the natural frequencies its README documents
    # (6.62-6.66, 41.3-41.4, 117.5 and about 230 Hz), found without being told them
    modes = s["impulse_modes_hz"]
    assert len(modes) >= 4
    np.testing.assert_allclose(modes[:4], [6.64, 41.35, 117.5, 230.0], rtol=0.012)
    # ... and the measured modes the diagnosis fits are those peaks, picked by the tool (not typed in a config)
    fitted = s["against_measured_modes"]["none"]["measured_hz"]
    np.testing.assert_allclose(fitted, modes[:4], rtol=1e-12)
    # the load cell's sign, read as recorded, is found reversed by the evidence (its preload is a compression)
    assert s["force_sign"]["reversed"] and s["force_sign"]["decided"]
    # EI and rhoA's prior is the section's (two documented thicknesses), correlated through the thickness
    assert {p["source"].split(" ")[0] for p in s["baseline_priors"].values()} == {"geometry"}
    # the configured in-band noise is what adjacent periods of the filtered record give
    assert s["noise_std_adjacent_periods"] == pytest.approx(s["noise_std_config"], rel=0.05)
    # a real gap: far above the noise floor even after band limitation
    assert s["baseline"]["heldout"] > 25.0
    assert (tmp_path / "gap" / "gap.json").is_file()
    # every refit is compared with the impulse test, and the report says which survive
    assert s["refits"] and all(len(r["modes"]["relative_error"]) >= 3 for r in s["refits"])
    # nothing implausible is named or exported: the point mass of 2-3x the beam on the accelerometer (what the
    # share-of-the-gap rule exported before) is flagged, and whatever is exported passes every check
    assert "point_mass" in s["implausible"]
    assert s["verdict"] not in s["implausible"]
    if s["exported"]:
        assert s["against_measured_modes"][s["verdict"]]["agrees"]
    else:
        assert s["verdict"] in ("unexplained", "none", "indistinguishable")
    assert "what would decide it" in stdout
    # every refit that closes the record's gap misfits the impulse test: the two are tried as two set-ups (the
    # impulse test without the shaker), and that reading is adopted only when it names something plausible
    apart = s["setups_apart"]
    assert apart is not None and "shaker" in apart["modes_without"], apart
    assert apart["adopted"] == (s["verdict"] == apart["verdict"] and s["verdict"] not in s["implausible"]
                                and s["verdict"] not in ("unexplained", "none", "indistinguishable"))
    assert "one set-up or two" in stdout
    # nothing plausible: the next record is designed between the refits that close the gap (each implausible),
    # so that "what would decide it" is a computed plan, not only advice
    nxt = s["next_experiment"]
    if s["verdict"] == "unexplained":
        closes = {r["label"]: r["closed"] for r in s["refits"]}
        assert nxt is not None and len(nxt["candidates"]) >= 2, nxt
        assert all(closes[c] >= 0.8 for c in nxt["candidates"]), (nxt["candidates"], closes)
        if nxt["plausible_readings"]:
            # two or more plausible readings: the design separates those, none of them implausible
            assert nxt["implausible"] == [] and nxt["candidates"] == list(dict.fromkeys(
                r["effect"] for r in s["plausible_readings"]))[:len(nxt["candidates"])], nxt
        else:
            assert set(nxt["implausible"]) == set(nxt["candidates"]) & set(s["implausible"]), nxt
        assert nxt["best"]["expected_log_bayes_factor"] > nxt["decisive_log_odds"], nxt["best"]
        assert "next experiment to separate" in stdout
    # held within plausibility (the priors, the impulse test's modes and the effects' ranges as limits), the refits
    # that close the gap leave plausible readings: each within what the two documented thicknesses (4.19 and
    # 5.14 mm) allow, its modes agreeing with the impulse test, predicting the held-out part within 10 % (measured:
    # the chain's gain 0.34 — the load cell's or the accelerometer's, tied 0.51 / 0.49 — the strip 4.65 mm thick
    # from EI and 4.74 mm from rhoA, 3.0 % held-out NRMSE, 98 % of the gap closed)
    held = s["plausible_readings"]
    if s["verdict"] == "unexplained":
        assert held, "no plausible reading"
    for r in held:
        assert 4.19 <= r["thickness_mm"]["from_EI"] <= 5.14 and 4.19 <= r["thickness_mm"]["from_rhoA"] <= 5.14, r
        assert r["heldout_nrmse"] < 0.10 and r["closed"] >= 0.8, r
        assert r["modes_chi2"] <= s["against_measured_modes"]["none"]["chi2_limit"], r
        assert "held within plausibility" in stdout
    if held:
        assert sum(r["probability"] for r in held) == pytest.approx(1.0)
        assert "Held within plausibility" in (tmp_path / "gap" / "report.html").read_text()
    for r in s["refits"]:
        worse = r["modes"]["max_abs_error"] > s["baseline"]["modes"]["max_abs_error"] + 0.01
        assert (r["label"] in s["consistent_with_impulse_test"]) == (not worse and r["closed"] >= 0.5)
