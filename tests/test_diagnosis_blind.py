"""Blind check of the gap diagnosis (issue 5).

Measured data come from the repository's independent generator
(:func:`ebb_model.reference.synthetic.synthesize`: cubic-Hermite finite
elements integrated exactly in time, or with Newmark for the time-varying
effects; finer than and different from the finite-difference model that is
identified), with 1 % noise and one withheld effect.  The diagnosis is never
told the effect and starts from a prior 10–15 % off the truth.  For every
effect of the library it must rank the right one first, close at least 80 %
of the held-out gap and fit the withheld size; on data without an added
effect it must say ``none``.
"""
from __future__ import annotations

import numpy as np
import pytest

from ebb_model.config import config_from_dict
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.synthetic import synthesize
from ebb_model.reference.withheld import WithheldEffect

from conftest import make_config
from one_baseline import assert_no_worse_than_identify

import diagnosis.problem.augmented  # noqa: F401 - imported plainly: a broken import must fail the suite
from diagnosis.run import diagnose  # noqa: E402

DT = 5e-4
N_SAMPLES = 6000


#: Relative error allowed on a fitted effect's size (position of a point mass: 5 cm); measured 0.005–2.8 % (kf),
#: the point mass at 0.2 mm.
SIZE_TOLERANCE = 0.1
#: The truth of the records; the config's nominal values (the diagnosis' prior) are 10–15 % off, as a user's are.
TRUTH = {"EI": 10.0, "rhoA": 1.0, "c": 2.0, "N": 20.0}
PRIOR = {"EI": 11.2, "rhoA": 0.9, "c": 2.3, "N": 23.0}


def bench_config(kind: str = "displacement"):
    """A clamped–pinned test bench: one force, two sensors of ``kind``, EI, rhoA, c, N unknown."""
    d = make_config("clamped", "pinned", nodes=60, dt=DT, substeps=4, **PRIOR,
                    actuators=[("F1", 0.55)],
                    sensors=[("y1", 0.35, kind), ("y2", 0.8, kind)]).to_dict()
    d["parameters"]["EI"].update(bounds=[5.0, 20.0], identify=True)
    d["parameters"]["rhoA"].update(bounds=[0.5, 2.0], identify=True)
    d["parameters"]["c"].update(bounds=[0.2, 8.0], identify=True)
    d["parameters"]["N"].update(bounds=[0.0, 60.0], identify=True)
    return config_from_dict(d, extra_sections=("identification",))


def _write(tmp_path, cfg, effect, seed, f_max=60.0):
    u = band_limited_input(N_SAMPLES, DT, 2.0, f_max, seed=seed)
    rec = synthesize(cfg, u, params=TRUTH, effect=effect, noise=0.01, seed=seed + 100)
    path = tmp_path / "measured.npz"
    np.savez(path, time=rec.time, F1=rec.inputs[:, 0], y1=rec.outputs[:, 0], y2=rec.outputs[:, 1])
    return path


CASES = [
    pytest.param("boundary_rotational_left", WithheldEffect("boundary_rotational_left", {"kr": 200.0})),
    ("boundary_translational_right", WithheldEffect("boundary_translational_right", {"kt": 5e4})),
    ("point_mass", WithheldEffect("point_mass", {"mass": 0.1, "x": 0.7})),
    ("kelvin_voigt", WithheldEffect("kelvin_voigt", {"eta": 6e-5})),
    ("rotary_inertia", WithheldEffect("rotary_inertia", {"rhoI": 4e-4})),
    ("foundation", WithheldEffect("foundation", {"kf": 200.0})),
    ("actuator_lag", WithheldEffect("actuator_lag", {"tau": 5e-4})),
    ("sensor_lag[y2]", WithheldEffect("sensor_lag", {"tau": 5e-4}, sensor="y2")),
    ("axial_drift", WithheldEffect("axial_drift", {"rate": 3.0})),
    ("geometric_stiffening", WithheldEffect("geometric_stiffening", {"EA": 2e6})),
]


@pytest.mark.parametrize("label,effect", CASES)
def test_withheld_effect_is_named_and_closes_the_gap(tmp_path, label, effect):
    cfg = bench_config()
    data = _write(tmp_path, cfg, effect, seed=3)
    d = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False)
    doc = d.document
    top = doc["effects"][0]
    fitted, base = top["refit"]["effect_parameters"], top["refit"]["baseline_parameters"]
    print(f"\n{label}: fitted {fitted} (withheld {dict(effect.values)}); baseline {base}")
    assert doc["verdict"] == label, doc["reason"]
    assert top["label"] == label
    assert top["refit"]["closed"] >= 0.8, top["refit"]
    # the baseline reported no worse than identify's point (tests/one_baseline.py)
    assert_no_worse_than_identify(d, cfg, [data], tmp_path / "identify")
    # the size, not only the name: the withheld values and the truth's beam, from a prior 10-15 % off
    for k, v in effect.values.items():
        if k == "x":
            assert abs(fitted[k] - v) <= 0.05, (k, fitted, effect.values)
        else:
            assert fitted[k] == pytest.approx(v, rel=SIZE_TOLERANCE), (k, fitted, effect.values)
    for k in ("EI", "rhoA", "N"):   # measured within 0.5 %, N within 3 % with a foundation (both stiffen every mode)
        assert base[k] == pytest.approx(TRUTH[k], rel=0.05), (k, base)
    # the gap is the withheld physics, not the model's grid (model-accuracy issue: numerical share < 10 %)
    assert doc["baseline"]["numerical_adequacy"]["max_numerical_share"] < 0.1, doc["baseline"]["numerical_adequacy"]
    assert (tmp_path / "gap" / "gap.json").is_file()


def test_no_effect_gives_none(tmp_path):
    cfg = bench_config()
    data = _write(tmp_path, cfg, None, seed=5)
    d = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1)
    assert d.verdict == "none", d.document["reason"]
    ratios = d.document["baseline"]["heldout_gap_ratio"]
    assert all(v < 1.25 for v in ratios.values()), ratios


#: The accelerometer family (issue 18): the same bench with two accelerometers, excited over 2–150 Hz (fs/13),
#: damping ratios from 2 % at mode 1 down to 0.1 % at mode 5 (viscous c = 2 only).  Named right, ≥ 80 % of the
#: held-out gap closed and the size within 10 % — measured: none → none (the baseline's held-out gap is within the
#: noise threshold), foundation 100 % closed (kf 200.5 for 200), actuator lag 99.6 % (τ 0.4996 ms for 0.5),
#: Kelvin–Voigt 100 % (η 6.01e-5 for 6e-5), point mass 100 % (0.0996 kg at 0.69997 m), sensor lag on y2 99.9 %
#: (τ 0.493 ms), axial drift 99.98 % (3.008 N/s), geometric stiffening 99.8 % (EA 1.99e6); and, found by their
#: modal pattern where the baseline had compensated them and their one-sided score was 0 (all were called a
#: point mass before): the compliant clamp 100 % (kr 203 for 200), rotary inertia 100 % (ρI 3.99e-4), a
#: translational spring at the pinned end 100 % (kt 4.98e4 for 5e4).
ACCEL_CASES = [
    ("foundation", WithheldEffect("foundation", {"kf": 200.0})),
    ("actuator_lag", WithheldEffect("actuator_lag", {"tau": 5e-4})),
    ("kelvin_voigt", WithheldEffect("kelvin_voigt", {"eta": 6e-5})),
    ("rotary_inertia", WithheldEffect("rotary_inertia", {"rhoI": 4e-4})),
    ("boundary_rotational_left", WithheldEffect("boundary_rotational_left", {"kr": 200.0})),
    ("boundary_translational_right", WithheldEffect("boundary_translational_right", {"kt": 5e4})),
    ("point_mass", WithheldEffect("point_mass", {"mass": 0.1, "x": 0.7})),
    ("sensor_lag[y2]", WithheldEffect("sensor_lag", {"tau": 5e-4}, sensor="y2")),
    ("axial_drift", WithheldEffect("axial_drift", {"rate": 3.0})),
    ("geometric_stiffening", WithheldEffect("geometric_stiffening", {"EA": 2e6})),
]


#: The wider-band displacement family (issue 18): two displacement sensors over 2–150 Hz (modes 1–5; the
#: record on which the seed's grid once made the no-effect diagnosis name a point mass — that case is in
#: ``test_diagnosis_grid.py``).  Measured: foundation 100 % closed (kf 200.09), Kelvin–Voigt 100 % (η 5.96e-5),
#: and (not run here, 99 s) the point mass 100 % (0.1001 kg at 0.69999 m).
WIDE_CASES = [
    ("foundation", WithheldEffect("foundation", {"kf": 200.0})),
    ("kelvin_voigt", WithheldEffect("kelvin_voigt", {"eta": 6e-5})),
]


@pytest.mark.parametrize(
    "kind,label,effect",
    [pytest.param("acceleration", *c.values, marks=c.marks, id=f"accel-{c.values[0]}")
     if hasattr(c, "values") else pytest.param("acceleration", *c, id=f"accel-{c[0]}")
     for c in ACCEL_CASES]
    + [pytest.param("displacement", *c, id=f"wide-{c[0]}") for c in WIDE_CASES],
)
def test_wider_band_families_name_the_effect(tmp_path, kind, label, effect):
    cfg = bench_config(kind)
    data = _write(tmp_path, cfg, effect, seed=3, f_max=150.0)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document
    top = doc["effects"][0]
    fitted = top["refit"]["effect_parameters"]
    print(f"\n{label} ({kind}, 2-150 Hz): verdict {doc['verdict']}, closed {top['refit']['closed']:.4f}, "
          f"fitted {fitted} (withheld {dict(effect.values)})")
    assert doc["verdict"] == label, doc["reason"]
    assert top["refit"]["closed"] >= 0.8, top["refit"]
    for k, v in effect.values.items():
        assert fitted[k] == pytest.approx(v, rel=SIZE_TOLERANCE), (k, fitted, effect.values)
    assert doc["baseline"]["numerical_adequacy"]["max_numerical_share"] < 0.1, doc["baseline"]["numerical_adequacy"]


def test_accelerometer_record_without_effect_gives_none(tmp_path):
    cfg = bench_config("acceleration")
    data = _write(tmp_path, cfg, None, seed=3, f_max=150.0)
    d = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False)
    ratios = d.document["baseline"]["heldout_gap_ratio"]
    print(f"\nno effect (accelerometers): verdict {d.verdict}, held-out gap ratio {ratios}")
    assert d.verdict == "none", d.document["reason"]
    assert all(v < 1.25 for v in ratios.values()), ratios


#: Effects outside the catalogue (issue 17): a grounded hardening spring (k3 w³ at 0.7 m; ~110–140 noise σ of
#: response change) and a dry-friction contact (0.05 N at 0.45 m, slip velocity 0.1 mm/s; ~22 σ), both
#: integrated by the generator's Newmark with Newton on the local element (converged: 0.02 σ between 8 and 16
#: sub-steps).  The diagnosis must say "not in the catalogue" instead of naming the least-bad candidate.
#: A third (issue 31): a one-sided stop 2 mm from the beam at 0.7 m (k 2000 N/m; the free beam's displacement
#: there has an RMS of 1.96 mm and peaks at 4.3 mm), ~110 σ of response change.
#: Measured: cubic spring — the best candidate (a pair at most) closes 6 % of the held-out gap; dry friction —
#: the best single candidate closes 4 %.
OUTSIDE_CASES = [
    ("cubic_spring", WithheldEffect("cubic_spring", {"k3": 1e9, "x": 0.7})),
    ("dry_friction", WithheldEffect("dry_friction", {"force": 0.05, "x": 0.45, "slip": 1e-4})),
    ("contact_stop", WithheldEffect("contact_stop", {"k": 2000.0, "x": 0.7, "gap": 2e-3})),
]


@pytest.mark.parametrize("label,effect", OUTSIDE_CASES)
def test_effect_outside_the_catalogue_is_not_named(tmp_path, label, effect):
    cfg = bench_config()
    data = _write(tmp_path, cfg, effect, seed=3)
    d = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1)
    doc = d.document
    print(f"\n{label} (outside the catalogue): verdict {doc['verdict']}: {doc['reason']}")
    assert doc["verdict"] == "unexplained", doc["reason"]
    assert doc["reason"].startswith("not in the catalogue"), doc["reason"]
    assert "where the gap is" in doc["reason"], doc["reason"]   # the localisation's lead, not a name
    assert min(doc["baseline"]["heldout_gap_ratio"].values()) > 10.0   # a real gap, not "none"
    assert "corrected" not in doc and not (tmp_path / "gap" / "corrected").exists()   # no model exported


#: Two withheld effects at once (issue 17).  The foundation is absorbed by the baseline's axial load (N 40.9 for
#: 20) and scores 0 at the baseline; scored again at the actuator lag's refit it is found.  Measured: actuator
#: lag + foundation 99 % closed (τ 0.4945 ms, kf 205.5), Kelvin–Voigt + sensor lag 100 % (η 5.89e-5, τ 0.4998 ms).
PAIR_CASES = [
    ({"actuator_lag", "foundation"}, [WithheldEffect("foundation", {"kf": 200.0}),
                                      WithheldEffect("actuator_lag", {"tau": 5e-4})]),
    ({"kelvin_voigt", "sensor_lag[y2]"}, [WithheldEffect("kelvin_voigt", {"eta": 6e-5}),
                                          WithheldEffect("sensor_lag", {"tau": 5e-4}, sensor="y2")]),
]


def assert_both_significant(doc):
    """A named pair pays for each of its effects: its BIC beats each effect refitted alone (its best refit, from
    the pair's optimum when that was better) by the margin — neither is a passenger the pair shrank to nothing."""
    rows = {e["label"]: e for e in doc["effects"]}
    pair = rows[doc["verdict"]]["refit"]
    for label in doc["verdict"].split("+"):
        alone = rows[label]["refit"]
        assert alone is not None, (label, doc["reason"])
        assert pair["delta_bic"] < alone["delta_bic"] - doc["settings"]["bic_margin"], (label, pair, alone)


@pytest.mark.parametrize("labels,effects", PAIR_CASES, ids=["foundation+actuator_lag", "kelvin_voigt+sensor_lag"])
def test_two_withheld_effects_are_named_as_a_pair(tmp_path, labels, effects):
    cfg = bench_config()
    data = _write(tmp_path, cfg, effects, seed=3)
    doc = diagnose(cfg, [data], tmp_path / "gap", plots=False, workers=1, export=False).document
    top = doc["effects"][0]
    fitted = top["refit"]["effect_parameters"]
    print(f"\n{sorted(labels)}: verdict {doc['verdict']}, closed {top['refit']['closed']:.4f}, fitted {fitted}")
    assert set(doc["verdict"].split("+")) == labels, doc["reason"]
    assert top["label"] == doc["verdict"] and top["refit"]["closed"] >= 0.8, top["refit"]
    assert doc["indistinguishable"] == []   # the single effect is nested in the pair, not its rival
    assert_both_significant(doc)
    for e in effects:
        label = f"{e.name}[{e.sensor}]" if e.sensor else e.name
        for k, v in e.values.items():   # measured within 2.8 % (kf)
            assert fitted[f"{label}.{k}"] == pytest.approx(v, rel=SIZE_TOLERANCE), (label, k, fitted)
