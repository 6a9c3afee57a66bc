"""The effects catalogue as a registry: its families, and a new signal-level effect added in one place.

The diagnosis names no effect outside ``diagnosis/effects/``: the simulation, the pairs and the corrected
model's StateSpace ask each signal part what it does.  A calibration error of one sensor (a gain), written
here as a user would write a new module, runs through all of them with no other code.
"""
from __future__ import annotations


import numpy as np
import pytest

import ebb_model as em
from diagnosis.augmented import simulate_effects
from diagnosis.corrected import corrected_statespace
from diagnosis.effects import (EFFECT_NAMES, FAMILIES, AugmentedModel, Scales, candidate_effects,
                               pair_effect, signal_effect)
from diagnosis.effects.chain import SensorGain
from diagnosis.effects.lag import ActuatorLag, first_order_lag
from ebb_model.reference.excitation import band_limited_input

from conftest import make_config


def bench(left: str = "clamped", right: str = "pinned"):
    return make_config(left, right, nodes=20, dt=5e-4, EI=10.0, rhoA=1.0, c=2.0, N=20.0,
                       actuators=[("F1", 0.55)],
                       sensors=[("y1", 0.35, "displacement"), ("a2", 0.8, "acceleration")])


SCALES = Scales(EI=10.0, rhoA=1.0, N=20.0, length=1.0, omega_low=20.0, omega_high=900.0, duration=0.6,
                stretch_max=1e-6)


def test_families_build_the_catalogue_in_report_order():
    labels = [e.label for e in candidate_effects(bench("clamped", "clamped"), SCALES)]
    assert labels == ["boundary_rotational_left", "boundary_translational_left", "boundary_rotational_right",
                      "boundary_translational_right", "point_mass", "transducer_mass[y1]",
                      "transducer_mass[a2]", "grounded_spring", "shaker_armature[F1]", "stiffness_loss",
                      "kelvin_voigt", "rotary_inertia",
                      "foundation", "actuator_lag", "sensor_lag[y1]", "sensor_lag[a2]", "actuator_gain",
                      "sensor_gain[y1]", "sensor_gain[a2]", "axial_drift", "geometric_stiffening"]
    assert {e.name for e in candidate_effects(bench("clamped", "clamped"), SCALES)} == set(EFFECT_NAMES)
    assert len(EFFECT_NAMES) == len(set(EFFECT_NAMES)) == 18 and len(FAMILIES) == 9
    # an identified parameter is no candidate; stretching needs both ends axially fixed
    free = [e.label for e in candidate_effects(bench("clamped", "free"), SCALES, identified=("eta",))]
    assert "kelvin_voigt" not in free and "geometric_stiffening" not in free and "axial_drift" in free


def test_every_effect_is_the_baseline_when_off():
    cfg = bench("clamped", "clamped")
    params = cfg.parameter_values()
    for effect in candidate_effects(cfg, SCALES):
        model = effect.apply(cfg, params, np.array(effect.off))
        assert model.config == cfg and model.params == params and model.signals == (), effect.label


def test_a_new_signal_effect_needs_no_other_code():
    cfg = bench()
    params = cfg.parameter_values()
    u = band_limited_input(1200, cfg.time.dt, 2.0, 150.0, seed=5)
    gain = signal_effect("sensor_gain", "a2", "gain", (0.5, 2.0), 1.0, "gain error of sensor a2",
                         lambda g: SensorGain("a2", g), "gain", "1")
    lag = ActuatorLag(1.5e-3)
    both = pair_effect(signal_effect("actuator_lag", None, "tau", (0.0, 1e-2), 0.0, "lag", ActuatorLag, "tau", "s"),
                       gain)
    model = both.apply(cfg, params, np.array([lag.tau, 1.1]))
    assert model.signals == (lag, SensorGain("a2", 1.1)) and model.time_invariant
    assert both.physical(np.array([lag.tau, 1.1])) == {"actuator_lag.tau": lag.tau, "sensor_gain[a2].gain": 1.1}

    # the simulation: lag on the inputs, the beam, the gain on a2 (composed by hand here)
    y = simulate_effects(model.config, model.params, u, model.signals)
    beam = em.simulate(em.assemble(cfg), first_order_lag(u, cfg.time.dt, lag.tau)).outputs
    np.testing.assert_allclose(y[:, 0], beam[:, 0], rtol=0, atol=1e-12 * np.abs(beam[:, 0]).max())
    np.testing.assert_allclose(y[:, 1], 1.1 * beam[:, 1], rtol=0, atol=1e-12 * np.abs(beam[:, 1]).max())

    # the corrected model's StateSpace: both parts in series, equal to the simulation to round-off
    sys = corrected_statespace(model)
    assert sys.nstates == em.assemble(cfg).nstates + 1          # the lag's state; the gain has none
    y_sys = em.simulate(sys, u).outputs
    assert np.max(np.abs(y_sys - y) / np.abs(y).max(axis=0)) < 1e-11


def test_axial_terms_add_and_end_time_invariance():
    from diagnosis.effects.axial import AxialDrift, Stretching

    model = AugmentedModel(bench(), {}, (AxialDrift(2.0), ActuatorLag(1e-3), Stretching(5e5), AxialDrift(-0.5)))
    assert (model.axial.rate, model.axial.EA) == (1.5, 5e5)
    assert not model.time_invariant and corrected_statespace(model) is None
    with pytest.raises(em.ParameterError, match="geometric_stiffening.EA"):
        Stretching(-1.0)


def sensor_gain_candidates(config, scales: Scales, identified: tuple[str, ...]):
    """The new family's builder, as its module would define it: one gain error per sensor (off: 1)."""
    return tuple(signal_effect("sensor_gain", s.name, "gain", (0.5, 2.0), 1.0, f"gain error of sensor {s.name}",
                               lambda g, name=s.name: SensorGain(name, g), "gain", "1")
                 for s in config.sensors)


def test_diagnose_names_and_exports_an_effect_added_the_documented_way(tmp_path, monkeypatch, capsys):
    """A new family — its module (above) and its registry line (``FAMILIES``) — is named by ``ebb diagnose``
    and exported as the corrected model, its units from the effect itself (not from the data generator).

    The record: the independent FE generator with no withheld effect, then sensor ``y2`` read 15 % high (a
    calibration error, applied to the generated readings as a miscalibrated sensor does).
    """
    import json

    import diagnosis.effects as catalogue
    from ebb_cli import main
    from ebb_model.reference.synthetic import synthesize
    from test_diagnose_cli import _toml
    from test_diagnosis_blind import DT, bench_config

    from diagnosis.effects.base import Family

    # the built-in measurement-chain family replaced by this test's own module-to-be
    mine = tuple(f for f in FAMILIES if "sensor_gain" not in f.names)
    monkeypatch.setattr(catalogue, "FAMILIES", mine + (Family(("sensor_gain",), sensor_gain_candidates),))
    cfg = bench_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = []
    for seed in (31, 32):
        u = band_limited_input(3000, DT, 2.0, 60.0, seed=seed)
        rec = synthesize(cfg, u, noise=0.01, seed=seed)
        path = tmp_path / f"rec{seed}.csv"
        rec.to_csv(path)
        lines = path.read_text().splitlines()
        header = lines[0].split(",")
        k = header.index("y2")
        rows = [[float(v) for v in line.split(",")] for line in lines[1:]]
        for r in rows:
            r[k] *= 1.15
        path.write_text("\n".join([lines[0]] + [",".join(repr(v) for v in r) for r in rows]) + "\n")
        files.append(path)
    out = tmp_path / "gap"
    # one process: the registry line is this test's (worker processes would read the module's own)
    rc = main(["diagnose", str(tmp_path / "bench.toml"), str(files[0]), "--holdout", str(files[1]),
               "--out", str(out), "--quiet", "--workers", "1", "--no-plots"])
    assert rc == 0, capsys.readouterr().err
    doc = json.loads((out / "gap.json").read_text())
    assert doc["verdict"] == "sensor_gain[y2]"
    top = doc["effects"][0]
    assert abs(top["refit"]["effect_parameters"]["gain"] - 1.15) < 0.01 and top["refit"]["closed"] >= 0.8
    corrected = json.loads((out / "corrected" / "corrected.json").read_text())
    assert corrected["effect"] == "sensor_gain[y2]"
    assert corrected["effect_parameters"]["gain"]["unit"] == "1"
