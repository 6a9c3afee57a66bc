"""An undeclared delay between the force's channel and the sensors' named by the diagnosis (issue 71).

The hint family's undeclared-delay records (``tests/hint_family.py``: every sensor channel shifted by 2–10 whole
samples after the truth's noise, as a second converter card would; a newcomer's config that declares no delay) were
``unexplained`` before the catalogue had a delay: the best candidate, a first-order lag, closed 13 % of the gap on
record 2 (2.8e3 noise variances left on the held-out part).  A delay's χ² is periodic along each dominant mode's
period, so its score is the best drop over whole samples, not a linearisation at zero (which scored it 30× below
its drop, rank 14 of 24).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

import ebb_model as em
from diagnosis.corrected.export import corrected_statespace, export_corrected
from diagnosis.effects import AugmentedModel
from diagnosis.effects.delay import READ_CONCENTRATION, ChannelDelay, read_delay
from diagnosis.problem.augmented import simulate_effects
from ebb_model.acquisition.delay_line import delay_line
from ebb_model.reference import synthesize
from ebb_model.reference.excitation import band_limited_input
from identification.export_statespace import load_statespace

from conftest import make_config
from hint_family import diagnosed, hint_bench


def _bench(hold: str = "cubic"):
    d = make_config("clamped", "pinned", nodes=20, dt=5e-4, EI=10.0, rhoA=1.0, c=2.0, N=20.0,
                    actuators=[("F1", 0.55)],
                    sensors=[("y1", 0.35, "displacement"), ("a2", 0.8, "acceleration")]).to_dict()
    d["time"]["input"] = hold
    return em.config_from_dict(d)


@pytest.mark.parametrize("samples", [3.0, -2.0, 20.4, 2.5])
def test_the_statespace_of_a_delay_is_the_diagnosis_simulation(samples):
    """The StateSpace form carries the delay as its outputs' delays: simulated, it is the diagnosis' own
    simulation of the delayed channels to round-off (a fraction by the same band-limited kernel)."""
    cfg = _bench("bandlimited")
    u = band_limited_input(1200, cfg.time.dt, 2.0, 150.0, seed=3)
    part = (ChannelDelay(samples),)
    sys = corrected_statespace(AugmentedModel(cfg, cfg.parameter_values(), part))
    y_ref = simulate_effects(cfg, cfg.parameter_values(), u, part)
    np.testing.assert_allclose(em.simulate(sys, u).outputs, y_ref, rtol=0, atol=1e-11 * np.abs(y_ref).max())
    if samples >= 15 or samples == round(samples) >= 0:
        # a causal delay line: states driven sample by sample — of the model such a host runs, the cubic between
        # samples (ebb_model.acquisition.bandlimited.causal_config)
        causal = _bench("cubic")
        y_ref = simulate_effects(causal, causal.parameter_values(), u, part)
        line = delay_line(corrected_statespace(AugmentedModel(causal, causal.parameter_values(), part)))
        np.testing.assert_allclose(em.simulate(line, u).outputs, y_ref, rtol=0, atol=1e-10 * np.abs(y_ref).max())


def test_an_export_carries_a_whole_delay_and_says_when_it_cannot(tmp_path):
    """A whole delay is in the exported StateSpace as delay-line states; a fraction of a sample shorter than the
    kernel's reach is left out, and ``corrected.json`` says so and why (nothing claims to carry it)."""
    cfg = _bench()
    u = band_limited_input(800, cfg.time.dt, 2.0, 150.0, seed=4)
    summary = {"effect": "channel_delay", "effect_parameters": {"delay": {"value": 3 * cfg.time.dt, "unit": "s"}}}
    whole = AugmentedModel(cfg, cfg.parameter_values(), (ChannelDelay(3.0),))
    export_corrected(whole, tmp_path / "whole", summary, targets=("statespace",))
    sys = load_statespace(tmp_path / "whole" / "corrected.npz")
    doc = json.loads((tmp_path / "whole" / "corrected.json").read_text())
    assert "channel delays" not in doc["files"] and "delay" in doc["files"]["corrected.npz"]
    assert sum(name.startswith("delay(") for name in sys.state_labels) == 3 * 2
    short = AugmentedModel(cfg, cfg.parameter_values(), (ChannelDelay(2.5),))
    export_corrected(short, tmp_path / "short", summary, targets=("statespace",))
    doc = json.loads((tmp_path / "short" / "corrected.json").read_text())
    assert "2.5 samples late" in doc["files"]["channel delays"]
    assert "delay" not in doc["files"]["corrected.npz"]
    assert not any(name.startswith("delay(") for name in load_statespace(tmp_path / "short" / "corrected.npz")
                   .state_labels)
    del u


#: Record 2 is the one the delay's score was developed on; 18 (a clamped–free beam under noise to 0.2 fs, one
#: accelerometer 9 samples late) and 34 (clamped–free, white noise, two displacement sensors 10 samples late) were
#: not looked at before.  The delay is found within a tenth of a sample (measured: 3.9989 for 4, 9.0015 for 9,
#: 9.9597 for 10).  50 (clamped–free, three sensors of three kinds 8 samples late: the delay scored sixth of 24 at
#: a baseline that left it out, ``unexplained``) and 54 (clamped–pinned, one velocity sensor 10 samples late, half
#: its first mode's period: a reversed force with −1.66 samples was named) are named since the delay is read from
#: the records' phase (:func:`read_delay`; measured: 7.995 for 8 and 9.995 for 10, 1.48 and 1.06 noise
#: variances held out).
RECORDS = [2, 18, 34, 50, 54]


@pytest.mark.parametrize("i", RECORDS)
def test_an_undeclared_delay_is_named(tmp_path, i):
    case = hint_bench(i, elements=128)
    assert case.kind == "undeclared delay"
    d = diagnosed(case, tmp_path)
    doc = d.document
    assert doc["verdict"] == "channel_delay", doc["reason"]
    named = next(e for e in doc["effects"] if e["label"] == "channel_delay")["refit"]
    dt = case.bench.dt
    assert abs(named["effect_parameters"]["delay"] / dt - case.lag) <= 0.1, named["effect_parameters"]


def _read(i: int) -> tuple[float, float] | None:
    """The delay read from hint record ``i`` (64-element truth, its delay applied after the noise as
    :func:`hint_family.write_hint_case` does) against the newcomer's own model — the records' start, before any
    fit."""
    case = hint_bench(i)
    b = case.bench
    rec = synthesize(b.truth_config(), b.force()[:, None], noise=b.noise, seed=11, interpolation=b.interpolation,
                     n_elements=b.elements, effect=case.effect)
    y = np.asarray(rec.outputs, float)
    if case.lag:
        y = np.vstack([np.zeros((case.lag, y.shape[1])), y[:-case.lag]])
    cfg = em.config_from_dict(b.config_dict())
    y_hat = em.simulate(em.fast_model(cfg, cfg.parameter_values()), np.asarray(rec.inputs, float)).outputs
    return read_delay([(y, y_hat)])


def test_the_records_phase_reads_the_delay():
    """The delay read from the phase of the records against a model 30–60 % off (:func:`read_delay`): on the
    undeclared-delay records of the hint family's first 64 (16 records, 2–10 samples) within half a sample with
    the concentration that starts a refit, or unread (measured: 14 read, at most 0.5 off — record 26, 9.5 for
    10 —, concentration 0.82–0.97; records 30 and 58 unread: fewer coherent bins than
    :data:`~diagnosis.effects.delay._LEAST_BINS`); on its 16 correct records, where a start read away from none
    costs a refit and nothing else, within one sample of none or unread (measured: 0.9 on record 32, within 0.3
    on the others, three unread)."""
    read_ones = 0
    for i in range(2, 64, 4):
        case = hint_bench(i)
        read = _read(i)
        if read is not None:
            read_ones += 1
            assert abs(read[0] - case.lag) <= 0.5 and read[1] >= READ_CONCENTRATION, (case.name, read)
    assert read_ones >= 14
    for i in range(0, 64, 4):
        read = _read(i)
        assert read is None or abs(read[0]) < 1.0, (i, read)
