"""What the user knows before the data (:mod:`identification.prior`): priors in the config, the posterior fit,
what moved each parameter, a wrong prior reported as a conflict — and refits that need implausible values never
named (:mod:`diagnosis.problem.plausibility`)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ebb_cli import main
from ebb_model.config import config_from_dict
from ebb_model.errors import ConfigError
from identification.prior import CONFLICT_SIGMA, Prior, PriorCheck

from test_diagnose_cli import _toml
from test_diagnosis_blind import TRUTH, bench_config
from test_noise_model import truth_config, truth_records


def _with(d: dict, **params: dict) -> dict:
    d = json.loads(json.dumps(d))
    for k, v in params.items():
        d["parameters"][k].update(v)
    return d


def test_a_prior_is_read_checked_and_written_back():
    d = _with(bench_config().to_dict(), EI={"prior_std": 0.5})
    cfg = config_from_dict(d, extra_sections=("identification",))
    assert cfg.parameters["EI"].prior_std == 0.5 and cfg.parameters["rhoA"].prior_std is None
    assert config_from_dict(cfg.to_dict(), extra_sections=("identification",)).parameters["EI"].prior_std == 0.5
    with pytest.raises(ConfigError, match=r"parameters.EI.prior_std: must be > 0"):
        config_from_dict(_with(d, EI={"prior_std": -1.0}), extra_sections=("identification",))
    with pytest.raises(ConfigError, match=r"parameters.N.prior_std: a prior belongs to an identified parameter"):
        config_from_dict(_with(d, N={"prior_std": 1.0, "identify": False}), extra_sections=("identification",))
    with pytest.raises(ConfigError, match=r"prior_std: must be a finite number"):
        config_from_dict(_with(d, EI={"prior_std": float("nan")}), extra_sections=("identification",))


def test_the_checks_say_what_moved_each_parameter():
    # posterior σ a tenth of the prior's: the data; nearly the prior's: the prior; 4 σ away: a conflict
    assert PriorCheck("EI", 10.0, 1.0, 10.5, 0.1).status == "data"
    assert PriorCheck("EI", 10.0, 1.0, 10.5, 0.95).status == "prior"
    assert PriorCheck("EI", 10.0, 1.0, 10.5, 0.7).status == "shared"
    c = PriorCheck("EI", 10.0, 1.0, 10.0 - (CONFLICT_SIGMA + 1.0), 0.1)
    assert c.status == "conflict" and "4.0 σ from the prior" in c.line() and "-40%" in c.line()
    p = Prior(("EI", "x_F1"), np.array([10.0, 0.0]), np.array([2.0, math.inf]))
    assert p.count == 1
    np.testing.assert_allclose(p.residuals(np.array([13.0, 0.3])), [1.5])
    # the posterior of a parameter the data say nothing about is its prior
    np.testing.assert_allclose(p.posterior_std(np.diag([0.0, 1.0]), np.array([10.0, 1.0])), [2.0, 1.0])


#: A steel strip with tolerances as a calliper and a data sheet give them (relative: 2.5 %, 0.6 %, 0.4 %, 2 %).
STRIP = {"E": {"value": 200e9, "std": 5e9}, "density": {"value": 7850.0, "std": 50.0},
         "width": {"value": 0.05, "std": 2e-4}, "thickness": {"value": 4.5e-3, "std": 9e-5}}


def _geometry_config(geometry, **params):
    d = _with(bench_config().to_dict(), **params)
    d["identification"] = {"geometry": geometry}
    return config_from_dict(d, extra_sections=("identification",))


def test_a_section_gives_ei_and_rhoa_a_correlated_prior():
    """[identification.geometry] → the prior on (EI, ρA): its mean E w t³/12, ρ w t and its covariance against
    200,000 draws of the four quantities (an independent Monte-Carlo propagation, GUM supplement 1).  Budget: the
    sample covariance's own scatter (√(2/n) ≈ 0.3 % relative) plus the first-order propagation's neglect of the
    cube's curvature (3 u_t² ≈ 0.1 % of the mean, ~1 % of the variance at u_t = 2 %)."""
    from identification.geometry import geometry_prior

    cfg = _geometry_config(STRIP)
    sec = geometry_prior(cfg)
    v = {k: q["value"] for k, q in STRIP.items()}
    np.testing.assert_allclose(sec.mean, [v["E"] * v["width"] * v["thickness"] ** 3 / 12.0,
                                          v["density"] * v["width"] * v["thickness"]], rtol=1e-12)
    rng = np.random.default_rng(5)
    draw = {k: q["value"] + q["std"] * rng.standard_normal(200_000) for k, q in STRIP.items()}
    mc = np.cov(np.stack([draw["E"] * draw["width"] * draw["thickness"] ** 3 / 12.0,
                          draw["density"] * draw["width"] * draw["thickness"]]))
    np.testing.assert_allclose(sec.cov, mc, rtol=0.03)
    # a thicker strip is stiffer and heavier: strongly correlated, (u_w² + 3u_t²)/(u_EI u_ρA) = 0.874
    u = {k: q["std"] / q["value"] for k, q in STRIP.items()}
    rho = sec.cov[0, 1] / np.sqrt(sec.cov[0, 0] * sec.cov[1, 1])
    assert rho == pytest.approx((u["width"] ** 2 + 3 * u["thickness"] ** 2) / math.sqrt(
        (u["E"] ** 2 + u["width"] ** 2 + 9 * u["thickness"] ** 2)
        * (u["density"] ** 2 + u["width"] ** 2 + u["thickness"] ** 2)), rel=1e-12)
    assert rho == pytest.approx(mc[0, 1] / np.sqrt(mc[0, 0] * mc[1, 1]), abs=0.01)
    # the Prior whitens with the correlation: its residuals' squares are the Mahalanobis distance
    prior = Prior.of(cfg, ("EI", "rhoA", "c", "N"))
    assert prior.count == 2 and prior.sources[0].startswith("geometry")
    x = np.array([sec.mean[0] * 1.1, sec.mean[1] * 0.97, 2.0, 20.0])
    d = x[:2] - sec.mean
    np.testing.assert_allclose(prior.residuals(x) @ prior.residuals(x), d @ np.linalg.solve(sec.cov, d), rtol=1e-10)
    # and its information (relative units) is Σ⁻¹ scaled; the evidence's normaliser is the Gaussian's
    scales = np.array([10.0, 1.0, 2.0, 20.0])
    info = prior.information(scales)
    np.testing.assert_allclose(info[:2, :2], np.linalg.inv(sec.cov) * np.outer(scales[:2], scales[:2]), rtol=1e-10)
    assert np.all(info[2:] == 0.0)
    assert prior.log_det_corr() == pytest.approx(math.log(1.0 - rho ** 2), rel=1e-10)
    # each within its own prior, but not in the ratio the section allows: a joint conflict, said
    sd = np.sqrt(np.diag(sec.cov))
    off = np.array([sec.mean[0] - 1.5 * sd[0], sec.mean[1] + 1.5 * sd[1], 2.0, 20.0])
    checks = prior.judge(off, np.array([0.1, 0.01, 1.0, 1.0]))
    assert [c.status for c in checks[:2]] == ["data", "data"]
    assert checks[2].joint and checks[2].name == "EI+rhoA" and checks[2].status == "conflict", checks[2].line()
    assert "together" in checks[2].line() and checks[2].to_dict()["posterior_std"] is None
    along = np.array([sec.mean[0] + sd[0], sec.mean[1] + sd[1], 2.0, 20.0])    # a thicker strip: 1 σ each, together
    assert prior.judge(along, np.ones(4))[2].status == "consistent"


def test_a_section_table_with_problems_names_each_at_load(tmp_path):
    """Every problem of the table at once, one line each, when the config is loaded (not after a GA run)."""
    from identification.config_file import load_identification_config

    bad = {"E": {"value": -1.0, "std": 1.0}, "width": {"value": 0.05}, "thickness": STRIP["thickness"],
           "colour": {"value": 1.0, "std": 0.0}}
    cfg = _geometry_config(bad, EI={"prior_std": 1.0})
    table = "\n".join(f"{k} = {{ " + ", ".join(f"{kk} = {vv!r}" for kk, vv in q.items()) + " }" for k, q in bad.items())
    (tmp_path / "c.toml").write_text(_toml(cfg) + "[identification.geometry]\n" + table + "\n")
    with pytest.raises(ConfigError) as err:
        load_identification_config(tmp_path / "c.toml")
    msg = str(err.value)
    for part in ("identification.geometry.colour: unknown quantity", "identification.geometry.density: missing",
                 "identification.geometry.E: must be { value = <number > 0> Pa", "identification.geometry.width",
                 "parameters.EI has a prior_std of its own"):
        assert part in msg, msg
    only_t = {k: {"value": q["value"], "std": 0.0} for k, q in STRIP.items()} | {"thickness": STRIP["thickness"]}
    with pytest.raises(ConfigError, match="would be known exactly"):
        Prior.of(_geometry_config(only_t), ("EI", "rhoA"))


def test_a_wrong_prior_is_reported_as_a_conflict_not_hidden(tmp_path):
    """A record of the bench at its truth (EI 10), a config whose prior says EI 13 ± 0.5 (30 % off, tight):
    the data win (EI within 1 % of the truth), ``gap.json`` reports the prior conflict (≈ 6 σ), and the verdict
    stays ``none`` — the model at the truth explains the record."""
    cfg = truth_config(EI={"value": 13.0, "prior_std": 0.5})
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = truth_records(tmp_path, cfg)
    out = tmp_path / "gap"
    assert main(["diagnose", str(tmp_path / "bench.toml"), str(files[0]), "--holdout", str(files[1]), "--out",
                 str(out), "--quiet", "--no-plots", "--workers", "1"]) == 0
    doc = json.loads((out / "gap.json").read_text())
    ei = doc["baseline"]["priors"]["EI"]
    assert ei["status"] == "conflict" and ei["z"] < -CONFLICT_SIGMA, ei
    assert abs(doc["baseline"]["parameters"]["EI"] / TRUTH["EI"] - 1.0) < 0.01
    assert doc["verdict"] == "none", doc["reason"]
    assert "prior conflict" in doc["reason"].lower()


def test_identify_reports_what_moved_each_parameter(tmp_path):
    """``identify`` with a prior on EI 30 % off the truth (13 ± 0.5), a loose one on N, and the truth's three
    lowest modes as measured data: the data decide EI (within 1 % of the truth; ``conflict`` reported, ≈ 6 σ),
    N's prior is loose and the data determine it, and the identified model agrees with the measured modes."""
    from identification.run import identify

    cfg = truth_config(EI={"value": 13.0, "prior_std": 0.5}, N={"prior_std": 50.0})
    # the truth's three lowest modes, measured to 0.3 %, as data of another kind
    from ebb_model.modal.modal import discrete_frequencies

    f_true = discrete_frequencies(cfg, TRUTH, 3)[0][:3]
    (tmp_path / "bench.toml").write_text(_toml(cfg) + "[identification.modes]\nfrequencies_hz = "
                                         + json.dumps([float(v) for v in f_true]) + "\nstd_hz = "
                                         + json.dumps([float(0.003 * v) for v in f_true]) + "\n")
    res = identify(tmp_path / "bench.toml", truth_records(tmp_path, cfg, seeds=(41,)), tmp_path / "out", pop=8,
                   generations=2, progress=False, export=False)
    checks = {c.name: c for c in res.priors}
    assert checks["EI"].status == "conflict" and checks["EI"].z < -CONFLICT_SIGMA
    assert abs(res.best["EI"] / TRUTH["EI"] - 1.0) < 0.01
    assert checks["N"].status == "data"
    doc = json.loads((tmp_path / "out" / "pareto.json").read_text())
    assert doc["identified"]["priors"]["EI"]["status"] == "conflict"
    assert doc["identified"]["against_measured_modes"]["agrees"]


@pytest.mark.parametrize("with_prior", [True, False], ids=["prior", "no-prior"])
def test_a_gain_error_is_named_when_a_prior_breaks_the_degeneracy(tmp_path, with_prior):
    """The load cell reads 25 % high (actuator gain 0.8).  Every receptance scales with 1/(EI, rhoA, c, N):
    without priors the baseline absorbs the gain (the records at the noise floor, EI 25 % high) — verdict
    ``none``, and the report says the gain cannot be told from the beam's scale; with priors on EI and rhoA (the
    truth ± 3 %) the baseline conflicts with them and ``actuator_gain`` — 0.8 within 1 % — is named."""
    cfg = truth_config(**({"EI": {"prior_std": 0.03 * TRUTH["EI"]}, "rhoA": {"prior_std": 0.03 * TRUTH["rhoA"]}}
                          if with_prior else {}))
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = truth_records(tmp_path, cfg, gain=0.8)
    out = tmp_path / "gap"
    assert main(["diagnose", str(tmp_path / "bench.toml"), str(files[0]), "--holdout", str(files[1]), "--out",
                 str(out), "--quiet", "--no-plots", "--workers", "1"]) == 0
    doc = json.loads((out / "gap.json").read_text())
    if with_prior:
        assert doc["verdict"] == "actuator_gain", doc["reason"]
        gain = doc["effects"][[e["label"] for e in doc["effects"]].index("actuator_gain")]["refit"]
        # the priors are centred on the truth, so the valley's best point is the truth's scale: 1 % (measured 0.1 %)
        assert abs(gain["effect_parameters"]["gain"] / 0.8 - 1.0) < 0.01, gain
    else:
        assert doc["verdict"] == "none", doc["reason"]
        assert "actuator_gain" in doc["indistinguishable"] and "cannot tell a gain error" in doc["reason"]
        assert abs(doc["baseline"]["parameters"]["EI"] / (TRUTH["EI"] / 0.8) - 1.0) < 0.01


def test_measured_modes_in_the_config_are_checked():
    """``[identification.modes]``: every problem named at once, one line each; a good table is read."""
    from identification.modal_data import modal_data

    def cfg_with(table):
        d = bench_config().to_dict()
        d["identification"] = {"modes": table}
        return config_from_dict(d, extra_sections=("identification",))

    with pytest.raises(ConfigError) as err:
        modal_data(cfg_with({"frequencies_hz": [5.0, 4.0], "std_hz": [0.1, 0.0, 1.0], "colour": 1}))
    msg = str(err.value)
    for part in ("identification.modes.colour: unknown key", "2 frequencies but 3 uncertainties",
                 "must be > 0 and increasing", "every uncertainty must be > 0"):
        assert part in msg, msg
    with pytest.raises(ConfigError, match="frequencies_hz: must be a non-empty list of finite numbers"):
        modal_data(cfg_with({"frequencies_hz": [float("nan")], "std_hz": [0.1]}))
    table = modal_data(cfg_with({"frequencies_hz": [5.0, 30.0], "std_hz": [0.1, 0.3]}))
    assert table is not None and table.count == 2 and modal_data(bench_config()) is None
    for groups in ([0, 2], [1, 1], [0], [0, 0.5], "01", [0, -1]):
        with pytest.raises(ConfigError, match="identification.modes.groups: one integer per frequency"):
            modal_data(cfg_with({"frequencies_hz": [5.0, 30.0], "std_hz": [0.1, 0.3], "groups": groups}))
    with pytest.raises(ConfigError) as err:       # a bad frequency list beside groups: both named, no crash
        modal_data(cfg_with({"frequencies_hz": 5.0, "std_hz": [0.1], "groups": [0]}))
    assert "frequencies_hz: must be a non-empty list" in str(err.value), err.value
    # a doublet: 30 and 31 Hz one mode's candidates, the model's second mode compared with the nearer; the table
    # goes into a config and back unchanged
    from identification.modal_data import with_modes

    table = modal_data(cfg_with({"frequencies_hz": [5.0, 30.0, 31.0], "std_hz": [0.1, 0.3, 0.3], "groups": [0, 1, 1]}))
    assert table is not None and table.count == 2
    assert table.compared_with(np.array([5.0, 30.9])).tolist() == [0, 2]
    assert table.compared_with(np.array([5.0, 30.2])).tolist() == [0, 1]
    assert [c.frequencies_hz.tolist() for c in table.choices()] == [[5.0, 30.0], [5.0, 31.0]]
    again = modal_data(with_modes(bench_config(), table))
    assert again is not None and again.groups.tolist() == [0, 1, 1]
