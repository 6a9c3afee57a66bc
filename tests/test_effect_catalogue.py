"""The effects catalogue as a registry: its families, and a new signal-level effect added in one place.

The diagnosis names no effect outside ``diagnosis/effects/``: the simulation, the pairs and the corrected
model's StateSpace ask each signal part what it does.  A calibration error of one sensor (a gain), written
here as a user would write a new module, runs through all of them with no other code.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
import pytest

import ebb_model as em
from diagnosis.problem.augmented import simulate_effects
from diagnosis.corrected.export import corrected_statespace
from diagnosis.effects import (EFFECT_NAMES, FAMILIES, AugmentedModel, Scales, Signal, candidate_effects,
                               pair_effect, signal_effect)
from diagnosis.effects.chain import SensorGain
from diagnosis.effects.lag import ActuatorLag, first_order_lag
from ebb_model.reference.excitation import band_limited_input

from conftest import make_config


def bench(left: str = "clamped", right: str = "pinned"):
    return make_config(left, right, nodes=20, dt=5e-4, EI=10.0, rhoA=1.0, c=2.0, N=20.0,
                       actuators=[("F1", 0.55)],
                       sensors=[("y1", 0.35, "displacement"), ("a2", 0.8, "acceleration")])


#: The benches' scales as the diagnosis sizes them, the outputs' RMS included (a new effect sized from it, as the
#: docs advise, meets the catalogue tests with a real value): y1 and a2 under the tests' force (band 2–150 Hz,
#: unit RMS), measured 7.2e-4 m and 14.6 m/s² (clamped–pinned), 4.7e-4 and 18.3 (clamped–clamped).
SCALES = Scales(EI=10.0, rhoA=1.0, N=20.0, length=1.0, omega_low=20.0, omega_high=900.0, duration=0.6,
                stretch_max=1e-6, output_rms=(6e-4, 16.0))


def test_families_build_the_catalogue_in_report_order():
    """The catalogue is its families' candidates, family by family in registry order — derived from the registry,
    not a list kept by hand: each family's candidates carry its names, every name of the registry is a candidate
    on a bench with both ends constrained and sensors of two kinds, and no label repeats."""
    cfg = bench("clamped", "clamped")
    effects = candidate_effects(cfg, SCALES)
    by_family = [f.candidates(cfg, SCALES, ()) for f in FAMILIES]
    assert [e.label for e in effects] == [e.label for group in by_family for e in group]
    for family, group in zip(FAMILIES, by_family):
        assert group and {e.name for e in group} <= set(family.names), family.names
    assert {e.name for e in effects} == set(EFFECT_NAMES) and len(EFFECT_NAMES) == len(set(EFFECT_NAMES))
    assert len({e.label for e in effects}) == len(effects)
    # a sensor-targeted family has one candidate per sensor, labelled by it
    lags = [e.label for e in effects if e.name == "sensor_lag"]
    assert lags == [f"sensor_lag[{s.name}]" for s in cfg.sensors]
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


def blind_bench_records(tmp_path, seeds: tuple[int, int], sensor: str, change):
    """The blind bench's config (written to ``bench.toml``) and two records of it — the independent FE generator,
    no withheld effect, 1 % noise — written as CSV with ``change`` applied to ``sensor``'s readings, as a
    miscalibrated or offset sensor records them."""
    from ebb_model.reference.synthetic import synthesize
    from test_diagnose_cli import _toml
    from test_diagnosis_blind import DT, bench_config

    cfg = bench_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = []
    for seed in seeds:
        rec = synthesize(cfg, band_limited_input(3000, DT, 2.0, 60.0, seed=seed), noise=0.01, seed=seed)
        path = tmp_path / f"rec{seed}.csv"
        rec.to_csv(path)
        lines = path.read_text().splitlines()
        k = lines[0].split(",").index(sensor)
        rows = [[float(v) for v in line.split(",")] for line in lines[1:]]
        for r in rows:
            r[k] = change(r[k])
        path.write_text("\n".join([lines[0]] + [",".join(repr(v) for v in r) for r in rows]) + "\n")
        files.append(path)
    return cfg, files


def sensor_gain_candidates(config, scales: Scales, identified: tuple[str, ...]):
    """The new family's builder, as its module would define it: one gain error per sensor (off: 1), declared
    degenerate with a common scale of the beam's unknowns (a gain is: the docs say to declare it)."""
    from dataclasses import replace

    return tuple(replace(signal_effect("sensor_gain", s.name, "gain", (0.5, 2.0), 1.0, f"gain error of sensor {s.name}",
                                       lambda g, name=s.name: SensorGain(name, g), "gain", "1"), scale_degenerate=True)
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

    from diagnosis.effects.base import Family

    # the built-in measurement-chain family replaced by this test's own module-to-be
    mine = tuple(f for f in FAMILIES if "sensor_gain" not in f.names)
    monkeypatch.setattr(catalogue, "FAMILIES", mine + (Family(("sensor_gain",), sensor_gain_candidates),))
    _, files = blind_bench_records(tmp_path, (31, 32), "y2", lambda v: v * 1.15)
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


# --- an output-level effect and an export target, each added exactly as docs/architecture.md says (issue 52) ---------
@dataclass(frozen=True)
class SensorOffset(Signal):
    """A new module's signal part: a constant added to one sensor's reading (nothing else declared)."""

    sensor: str
    offset: float
    description = "a constant offset of a sensor's reading"

    def outputs(self, y: np.ndarray, dt: float, names: tuple[str, ...]) -> np.ndarray:
        out = np.array(y, dtype=float)
        out[:, names.index(self.sensor)] += self.offset
        return out


def sensor_offset_candidates(config, scales: Scales, identified: tuple[str, ...]):
    """The new family's builder: one offset per sensor, searched within half the reading's RMS either side."""
    return tuple(signal_effect("sensor_offset", s.name, "offset", (-0.5 * rms, 0.5 * rms), 0.0,
                               f"a constant offset of sensor {s.name}",
                               lambda v, name=s.name: SensorOffset(name, v), "offset", s.unit)
                 for s, rms in zip(config.sensors, scales.output_rms))


MAT_TARGET = '''
"""Export target ``mat``: the model's matrices for MATLAB (``<stem>.mat``)."""
from pathlib import Path

from scipy.io import savemat

from ebb_model.io.output import atomic_path


def write(item, out_dir: Path) -> list[Path]:
    path = out_dir / f"{item.stem}.mat"
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            savemat(fh, {"A": item.system.A, "B": item.system.B, "C": item.system.C, "D": item.system.D,
                         "dt": item.system.dt})
    return [path]
'''


def test_an_offset_and_a_mat_target_added_the_documented_way(tmp_path, monkeypatch, capsys):
    """A sensor offset (a :class:`Signal` subclass and its family's line) and a ``mat`` export target (a module and
    its line in ``TARGETS``), touching nothing else: ``ebb diagnose`` names the offset (0.2 mm on ``y1``), writes
    the corrected model through both targets, lists every file in ``corrected.json`` in the targets' words, gives
    the offset as an affine term beside the StateSpace (the model is time-invariant), and says so on the console.

    The record: the independent FE generator without a withheld effect, then 0.2 mm added to ``y1``'s readings, as
    an offset of a displacement sensor does."""
    import json
    import sys
    from types import MappingProxyType

    import diagnosis.effects as catalogue
    import identification.export_targets as export_targets
    from diagnosis.effects.base import Family
    from ebb_cli import main
    from identification.export_statespace import load_statespace

    monkeypatch.setattr(catalogue, "FAMILIES", FAMILIES + (Family(("sensor_offset",), sensor_offset_candidates),))
    (tmp_path / "targets").mkdir()
    (tmp_path / "targets" / "mat_target.py").write_text(MAT_TARGET)
    monkeypatch.syspath_prepend(str(tmp_path / "targets"))
    registry = dict(export_targets.TARGETS) | {"mat": "mat_target"}      # the registry's one new line
    monkeypatch.setattr(export_targets, "TARGETS", MappingProxyType(registry))
    _, files = blind_bench_records(tmp_path, (41, 42), "y1", lambda v: v + 2e-4)
    out = tmp_path / "gap"
    rc = main(["diagnose", str(tmp_path / "bench.toml"), str(files[0]), "--holdout", str(files[1]), "--out", str(out),
               "--workers", "1", "--no-plots", "--target", "statespace", "fmu", "mat"])
    console = capsys.readouterr().out
    assert rc == 0
    doc = json.loads((out / "gap.json").read_text())
    assert doc["verdict"] == "sensor_offset[y1]", doc["reason"]
    refit = doc["effects"][0]["refit"]
    # within 2 %: 1 % noise on 3000 samples leaves the mean's standard error ~1e-6 m; the rest is the baseline's
    assert abs(refit["effect_parameters"]["offset"] - 2e-4) < 4e-6 and refit["closed"] >= 0.9, refit
    corrected = json.loads((out / "corrected" / "corrected.json").read_text())
    carries = corrected["files"]
    assert set(carries) >= {"corrected.toml", "corrected.npz", "corrected.fmu", "corrected.mat", "note"}, carries
    assert carries["corrected.mat"] == "written by the export target 'mat'"
    assert carries["corrected.npz"].startswith("StateSpace of the model")
    assert corrected["output_offsets"]["y1"]["unit"] == "m"
    assert abs(corrected["output_offsets"]["y1"]["value"] - refit["effect_parameters"]["offset"]) < 1e-12
    for name in carries:
        if name != "note":
            assert (out / "corrected" / name).is_file(), name
            assert f"  {name}: {carries[name]}" in console, console
    assert "affine" in console and "not time-invariant" not in console
    sys_ = load_statespace(out / "corrected" / "corrected.npz")
    assert sys_.nstates > 0 and "mat_target" in sys.modules


@pytest.mark.parametrize("order", ["lag first", "offset first"])
def test_an_offset_paired_with_a_lag_is_exported(tmp_path, order):
    """The pair offset + actuator lag (either order): the StateSpace written, and with the offsets beside it
    reproducing the diagnosis' own simulation to round-off (the exact series connection: 1e-11 of the largest
    output, as the lags alone)."""
    import json

    from diagnosis.corrected.export import export_corrected, statespace_form

    cfg = bench()
    parts = (ActuatorLag(1e-3), SensorOffset("y1", 2e-4))
    parts = parts if order == "lag first" else parts[::-1]
    model = AugmentedModel(cfg, cfg.parameter_values(), parts)
    form = statespace_form(model)
    assert form.system is not None and form.output_offsets == {"y1": 2e-4}, form
    u = band_limited_input(1200, cfg.time.dt, 2.0, 150.0, seed=5)
    y_ref = simulate_effects(cfg, cfg.parameter_values(), u, parts)
    y = em.simulate(form.system, u).outputs + np.array([2e-4, 0.0])
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-11 * np.abs(y_ref).max())
    export_corrected(model, tmp_path / "c", {"effect": "pair"})
    doc = json.loads((tmp_path / "c" / "corrected.json").read_text())
    assert "corrected.npz" in doc["files"] and doc["output_offsets"]["y1"]["value"] == 2e-4


def test_a_part_whose_statespace_form_is_wrong_gives_none(tmp_path):
    """A gain that forgets to declare its StateSpace form (the default ``in_series`` leaves the system as it is) is
    caught by the probe: no StateSpace, and the reason, rather than a wrong file."""
    import json

    from diagnosis.corrected.export import export_corrected, statespace_form

    @dataclass(frozen=True)
    class Forgetful(Signal):
        description = "a gain without its StateSpace form"

        def outputs(self, y, dt, names):
            return 1.5 * np.asarray(y, dtype=float)

    cfg = bench()
    model = AugmentedModel(cfg, cfg.parameter_values(), (Forgetful(),))
    form = statespace_form(model)
    assert form.system is None and "does not reproduce" in form.reason, form
    export_corrected(model, tmp_path / "c", {"effect": "forgetful"})
    doc = json.loads((tmp_path / "c" / "corrected.json").read_text())
    assert "corrected.npz" not in doc["files"]
    assert "does not reproduce" in doc["files"]["statespace (nothing written)"], doc["files"]


def test_a_target_written_as_the_docs_say_never_exports_the_beam_without_the_effect(tmp_path, monkeypatch):
    """A new export target that writes ``item.system`` (as the docs say), handed a corrected model whose effect
    has no StateSpace form (axial drift: not time-invariant): it gets ``None`` and the reason — it cannot write
    the beam without the drift by mistake (it used to be handed that beam as ``system``); the FMU targets build
    from ``item.beam`` and say what they leave out."""
    import json
    import types

    from diagnosis.corrected.export import export_corrected
    from diagnosis.effects.axial import AxialDrift
    from identification import export_targets

    seen = []

    def write(item, out_dir):
        seen.append((item.system, item.no_system))
        return []

    module = types.ModuleType("identification.export_targets.mine")
    module.write = write
    monkeypatch.setitem(sys.modules, module.__name__, module)
    monkeypatch.setattr(export_targets, "TARGETS", dict(export_targets.TARGETS, mine=module.__name__))
    cfg = bench("clamped", "clamped")
    model = AugmentedModel(cfg, cfg.parameter_values(), (AxialDrift(5.0),))
    assert not model.time_invariant
    export_corrected(model, tmp_path / "c", {"effect": "axial_drift"}, targets=("statespace", "mine"))
    assert seen and seen[0][0] is None and "not time-invariant" in seen[0][1]
    files = json.loads((tmp_path / "c" / "corrected.json").read_text())["files"]
    assert "not time-invariant" in files["statespace (nothing written)"] and "corrected.npz" not in files


def test_no_effect_at_its_bounds_raises_what_the_search_does_not_catch():
    """Every candidate on a bench with both ends constrained and sensors of two kinds, at every corner of its
    bounds (each variable at its lower or upper bound: a zero lag, a zero stiffness, a mass at its largest), under
    the baseline at its nominal values and with the axial load at ±60 % of it: the simulation returns, or raises
    one of the errors the search catches and scores as a rejected candidate (:class:`~ebb_model.errors.EbbError`,
    ``ValueError``, ``LinAlgError``) — never another exception (a ``ZeroDivisionError`` from the recursion's
    one-tap form ended a user's diagnosis)."""
    import itertools

    from ebb_model.errors import EbbError

    cfg = bench("clamped", "clamped")
    u = band_limited_input(400, cfg.time.dt, 2.0, 150.0, seed=9)
    tried = 0
    for effect in candidate_effects(cfg, SCALES):
        k = len(effect.variables)
        corners = itertools.product(*zip(effect.lower, effect.upper)) if k <= 4 else \
            (effect.lower, effect.upper)
        for corner in corners:
            for n_scale in (0.4, 1.6):
                params = dict(cfg.parameter_values(), N=cfg.parameter_values()["N"] * n_scale)
                try:
                    model = effect.apply(cfg, params, np.array(corner, dtype=float))
                    simulate_effects(model.config, model.params, u, model.signals)
                except (EbbError, ValueError, np.linalg.LinAlgError):
                    pass
                tried += 1
    assert tried >= 2 * len(candidate_effects(cfg, SCALES))


def test_a_place_has_a_mirror_image_only_on_a_beam_alike_from_either_end():
    """On a beam the same seen from either end (its ends and its own attachments) a place and its mirror image
    shift every natural frequency alike — the refits try both (:func:`diagnosis.effects.base.mirror_image`); a
    pair's places mirror together, the other variables stay; an effect without a place, or a beam whose ends or
    attachments differ, has none."""
    from diagnosis.effects import mirror_image

    pinned = make_config("pinned", "pinned", length=2.0, actuators=[("F1", 0.3)])
    effects = {e.label: e for e in candidate_effects(pinned, SCALES)}
    s = np.array([0.1, 0.6])
    np.testing.assert_array_equal(mirror_image(effects["point_mass"], pinned, s), [0.1, 1.4])
    pair = pair_effect(effects["point_mass"], effects["grounded_spring"])
    np.testing.assert_array_equal(mirror_image(pair, pinned, np.array([0.1, 0.6, 0.3, 0.5])), [0.1, 1.4, 0.3, 1.5])
    assert mirror_image(effects["actuator_gain"], pinned, np.array([1.2])) is None
    assert mirror_image(effects["point_mass"], make_config("clamped", "pinned", length=2.0), s) is None
    # the beam's own masses: alike from either end when they mirror each other, not with one of them alone
    two = make_config("pinned", "pinned", length=2.0, masses=[("m1", 0.5, 0.2), ("m2", 1.5, 0.2)])
    one = make_config("pinned", "pinned", length=2.0, masses=[("m1", 0.5, 0.2)])
    assert mirror_image(effects["point_mass"], two, s) is not None
    assert mirror_image(effects["point_mass"], one, s) is None


def test_a_refit_moves_to_another_catalogue_by_its_physical_values():
    """Two baselines size a mass by two values of ρA L: a refit carried from one catalogue to the other keeps its
    mass and place (:func:`diagnosis.effects.variables_for`), and a value no point of the effect's bounds gives is
    refused."""
    from dataclasses import replace as dc_replace

    from diagnosis.effects import variables_for

    cfg = bench()
    one = {e.label: e for e in candidate_effects(cfg, SCALES)}
    two = {e.label: e for e in candidate_effects(cfg, dc_replace(SCALES, rhoA=1.3))}
    s = np.array([0.05, 0.65])
    moved = variables_for(two["point_mass"], one["point_mass"].physical(s), s)
    assert moved is not None and moved[0] == pytest.approx(0.05 / 1.3, rel=1e-12) and moved[1] == 0.65
    assert two["point_mass"].physical(moved) == pytest.approx(one["point_mass"].physical(s), rel=1e-12)
    crack = np.array([0.05, 0.3, 0.03])
    assert np.allclose(variables_for(two["stiffness_loss"], one["stiffness_loss"].physical(crack), crack), crack)
    assert variables_for(two["point_mass"], {"mass": 5.0, "x": 0.65}, s) is None      # beyond ρA L: out of bounds
