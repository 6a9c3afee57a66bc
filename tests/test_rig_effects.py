"""Rig effects, blind (issue 31): a spring to ground inside the span and a local loss of bending stiffness, on
three benches and three sensor kinds.

As the rest of the blind family (:mod:`test_diagnosis_blind`): records from the independent generator (Hermite
finite elements, exact in time, cubic-spline force), 1 % noise, priors 10–15 % off, the effect never told.

Benches (besides the family's own, in :mod:`test_diagnosis_blind`):

* the family's clamped–pinned bench (one force at 0.55 m, two sensors at 0.35 and 0.8 m) with displacement
  sensors (multisine 2–60 Hz) and accelerometers (2–150 Hz);
* a pinned–pinned beam under compression at half its buckling load (N = −50 N, ``N_cr = π² EI/L² = 98.7 N``:
  modes 3.5 / 18.6 / 43.9 / 79 Hz), two velocity sensors (0.3, 0.7 m), one force at 0.45 m, driven by a
  swept sine 2–100 Hz;
* a cantilever (clamped–free, EI, ρA, c unknown), one force at 0.9 m, displacement sensors at mid-length and the
  tip, driven by a multisine 1–60 Hz or hit by an impact hammer (three 4 ms half-sines, free decay between);
* a clamped–clamped beam with two forces (0.3, 0.65 m) and three mixed sensors (displacement, velocity,
  acceleration), pink (1/f) sensor noise at 1 % of each sensor's RMS.

Measured (2 cores): the spring (400 N/m at 0.3 m, κ = kL³/EI = 40) on displacement sensors — ``grounded_spring``
closes 100 % of the held-out gap (816 → 0.995 noise variances), k 400.6, x 0.3005 m, 27 s; on accelerometers —
a point mass at 0.82 m is the first local refit to explain the dominant part (it leaves 11 noise variances); the
modal pattern, run because it does not reach the noise floor, puts the spring at 0.2998 m (k 402.0), 100 % closed,
95 s.  Near the detection limit, on the cantilever: a point mass of 1 % of the beam (held-out gap 12 noise
variances) and of 0.3 % (gap 1.9, the threshold being 1.25) are both named, 10.2 g for 10 and 3.05 g for 3, at
0.699 / 0.700 m for 0.7, 16 s each.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ebb_model.config import config_from_dict
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.synthetic import synthesize
from ebb_model.reference.withheld import WithheldEffect

from conftest import make_config

from diagnosis.run import diagnose

from test_diagnosis_blind import DT, N_SAMPLES, SIZE_TOLERANCE, _write, assert_both_significant, bench_config
from test_noise_model import edged, pink

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
#: A soft spring to ground on the hammer-hit cantilever.
HAMMER_SPRING = {"k": 20.0, "x": 0.6}
#: The actuator lag of the pair with a spring to ground [s].
PAIR_LAG = {"tau": 5e-4}


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
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document
    _check_named(doc, "grounded_spring", SPRING)


def test_the_compressed_bench_under_a_swept_sine_without_effect_gives_none(tmp_path):
    cfg = pinned_bench()
    data = _write_swept(tmp_path, cfg, None, seed=4)
    d = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False)
    ratios = d.document["baseline"]["heldout_gap_ratio"]
    print(f"\nno effect (compressed pinned-pinned, velocity, swept sine): {d.verdict}, held-out {ratios}")
    assert d.verdict == "none", d.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios


def test_a_spring_to_ground_is_named_on_the_compressed_bench(tmp_path):
    cfg = pinned_bench()
    data = _write_swept(tmp_path, cfg, WithheldEffect("grounded_spring", PINNED_SPRING), seed=4)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document
    _check_named(doc, "grounded_spring", PINNED_SPRING)


# ------------------------------------------------------------------------------------------- the cantilever
CANTILEVER_TRUTH = {"EI": 10.0, "rhoA": 1.0, "c": 2.0}


def cantilever_bench(kind: str = "displacement"):
    """Clamped–free, one force near the tip, sensors at mid-length and the tip; EI, ρA, c unknown (prior off)."""
    d = make_config("clamped", "free", nodes=60, dt=DT, substeps=4, EI=11.2, rhoA=0.9, c=2.3, N=0.0,
                    actuators=[("F1", 0.9)], sensors=[("y1", 0.5, kind), ("y2", 1.0, kind)]).to_dict()
    for name, bounds in (("EI", [5.0, 20.0]), ("rhoA", [0.5, 2.0]), ("c", [0.2, 8.0])):
        d["parameters"][name].update(bounds=bounds, identify=True)
    return config_from_dict(d, extra_sections=("identification",))


def hammer(n: int) -> np.ndarray:
    """Three impact-hammer hits 1 s apart: 4 ms half-sines of 20 N, the beam decaying freely between them."""
    u = np.zeros((n, 1))
    for k0 in (100, 2100, 4100):
        u[k0:k0 + 8, 0] = 20.0 * np.sin(np.pi * np.arange(8) / 8)
    return u


def _write_cantilever(tmp_path, cfg, effect, u):
    rec = synthesize(cfg, u, params=CANTILEVER_TRUTH, effect=effect, noise=0.01, seed=103)
    path = tmp_path / "measured.npz"
    np.savez(path, time=rec.time, F1=rec.inputs[:, 0], y1=rec.outputs[:, 0], y2=rec.outputs[:, 1])
    return path


def test_a_cantilever_hit_by_a_hammer_without_effect_gives_none(tmp_path):
    cfg = cantilever_bench()
    d = diagnose(cfg, [_write_cantilever(tmp_path, cfg, None, hammer(N_SAMPLES))], tmp_path / "gap", plots=False,
                 workers=1, export=False)
    ratios = d.document["baseline"]["heldout_gap_ratio"]
    print(f"\nno effect (cantilever, hammer): {d.verdict}, held-out {ratios}")
    assert d.verdict == "none", d.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios


def test_a_spring_to_ground_is_named_from_hammer_hits_on_the_cantilever(tmp_path):
    cfg = cantilever_bench()
    values = HAMMER_SPRING
    doc = diagnose(cfg, [_write_cantilever(tmp_path, cfg, WithheldEffect("grounded_spring", values),
                                           hammer(N_SAMPLES))], tmp_path / "gap", plots=False, workers=1,
                   export=False).document
    _check_named(doc, "grounded_spring", values)


@pytest.mark.parametrize("mass", [0.01, 0.003], ids=["1%", "0.3%"])
def test_a_point_mass_near_the_detection_limit_is_named(tmp_path, mass):
    cfg = cantilever_bench()
    values = {"mass": mass, "x": 0.7}
    u = band_limited_input(N_SAMPLES, DT, 1.0, 60.0, seed=3)
    doc = diagnose(cfg, [_write_cantilever(tmp_path, cfg, WithheldEffect("point_mass", values), u)],
                   tmp_path / "gap", plots=False, workers=1, export=False).document
    before = doc["baseline"]["heldout_gap_ratio"]
    print(f"\npoint mass {mass} kg: held-out gap before {before}")
    assert max(before.values()) < 40.0       # near the limit: measured 14 / 9.7 (1 %), 2.2 / 1.65 (0.3 %)
    _check_named(doc, "point_mass", values)


# ------------------------------------------------------------------------------ clamped-clamped, mixed, pink
CLAMPED_TRUTH = {"EI": 10.0, "rhoA": 1.0, "c": 2.0, "N": 20.0}


def write_mixed(tmp_path, effect=None, edge: tuple[float, int] | None = None, declared: bool = False):
    """The clamped–clamped bench with two forces and three mixed sensors, its record under pink noise (``effect``
    withheld; default none; ``edge = (fraction of the sampling rate, order)``: the noise shaped by an acquisition's
    Butterworth anti-alias edge, in the frequency domain as the analog chain shapes it before sampling;
    ``declared``: the signals through that filter too — the truth's own realisation of scipy's poles — and the
    config declaring it on every sensor): ``(config, path)``."""
    d = make_config("clamped", "clamped", nodes=60, dt=DT, substeps=4, EI=11.2, rhoA=0.9, c=2.3, N=23.0,
                    actuators=[("F1", 0.3), ("F2", 0.65)],
                    sensors=[("d1", 0.4, "displacement"), ("v1", 0.55, "velocity"),
                             ("a1", 0.8, "acceleration")]).to_dict()
    for name, bounds in (("EI", [5.0, 20.0]), ("rhoA", [0.5, 2.0]), ("c", [0.2, 8.0]), ("N", [0.0, 60.0])):
        d["parameters"][name].update(bounds=bounds, identify=True)
    if declared:
        assert edge is not None
        for sensor in d["sensors"]:
            sensor["antialias"] = {"order": edge[1], "corner": edge[0] / DT}
    cfg = config_from_dict(d, extra_sections=("identification",))
    u = band_limited_input(N_SAMPLES, DT, 2.0, 150.0, n_inputs=2, seed=6)
    rec = synthesize(cfg, u, params=CLAMPED_TRUTH, effect=effect, noise=0.0, seed=6)
    rng = np.random.default_rng(106)
    noise = [pink(N_SAMPLES, rng) for _ in range(3)]
    if edge is not None:
        noise = [edged(x, edge[0] / DT, edge[1], DT) for x in noise]
    y = rec.outputs_clean + 0.01 * rec.outputs_clean.std(axis=0) * np.column_stack(noise)
    path = tmp_path / "measured.npz"
    np.savez(path, time=rec.time, F1=u[:, 0], F2=u[:, 1], d1=y[:, 0], v1=y[:, 1], a1=y[:, 2])
    return cfg, path


def test_clamped_beam_with_two_forces_three_mixed_sensors_and_pink_noise_gives_none(tmp_path):
    cfg, path = write_mixed(tmp_path)
    res = diagnose(cfg, [path], tmp_path / "gap", plots=False, workers=1, export=False)
    ratios = res.document["baseline"]["heldout_gap_ratio"]
    print(f"\nno effect (clamped-clamped, 2 forces, 3 mixed sensors, pink noise): {res.verdict}, held-out {ratios}")
    assert res.verdict == "none", res.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios


def test_pink_noise_through_an_anti_alias_edge_is_still_noise(tmp_path):
    """The same record, its pink noise rolled off by a 4th-order anti-alias edge at 0.4 of the sampling rate (as
    every acquisition's noise is): before, the noise model found no shape for the quiet bins above the band, fell
    back to the white floor there — far below the in-band pink level — and called the record ``unexplained`` at
    12 / 14 / 20 noise variances (d1 / v1 / a1).  The edge, fitted to the three channels at once, is taken out of
    the noise's shape: 782 Hz for the 800 Hz corner, order 4, and the verdict is ``none`` at 1.12 / 1.11 / 1.13."""
    cfg, path = write_mixed(tmp_path, edge=(0.4, 4))
    said: list[str] = []
    res = diagnose(cfg, [path], tmp_path / "gap", plots=False, workers=1, export=False, progress=said.append)
    ratios = res.document["baseline"]["heldout_gap_ratio"]
    assert res.verdict == "none", res.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios
    assert any(m.startswith("noise model") and "AR(" in m for m in said), said


def test_an_acquisition_filter_declared_on_the_sensors_is_part_of_the_model(tmp_path):
    """Signals and noise through a 4th-order Butterworth at 0.4 fs on every channel (the truth: scipy's poles in
    series, exact in time).  Declared on the sensors, the model carries the filter and the record is explained to
    the noise (``none``); left out of the config, the same record is not (the filter's phase in the band, about
    9° at 50 Hz, is tens to hundreds of noise variances even after the baseline refits around it).  Measured:
    declared ``none`` at 1.13 / 1.12 / 1.10 (d1 / v1 / a1); left out, the baseline refitted, held-out 30 / 371 / 658
    noise variances."""
    cfg, path = write_mixed(tmp_path, edge=(0.4, 4), declared=True)
    res = diagnose(cfg, [path], tmp_path / "gap", plots=False, workers=1, export=False)
    ratios = res.document["baseline"]["heldout_gap_ratio"]
    assert res.verdict == "none", res.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios
    # the same problem with the filter left out of the config, its baseline refitted from the declared one's
    plain = replace(cfg, sensors=tuple(replace(s, antialias=None) for s in cfg.sensors))
    undeclared = replace(res.problem, config=plain)
    fit = undeclared.fit(res.ranking.baseline.beta)
    gap = [float(v) for v in undeclared.heldout(fit.beta)[0]]
    print(f"\nfilter declared: {res.verdict}, held-out {ratios}; left out: held-out {gap}")
    assert all(v > 10.0 for v in gap), gap          # the gap threshold is a few noise variances


#: A stiff foundation and a small lag on the accelerometer of the mixed bench: the foundation alone closes 98 % of
#: the gap and leaves 9.4 noise variances — beyond ``pair_remainder`` (5), so a second effect is tried.
MIXED_PAIR = [WithheldEffect("foundation", {"kf": 500.0}), WithheldEffect("sensor_lag", {"tau": 1e-4}, sensor="a1")]


def test_a_foundation_and_a_small_sensor_lag_on_the_mixed_bench_are_named_as_a_pair(tmp_path):
    """Measured: foundation alone 98.1 % closed (488 → 10.4 noise variances, "the dominant part only" before the
    pair rule looked at the remainder); the pair 100 % (→ 1.17), kf 497.3 (500), τ 0.0993 ms (0.1), 18 s."""
    cfg, path = write_mixed(tmp_path, MIXED_PAIR)
    doc = diagnose(cfg, [path], tmp_path / "gap", plots=False, workers=1, export=False).document
    assert set(doc["verdict"].split("+")) == {"foundation", "sensor_lag[a1]"}, doc["reason"]
    fitted = doc["effects"][0]["refit"]["effect_parameters"]
    kf = next(v for k, v in fitted.items() if k.endswith("kf"))
    tau = next(v for k, v in fitted.items() if k.endswith("tau"))
    assert kf == pytest.approx(500.0, rel=SIZE_TOLERANCE) and tau == pytest.approx(1e-4, rel=SIZE_TOLERANCE), fitted
    assert_both_significant(doc)


#: A soft foundation and a lag on the accelerometer: alone the foundation and a spring to ground are near-equal
#: rivals (each closing about 36 % of the gap), the lag alone a little more.
SOFT_PAIR = [WithheldEffect("foundation", {"kf": 100.0}), WithheldEffect("sensor_lag", {"tau": 1.5e-4}, sensor="a1")]


def test_a_pair_is_weighed_against_the_pair_its_rival_makes(tmp_path):
    """Done-when (e): a foundation and a grounded spring, each with the sensor's lag — both pairs refitted, the
    true one named.  Measured: singles sensor lag 22.8, foundation 24.8, grounded spring 25.3 noise variances
    left of 38.7; pairs with the lag: the foundation 1.20, the spring 3.84 — the foundation's pair named,
    kf 100 and τ 0.15 ms within the size tolerance."""
    cfg, path = write_mixed(tmp_path, SOFT_PAIR)
    doc = diagnose(cfg, [path], None, plots=False, workers=2, export=False).document
    assert set(doc["verdict"].split("+")) == {"foundation", "sensor_lag[a1]"}, doc["reason"]
    rows = {frozenset(e["label"].split("+")): e for e in doc["effects"] if "refit" in e}
    rival = rows.get(frozenset({"grounded_spring", "sensor_lag[a1]"}))
    assert rival is not None, sorted(e["label"] for e in doc["effects"])
    named = rows[frozenset({"foundation", "sensor_lag[a1]"})]
    after = {k: max(r["refit"]["heldout_gap_ratio_after"].values()) for k, r in (("named", named), ("rival", rival))}
    assert after["named"] < after["rival"], after
    fitted = named["refit"]["effect_parameters"]
    kf = next(v for k, v in fitted.items() if k.endswith("kf"))
    tau = next(v for k, v in fitted.items() if k.endswith("tau"))
    assert kf == pytest.approx(100.0, rel=SIZE_TOLERANCE) and tau == pytest.approx(1.5e-4, rel=SIZE_TOLERANCE), fitted


def test_a_spring_to_ground_and_an_actuator_lag_are_named_as_a_pair(tmp_path):
    """A pair with the new effect on the family's bench: both found, each at its size, each significant."""
    cfg = bench_config()
    effects = [WithheldEffect("grounded_spring", SPRING), WithheldEffect("actuator_lag", PAIR_LAG)]
    doc = diagnose(cfg, [_write(tmp_path, cfg, effects, seed=3)], tmp_path / "gap", plots=False, workers=1,
                   export=False).document
    top = doc["effects"][0]
    fitted = top["refit"]["effect_parameters"]
    print(f"\ngrounded_spring + actuator_lag: verdict {doc['verdict']}, closed {top['refit']['closed']:.4f}, "
          f"fitted {fitted}")
    assert set(doc["verdict"].split("+")) == {"grounded_spring", "actuator_lag"}, doc["reason"]
    assert top["refit"]["closed"] >= 0.8, top["refit"]
    assert fitted["grounded_spring.k"] == pytest.approx(SPRING["k"], rel=SIZE_TOLERANCE), fitted
    assert abs(fitted["grounded_spring.x"] - SPRING["x"]) <= 0.05, fitted
    assert fitted["actuator_lag.tau"] == pytest.approx(PAIR_LAG["tau"], rel=SIZE_TOLERANCE), fitted
    assert_both_significant(doc)


# ------------------------------------------------------------------------------ a local loss of bending stiffness
def _check_weak(doc, values):
    """Named, ≥ 80 % closed, at its place (5 cm) with its compliance ``(1/f − 1) ℓ/L`` within 10 % — what the
    records determine (the length and the factor alone trade against each other)."""
    top = doc["effects"][0]
    fitted = top["refit"]["effect_parameters"]
    compliance = crack_compliance(values)
    print(f"\nstiffness_loss: verdict {doc['verdict']}, closed {top['refit']['closed']:.4f}, fitted {fitted} "
          f"(withheld {values}, compliance {compliance:.4g})")
    assert doc["verdict"] == "stiffness_loss", doc["reason"]
    assert top["label"] == "stiffness_loss" and top["refit"]["closed"] >= 0.8, top["refit"]
    assert abs(fitted["x"] - values["x"]) <= 0.05, fitted
    assert fitted["compliance"] == pytest.approx(compliance, rel=SIZE_TOLERANCE), fitted


def crack_compliance(values: dict[str, float]) -> float:
    """The segment's compliance ``(1/f − 1) ℓ/L`` (L = 1 m), what the records determine."""
    return (1.0 / values["factor"] - 1.0) * values["length"]


CRACK = {"x": 0.45, "length": 0.04, "factor": 0.3}
#: The segment on the compressed bench.
PINNED_CRACK = {"x": 0.6, "length": 0.04, "factor": 0.3}


@pytest.mark.parametrize("kind,f_max", [("displacement", 60.0), ("acceleration", 150.0)])
def test_a_local_stiffness_loss_is_named_on_the_family_bench(tmp_path, kind, f_max):
    """Measured: displacement — compliance 0.0922 for 0.0933 at 0.4500 m, 100 % closed, 14 s; accelerometers
    (held-out gap 1.2e4 noise variances) — 0.0938 at 0.4495 m, held-out 1.09 / 1.12 after (with a segment of
    fixed length the gap stayed at 4.5: the records see its length).  Not yet: a crack near the clamp of the
    hammer-hit cantilever (0.3 m, 0.04 m at 0.4) is named at 0.33 m but its refit stops in a long-segment basin
    (compliance 0.10 for 0.06, held-out 4.6 noise variances)."""
    cfg = bench_config(kind)
    data = _write(tmp_path, cfg, WithheldEffect("stiffness_loss", CRACK), seed=3, f_max=f_max)
    _check_weak(diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document, CRACK)


def test_a_local_stiffness_loss_is_named_on_the_compressed_bench(tmp_path):
    """A second bench and a third sensor kind: the compressed pinned–pinned beam (velocity sensors, swept sine),
    the segment at 0.6 m.  Measured: compliance 0.0932 for 0.0933 at 0.6002 m, 100 % closed, 27 s alone on
    2 cores; on the cantilever under a 1–60 Hz multisine (not in the suite), at 0.5 m: 0.0935 at 0.4996 m."""
    cfg = pinned_bench()
    data = _write_swept(tmp_path, cfg, WithheldEffect("stiffness_loss", PINNED_CRACK), seed=4)
    _check_weak(diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document, PINNED_CRACK)


# ------------------------------------------------------------------------- the shaker's armature at the drive point
def _armature(x, values):
    """The generator's truth of an armature: a point mass and a spring to ground at the drive point ``x``."""
    return [WithheldEffect("point_mass", {"mass": values["mass"], "x": x}),
            WithheldEffect("grounded_spring", {"k": values["k"], "x": x})]


ARMATURE = {"mass": 0.1, "k": 400.0}     # 10 % of the beam; its own resonance sqrt(k/m)/2π = 10 Hz, in band
PINNED_ARMATURE = {"mass": 0.1, "k": 300.0}          # at the compressed bench's drive point
CANTILEVER_ARMATURE = {"mass": 0.05, "k": 20.0}      # at the cantilever's drive point
#: A bare mass at the family bench's drive point (not an armature).
DRIVE_POINT_MASS = {"mass": 0.1, "x": 0.55}


@pytest.mark.parametrize("kind,f_max", [("displacement", 60.0), ("acceleration", 150.0)])
def test_a_shakers_armature_is_named_on_the_family_bench(tmp_path, kind, f_max):
    """Neither a point mass nor a spring alone explains it (the modes below 10 Hz rise, those above fall); its
    modal pattern puts it at the drive point.  Measured: displacement — mass 0.1002 kg, k 402.9 N/m, 100 % closed
    (438 → 0.998 noise variances), each part alone 1.9e4 / 4.5e4 BIC worse, 41 s; accelerometers — 0.0995 kg,
    403.4 N/m (7.9e3 → 1.03), 37 s.

    On the compressed pinned–pinned bench: :func:`test_a_shakers_armature_is_named_on_the_compressed_bench`."""
    cfg = bench_config(kind)
    data = _write(tmp_path, cfg, _armature(0.55, ARMATURE), seed=3, f_max=f_max)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document
    _check_named(doc, "shaker_armature[F1]", ARMATURE)


def test_a_shakers_armature_is_named_on_the_compressed_bench(tmp_path):
    """0.1 kg on 300 N/m at the drive point (0.45 m) of the pinned–pinned beam under compression, velocity sensors,
    a 2–100 Hz sweep.  Its fourth mode (76 Hz) is weakly seen by both sensors: the modal estimate's damping ran to
    6e-20 and the fit's log-damping Jacobian gave it a standard error of 0, which put every candidate's modal
    match at ~1e8 (verdict ``unexplained``).  The damping is now floored and its standard error taken from
    differences in the damping itself (measured: ζ 1e-6 ± 1.5e-3).  Measured: the armature's modal χ² 3.5 (the
    next 503), verdict ``shaker_armature[F1]``, 100 % closed (1.09e4 → 1.67 noise variances), 92 s alone."""
    cfg = pinned_bench()
    values = PINNED_ARMATURE
    doc = diagnose(cfg, [_write_swept(tmp_path, cfg, _armature(0.45, values), seed=4)], tmp_path / "gap",
                   plots=False, workers=1, export=False).document
    _check_named(doc, "shaker_armature[F1]", values)


def test_a_shakers_armature_is_named_on_the_cantilever(tmp_path):
    """A 50 g armature on a 20 N/m suspension at 0.9 m of the cantilever (1–60 Hz multisine).  Measured:
    0.0498 kg, 19.98 N/m, 100 % closed (1.1e3 → 0.998 noise variances), 31 s.  It needed the measured modes
    limited to the excited band: the fourth (60.8 Hz in the truth, at the band's top) was estimated at 74.9 Hz,
    73 standard errors away, and dominated every modal match (:func:`diagnosis.search.modal_source.modal_source`)."""
    cfg = cantilever_bench()
    values = CANTILEVER_ARMATURE
    u = band_limited_input(N_SAMPLES, DT, 1.0, 60.0, seed=3)
    doc = diagnose(cfg, [_write_cantilever(tmp_path, cfg, _armature(0.9, values), u)], tmp_path / "gap",
                   plots=False, workers=1, export=False).document
    _check_named(doc, "shaker_armature[F1]", values)


def test_a_point_mass_at_the_drive_point_is_not_an_armature(tmp_path):
    """The armature must pay for its suspension: a bare mass at the drive point is named a point mass."""
    cfg = bench_config()
    values = DRIVE_POINT_MASS
    data = _write(tmp_path, cfg, WithheldEffect("point_mass", values), seed=3)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document
    _check_named(doc, "point_mass", values)
