"""Evidence belongs to a set-up (:mod:`diagnosis.setups`): the config's ``[[setups]]`` checked like the rest, and
a bench measured twice — a modal test of the bare beam, a time record with the shaker bolted on — diagnosed with
each piece of evidence in its own set-up.

The truth is independent: the record from the Hermite finite-element generator with the armature as a point mass
and a spring to ground at the drive point; the bare beam's modes from the analytic characteristic equation of the
clamped–pinned beam under its axial load (:func:`ebb_model.reference.analytic.analytic_frequencies_hz`).
"""
from __future__ import annotations

import numpy as np
import pytest

from diagnosis.run import diagnose
from diagnosis.setups import setups_from_config
from ebb_model.config import config_from_dict
from ebb_model.errors import ConfigError
from ebb_model.reference.analytic import analytic_frequencies_hz
from test_diagnosis_blind import SIZE_TOLERANCE, TRUTH, _write, bench_config
from test_rig_effects import ARMATURE, _armature

#: The modal test's standard uncertainty, relative (a hammer test's peaks read to about 0.5 %).
MODES_STD = 0.005


def _with(cfg, **extra):
    d = cfg.to_dict()
    d.update(extra)
    return config_from_dict(d, extra_sections=("identification", "setups"))


SHAKER_AND_HAMMER = [{"name": "shaker on", "parts": ["shaker"], "evidence": ["records"]},
                     {"name": "hammer test", "parts": [], "evidence": ["modes"]}]


def test_setups_are_checked_like_the_rest():
    cfg = bench_config()
    s = setups_from_config(_with(cfg, setups=SHAKER_AND_HAMMER))
    assert s is not None and s.modes_lack() == frozenset({"shaker"}) and s.records_have("shaker")
    assert setups_from_config(cfg) is None
    bad = [{"name": "a", "parts": ["shaker", "clamp"], "evidence": ["records", "photos"], "colour": 1},
           {"name": "a", "parts": [], "evidence": ["records"]}, {"parts": []}]
    with pytest.raises(ConfigError) as err:
        setups_from_config(_with(cfg, setups=bad))
    for expected in ("unknown rig part 'clamp'", "unknown kind 'photos'", "colour: unknown key",
                     "the name is used twice", "records belongs to set-up 'a' already", "setups[2].name"):
        assert expected in str(err.value), (expected, str(err.value))
    with pytest.raises(ConfigError, match="must be a list of tables"):
        setups_from_config(_with(cfg, setups={"name": "a"}))


def _bare_modes(n: int = 4) -> dict:
    f = analytic_frequencies_hz("clamped", "pinned", length=1.0, EI=TRUTH["EI"], rhoA=TRUTH["rhoA"], N=TRUTH["N"],
                                n_modes=n)
    return {"frequencies_hz": [float(v) for v in f], "std_hz": [float(MODES_STD * v) for v in f]}


def test_a_shaker_record_and_a_bare_modal_test_name_the_attachment(tmp_path):
    """The armature (0.1 kg on 400 N/m at the drive point) is in the time record only; the bare beam's four modes
    come from a hammer test without it.  Read as one set-up, the two disagree: the armature's refit is vetoed by
    the modes (measured: its modes 8.52, 25.57, 49.14, 89.73 Hz against 8.13, 25.58, 52.92, 90.19 — χ² 296 > 18.5),
    and so is every other refit that closes the gap.  Done-when (a): declared as two set-ups, the armature is
    named at its size and agrees with the modes (their rows computed without the shaker: χ² 0.05); the beam's own
    parameters, shared, are fitted to both.  Not declared, the diagnosis says the evidence disagrees more than one
    structure explains, ranks again with the modes taken without the rig parts and names the armature the same way,
    the set-ups marked inferred (measured: 3 refits closing ≥ 80 %, all misfitting the modes, χ² 296–677)."""
    cfg = bench_config()
    data = _write(tmp_path, cfg, _armature(0.55, ARMATURE), seed=3)
    ident = dict(cfg.extra.get("identification", {}) or {}) | {"modes": _bare_modes()}
    declared = _with(cfg, identification=ident, setups=SHAKER_AND_HAMMER)
    inferred = _with(cfg, identification=ident)
    for how, config in (("declared", declared), ("inferred", inferred)):
        doc = diagnose(config, [data], None, plots=False, workers=1, export=False).document
        print(f"\nset-ups {how}: {doc['verdict']}; {doc['reason'][:400]}")
        assert doc["verdict"] == "shaker_armature[F1]", (how, doc["reason"])
        fitted = doc["effects"][0]["refit"]["effect_parameters"]
        for k, v in ARMATURE.items():
            assert fitted[k] == pytest.approx(v, rel=SIZE_TOLERANCE), (how, fitted)
        assert doc["against_measured_modes"]["shaker_armature[F1]"]["agrees"], doc["against_measured_modes"]
        assert np.isclose(doc["effects"][0]["refit"]["baseline_parameters"]["EI"], TRUTH["EI"], rtol=0.05)
        if how == "declared":
            assert doc["setups"] == {"records": {"setup": "shaker on", "parts": ["shaker"]},
                                     "modes": {"setup": "hammer test", "parts": []}}
            assert "setups_apart" not in doc
        else:
            assert doc["setups"]["inferred"] and "shaker" not in doc["setups"]["modes"]["parts"], doc["setups"]
            apart = doc["setups_apart"]
            assert apart["adopted"] and apart["verdict"] == "shaker_armature[F1]", apart
            assert "disagree more than one structure explains" in doc["reason"]


def _modes_with_armature(cfg, n: int = 4) -> dict:
    """The modes of the beam with the armature on, from the independent finite-element truth (128 Hermite
    elements; 64 differ by at most 3e-7 relative, far below the modal test's 0.5 %)."""
    from ebb_model.reference.truth_model import apply_effects, build_beam

    p = dict(cfg.parameter_values()) | TRUTH
    beam = build_beam(cfg, p, apply_effects(cfg, p, _armature(0.55, ARMATURE)), 128, 1, cfg.time.dt)
    f = beam.natural_frequencies_hz(n)
    return {"frequencies_hz": [float(v) for v in f], "std_hz": [float(MODES_STD * v) for v in f]}


def test_both_pieces_of_evidence_with_the_shaker_stay_one_setup(tmp_path):
    """Done-when (b): the modal test made with the shaker on too (the truth's modes with the armature) — the
    evidence agrees, nothing is split: the armature is named at its size, agreeing with the modes, and no set-ups
    are inferred."""
    cfg = bench_config()
    data = _write(tmp_path, cfg, _armature(0.55, ARMATURE), seed=3)
    ident = dict(cfg.extra.get("identification", {}) or {}) | {"modes": _modes_with_armature(cfg)}
    doc = diagnose(_with(cfg, identification=ident), [data], None, plots=False, workers=1, export=False).document
    assert doc["verdict"] == "shaker_armature[F1]", doc["reason"]
    fitted = doc["effects"][0]["refit"]["effect_parameters"]
    for k, v in ARMATURE.items():
        assert fitted[k] == pytest.approx(v, rel=SIZE_TOLERANCE), fitted
    assert doc["against_measured_modes"]["shaker_armature[F1]"]["agrees"]
    assert "setups" not in doc and "setups_apart" not in doc
