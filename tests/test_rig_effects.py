"""Rig effects, blind (issue 31): a spring to ground inside the span, on two benches and three sensor kinds.

As the rest of the blind family (:mod:`test_diagnosis_blind`): records from the independent generator (Hermite
finite elements, exact in time, cubic-spline force), 1 % noise, priors 10–15 % off, the effect never told.

Benches:

* the family's clamped–pinned bench (one force at 0.55 m, two sensors at 0.35 and 0.8 m) with displacement
  sensors (multisine 2–60 Hz) and accelerometers (2–150 Hz);
* a pinned–pinned beam under compression at half its buckling load (N = −50 N, ``N_cr = π² EI/L² = 98.7 N``:
  modes 3.5 / 18.6 / 43.9 / 79 Hz), two velocity sensors (0.3, 0.7 m), one force at 0.45 m, driven by a
  swept sine 2–100 Hz.

Measured (2 cores): the spring (400 N/m at 0.3 m, κ = kL³/EI = 40) on displacement sensors — ``grounded_spring``
closes 100 % of the held-out gap (816 → 0.995 noise variances), k 400.6, x 0.3005 m, 27 s; on accelerometers —
a point mass at 0.82 m is the first local refit to explain the dominant part (it leaves 11 noise variances); the
modal pattern, run because it does not reach the noise floor, puts the spring at 0.2998 m (k 402.0), 100 % closed,
95 s.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ebb_model.config import config_from_dict
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.synthetic import synthesize
from ebb_model.reference.withheld import WithheldEffect

from conftest import make_config

from diagnosis.run import diagnose

from test_diagnosis_blind import DT, N_SAMPLES, SIZE_TOLERANCE, _write, bench_config

#: The compressed pinned–pinned bench's truth and prior (10–15 % off; N within its bounds, below buckling for
#: every EI the bounds allow: π² · 8 = 79 N > 75 N).
PINNED_TRUTH = {"EI": 10.0, "rhoA": 1.0, "c": 2.0, "N": -50.0}
PINNED_PRIOR = {"EI": 11.2, "rhoA": 0.9, "c": 2.3, "N": -43.0}


def pinned_bench():
    """Pinned–pinned under compression, two velocity sensors, EI, ρA, c, N unknown."""
    d = make_config("pinned", "pinned", nodes=60, dt=DT, substeps=4, **PINNED_PRIOR, actuators=[("F1", 0.45)],
                    sensors=[("v1", 0.3, "velocity"), ("v2", 0.7, "velocity")]).to_dict()
    for name, bounds in (("EI", [8.0, 20.0]), ("rhoA", [0.5, 2.0]), ("c", [0.2, 8.0]), ("N", [-75.0, 0.0])):
        d["parameters"][name].update(bounds=bounds, identify=True)
    return config_from_dict(d, extra_sections=("identification",))


def _write_swept(tmp_path, cfg, effect, seed):
    u = band_limited_input(N_SAMPLES, DT, 2.0, 100.0, seed=seed, kind="chirp")
    rec = synthesize(cfg, u, params=PINNED_TRUTH, effect=effect, noise=0.01, seed=seed + 100)
    path = tmp_path / "measured.npz"
    np.savez(path, time=rec.time, F1=rec.inputs[:, 0], v1=rec.outputs[:, 0], v2=rec.outputs[:, 1])
    return path


def test_the_compressed_bench_is_half_way_to_buckling():
    assert -PINNED_TRUTH["N"] / (math.pi ** 2 * PINNED_TRUTH["EI"]) == pytest.approx(0.507, abs=1e-3)
    assert 8.0 * math.pi ** 2 > 75.0


SPRING = {"k": 400.0, "x": 0.3}
PINNED_SPRING = {"k": 300.0, "x": 0.35}


def _check_named(doc, label, values):
    top = doc["effects"][0]
    fitted = top["refit"]["effect_parameters"]
    print(f"\n{label}: verdict {doc['verdict']}, closed {top['refit']['closed']:.4f}, fitted {fitted} "
          f"(withheld {values})")
    assert doc["verdict"] == label, doc["reason"]
    assert top["label"] == label and top["refit"]["closed"] >= 0.8, top["refit"]
    for k, v in values.items():
        if k == "x":
            assert abs(fitted[k] - v) <= 0.05, (k, fitted, values)
        else:
            assert fitted[k] == pytest.approx(v, rel=SIZE_TOLERANCE), (k, fitted, values)


@pytest.mark.parametrize("kind,f_max", [("displacement", 60.0), ("acceleration", 150.0)])
def test_a_spring_to_ground_is_named_on_the_family_bench(tmp_path, kind, f_max):
    cfg = bench_config(kind)
    data = _write(tmp_path, cfg, WithheldEffect("grounded_spring", SPRING), seed=3, f_max=f_max)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, export=False).document
    _check_named(doc, "grounded_spring", SPRING)


def test_the_compressed_bench_under_a_swept_sine_without_effect_gives_none(tmp_path):
    cfg = pinned_bench()
    data = _write_swept(tmp_path, cfg, None, seed=4)
    d = diagnose(cfg, [data], tmp_path / "gap", plots=False, export=False)
    ratios = d.document["baseline"]["heldout_gap_ratio"]
    print(f"\nno effect (compressed pinned-pinned, velocity, swept sine): {d.verdict}, held-out {ratios}")
    assert d.verdict == "none", d.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios


def test_a_spring_to_ground_is_named_on_the_compressed_bench(tmp_path):
    cfg = pinned_bench()
    data = _write_swept(tmp_path, cfg, WithheldEffect("grounded_spring", PINNED_SPRING), seed=4)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, export=False).document
    _check_named(doc, "grounded_spring", PINNED_SPRING)
