"""The diagnosed model as a product: the corrected model exported as config, StateSpace and FMU.

The StateSpace of a corrected model with a lag or a gain must reproduce the diagnosis' own simulation of that model
(:func:`diagnosis.problem.augmented.simulate_effects`, the lag applied to the signal) — the series connection is exact,
so to round-off.  The exported config reloads to the same model; the FMU runs it through fmpy.
"""
from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

import ebb_model as em
from diagnosis.problem.augmented import simulate_effects
from diagnosis.corrected.export import corrected_statespace, export_corrected
from diagnosis.effects import AugmentedModel
from diagnosis.effects.axial import AxialDrift, Stretching
from diagnosis.effects.chain import ActuatorGain, SensorGain
from diagnosis.effects.lag import ActuatorLag, SensorLag
from ebb_model.reference.excitation import band_limited_input
from ebb_model.io.tomlio import dumps
from ebb_model.modal.truncation import design_model
from identification.export_statespace import load_metadata, load_statespace

from conftest import make_config


def bench(**kw):
    return make_config("clamped", "pinned", nodes=20, dt=5e-4, EI=10.0, rhoA=1.0, c=2.0, N=20.0,
                       actuators=[("F1", 0.55)],
                       sensors=[("y1", 0.35, "displacement"), ("a2", 0.8, "acceleration")], **kw)


@pytest.mark.parametrize("input_hold", ["cubic", "foh"])
@pytest.mark.parametrize("lag", [(ActuatorLag(2e-3),), (SensorLag("a2", 1.5e-3),),
                                 (ActuatorLag(1e-3), SensorLag("y1", 3e-3)),
                                 (SensorLag("y1", 3e-3), ActuatorLag(1e-3)),
                                 (ActuatorGain(0.4),), (SensorGain("a2", 2.5),),
                                 (ActuatorGain(0.4), SensorLag("y1", 3e-3), SensorGain("y1", 1.7))])
def test_lag_statespace_equals_the_diagnosis_simulation(lag, input_hold):
    d = bench().to_dict()
    d["time"]["input"] = input_hold
    cfg = em.config_from_dict(d)
    u = band_limited_input(1200, cfg.time.dt, 2.0, 150.0, seed=3)
    u[0] = 0.3                                   # a start away from zero exercises the "at rest" convention
    model = AugmentedModel(cfg, cfg.parameter_values(), lag)
    sys = corrected_statespace(model)
    y_ref = simulate_effects(cfg, cfg.parameter_values(), u, lag)
    y = em.simulate(sys, u).outputs
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-11 * np.abs(y_ref).max())


def test_time_varying_effects_have_no_statespace():
    cfg = bench()
    assert corrected_statespace(AugmentedModel(cfg, cfg.parameter_values(), (AxialDrift(2.0),))) is None
    stretched = AugmentedModel(cfg, cfg.parameter_values(), (ActuatorLag(1e-3), Stretching(1e6)))
    assert corrected_statespace(stretched) is None


def test_config_toml_round_trips():
    for path in ("examples/seed_clamped.toml", "examples/arts_diagnose.toml"):
        cfg = em.load_config(path, extra_sections=("identification",))
        back = em.config_from_dict(tomllib.loads(dumps(cfg.to_dict())), extra_sections=("identification",))
        assert back.to_dict() == cfg.to_dict()
    d = bench().to_dict()
    d["beam"]["left_kr"] = float("inf")
    assert tomllib.loads(dumps(d))["beam"]["left_kr"] == float("inf")


def test_export_writes_config_statespace_and_fmu(tmp_path):
    """A structural effect (point mass) plus a refitted baseline: every file, consistent with each other."""
    from dataclasses import replace

    from ebb_model.beam import PointMass

    base = bench()
    cfg = replace(base, masses=(PointMass("effect_mass", 0.6, 0.05),))
    params = base.parameter_values() | {"EI": 10.3, "N": 19.0}
    summary = {"effect": "point_mass", "effect_parameters": {"mass": {"value": 0.05, "unit": "kg"}}}
    files = export_corrected(AugmentedModel(cfg, params), tmp_path / "corrected", summary)
    assert sorted(f.name for f in files) == ["corrected.fmu", "corrected.json", "corrected.npz", "corrected.toml"]
    reloaded = em.load_config(tmp_path / "corrected" / "corrected.toml")
    assert reloaded.parameter_values()["EI"] == 10.3 and reloaded.masses == cfg.masses
    u = band_limited_input(800, cfg.time.dt, 2.0, 150.0, seed=4)
    y_cfg = em.simulate(em.assemble(reloaded), u).outputs
    sys = load_statespace(tmp_path / "corrected" / "corrected.npz")
    assert sys.name == "corrected"
    meta = load_metadata(tmp_path / "corrected" / "corrected.npz")
    assert meta["parameters"]["EI"] == 10.3 and meta["units"]["EI"] == "N.m2"
    assert meta["signal_units"] == {"F1": "N", "y1": "m", "a2": "m/s2"}
    # the StateSpace is the design model (modes up to Nyquist, the rest a static correction), the FMU the whole beam
    design = design_model(reloaded)
    y_npz = em.simulate(em.DiscreteStateSpace(sys.A, sys.B, sys.C, sys.D, sys.dt, hold=design.hold), u).outputs
    np.testing.assert_allclose(y_npz, em.simulate(design, u).outputs, rtol=0, atol=1e-12 * np.abs(y_cfg).max())
    assert sys.nstates == design.nstates < em.assemble(reloaded).nstates
    doc = json.loads((tmp_path / "corrected" / "corrected.json").read_text())
    assert doc["effect"] == "point_mass" and "corrected.fmu" in doc["files"]
    from fmpy import read_model_description

    md = read_model_description(str(tmp_path / "corrected" / "corrected.fmu"))
    start = {v.name: v.start for v in md.modelVariables}
    assert float(start["EI"]) == 10.3 and float(start["N"]) == 19.0
