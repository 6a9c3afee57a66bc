"""A channel's converter delay in what is driven sample by sample (:mod:`ebb_model.acquisition.delay_line`): the
StateSpace for control design, the Python FMU through fmpy, the exports of an identified model.

Truth: the native run, which delays each output after the whole record is simulated
(:func:`~ebb_model.acquisition.channel_delay.delay_outputs`, checked against the finite-element truth delayed bin
by bin in ``tests/test_channel_delay.py``) — the delay line must reproduce it from the past alone; and that
finite-element truth itself for the fraction of a sample a causal model interpolates.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import ebb_model as em
from ebb_model.acquisition.bandlimited import causal_config
from ebb_model.acquisition.channel_delay import effective_delays
from ebb_model.acquisition.delay_line import MIN_FRACTIONAL, delay_line, delay_taps, exported_config, line_problems
from ebb_model.errors import ConfigError
from ebb_model.io.tomlio import dumps as toml_dumps

from test_bad_input import one_line_error
from test_bandlimited import config, last_periods, multisine, noise_variances
from test_channel_delay import DT, delayed, truth

sys.path.insert(0, str(Path(__file__).resolve().parent / "fmu_hosts"))
from fmu_loops import fmpy_outputs  # noqa: E402

#: (sensors' delays, the force channel's delay, the force between samples), in samples: whole delays, a force
#: channel late too, a fraction far from and one at the shortest causal delay (its kernel reaches the current
#: sample: feedthrough).
CASES = [((3.0, 7.0), 0.0, "cubic"), ((4.0, 2.0), 1.0, "cubic"), ((37.4, 3.0), 0.0, "bandlimited"),
         ((MIN_FRACTIONAL + 0.5, 0.0), 0.0, "bandlimited")]


def causal(sensors: tuple[float, ...], force: float, hold: str, nodes: int = 20) -> em.BeamConfig:
    """The delayed config as a model driven sample by sample takes it (:func:`causal_config`)."""
    return causal_config(delayed(config(nodes, hold), sensors, force))


def _rel(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(y - ref) / np.abs(ref).max(axis=0)))


@pytest.mark.parametrize("sensors, force, hold", CASES)
def test_the_delay_line_is_the_native_delay(sensors, force, hold):
    """The delay line realised and iterated from rest equals the native run (delayed after the record) to
    round-off — the same products summed in another order (measured 1.5e-15 of the largest output) — on the dense
    and on the modal realisation, and through python-control from the saved system's rest state; one state per
    sample of the longest lag of each delayed channel."""
    import control

    cfg = causal(sensors, force, hold)
    u = np.random.default_rng(3).standard_normal((600, 1))
    for system in (em.assemble(cfg), em.assemble_modal(cfg)):
        native = system if system.output_delays else em.assemble(cfg)       # assemble_modal realises the line
        y_native = em.simulate(native, u).outputs
        lined = delay_line(system)
        assert lined.output_delays == ()
        assert _rel(em.simulate(lined, u).outputs, y_native) < 1e-12
    lags = [int(delay_taps(s - force)[0].max()) for s in sensors if s != force]
    assert lined.nstates == em.assemble_modal(causal((0.0, 0.0), 0.0, hold)).nstates + sum(lags)
    ctl = em.assemble(cfg).to_control()
    assert ctl.nstates == em.assemble(cfg).nstates + sum(lags) and ctl.dt == DT
    rest = -(delay_line(em.assemble(cfg)).hold @ u[0])
    y_ctl = control.forced_response(ctl, np.arange(len(u)) * DT, u.T, X0=rest).outputs.T
    assert _rel(y_ctl, em.simulate(em.assemble(cfg), u).outputs) < 1e-10


def test_a_fraction_in_a_causal_model_adds_nothing_to_its_error():
    """The kernel interpolates the causal model's (cubic) output samples, which are not strictly band-limited: against
    the finite-element truth delayed bin by bin, a channel 37.4 samples late leaves what the undelayed causal model
    leaves against the undelayed truth (measured: 3.68 / 4.81 noise variances both, within 8e-4, under a force to
    0.2 fs — the cubic's own error, docs/model.md); asserted within 0.01."""
    u = multisine(0.2)
    undelayed = noise_variances(last_periods(em.assemble_modal(causal((0.0, 0.0), 0.0, "bandlimited", 200)), u)[0],
                                truth(u, 128, (0.0, 0.0)))
    lined = noise_variances(last_periods(em.assemble_modal(causal((37.4, 3.0), 0.0, "bandlimited", 200)), u)[0],
                            truth(u, 128, (37.4, 3.0)))
    assert np.all(np.abs(lined - undelayed) < 0.01), (lined, undelayed)


def test_what_has_no_causal_delay_line_is_refused_in_one_line(tmp_path, capsys):
    """A sensor ahead of the force's channel (it would read the force ahead) and a fraction shorter than
    ``MIN_FRACTIONAL`` samples (the kernel reads that many samples after the one it delays) are refused by the
    StateSpace and by ``ebb build-fmu`` — one line naming the channel, no file; the native model takes both, and the
    exports leave them out saying why."""
    from ebb_cli import main

    ahead = delayed(config(20, "cubic"), (4.0, 0.0), force=1.0)
    short = delayed(config(20, "bandlimited"), (2.5, 0.0))
    for cfg, words in ((ahead, "s1 is 1 sample ahead"), (short, "s0 is 2.5 samples late")):
        assert len(line_problems(cfg)) == 1 and words in line_problems(cfg)[0]
        with pytest.raises(ConfigError, match=words):
            em.assemble(causal_config(cfg)).to_control()
        path = tmp_path / "delayed.toml"
        path.write_text(toml_dumps(cfg.to_dict()))
        assert main(["build-fmu", str(path), "--out", str(tmp_path / "b.fmu")]) == 2
        assert words in one_line_error(capsys, "build-fmu")
        assert not (tmp_path / "b.fmu").exists()
        em.simulate(em.assemble(cfg), np.ones((50, 1)))               # the records' model takes it
        exported, said = exported_config(cfg)                         # the exports leave them out and say why
        assert effective_delays(exported) == () and "leave the channels' converter delays out" in said
        assert words in said
    assert exported_config(delayed(config(20, "cubic"), (4.0, 0.0)))[1] == ""


def test_the_python_fmu_carries_the_delays(tmp_path):
    """The Python FMU of a config with whole and fractional delays, through fmpy, equals the native run of the same
    causal model to 1e-10 (the FMU tests' bound against the core, ``tests/test_fmu_fmpy.py``); a channel whose
    kernel does not reach the current sample shows no feedthrough in the model description."""
    from fmpy import read_model_description

    from fmu_build import build_fmu

    u = np.random.default_rng(8).standard_normal((700, 1))
    for sensors, hold in (((3.0, 7.0), "cubic"), ((37.4, 0.0), "bandlimited")):
        cfg = delayed(config(20, hold), sensors)
        fmu = build_fmu(cfg, tmp_path / f"delayed_{hold}.fmu")
        ref = em.simulate(em.assemble(causal_config(cfg)), u).outputs
        assert _rel(fmpy_outputs(fmu, u), ref) < 1e-10
        structure = {o.variable.name: o.dependencies for o in read_model_description(str(fmu)).outputs}
        for s, d in zip(cfg.sensors, sensors):
            assert (structure[s.name] == []) == (d != 0.0), structure     # accelerometers: D ≠ 0 undelayed


def test_the_exports_of_an_identified_model_carry_the_delays(identify_case, tmp_path):
    """``ebb identify`` of a config whose sensors report 3 and 5 samples late: the exported StateSpace is the design
    model with its delay line (its response from the saved rest state equals the design model's native delayed
    run), and the exported FMU equals the native run of the whole beam at the exported parameters, through fmpy."""
    from ebb_cli import main
    from ebb_model.modal.truncation import design_model
    from identification.export_statespace import load_metadata, load_statespace, rest_state

    cfg_path, data, _ = identify_case
    d = em.load_config(cfg_path).to_dict()
    for s, k in zip(d["sensors"], (3, 5)):
        s["delay"] = k * 1e-4
    cfg_path.write_text(toml_dumps(d))
    out = tmp_path / "run"
    assert main(["identify", str(cfg_path), str(data), "--out", str(out), "--pop", "6", "--generations", "2",
                 "--no-progress", "--target", "statespace", "fmu"]) == 0
    npz, fmu = out / "export" / "point_0.npz", out / "export" / "point_0.fmu"
    params = load_metadata(npz)["parameters"]
    cfg = em.config_from_dict(d).with_parameters(**params)
    u = np.random.default_rng(2).standard_normal((500, 1))
    import control
    ctl = load_statespace(npz)
    assert sum(n.startswith("delay(") for n in ctl.state_labels) == 3 + 5
    y = control.forced_response(ctl, np.arange(len(u)) * 1e-4, u.T, X0=rest_state(npz, u[0])).outputs.T
    assert _rel(y, em.simulate(design_model(cfg), u).outputs) < 1e-10
    assert _rel(fmpy_outputs(fmu, u), em.simulate(em.assemble(causal_config(cfg)), u).outputs) < 1e-10


def test_the_corrected_model_carries_the_delays_under_its_signal_effects(tmp_path):
    """The diagnosis' corrected model of a config whose sensors report 4 and 9 samples late, with a lag on the
    delayed accelerometer: its StateSpace (``corrected.npz``, from the saved rest state) equals the design model's
    native delayed run through that lag (the lag on the delayed signal: both LTI and started steady at the first
    sample, they commute exactly for whole samples) to 1e-10, and ``corrected.json`` says nothing was left out."""
    import json

    import control

    from diagnosis.corrected.export import export_corrected
    from diagnosis.effects import AugmentedModel
    from diagnosis.effects.lag import SensorLag
    from ebb_model.modal.truncation import design_model
    from ebb_model.reference.excitation import band_limited_input
    from identification.export_statespace import load_statespace, rest_state

    cfg = delayed(config(20, "cubic"), (4.0, 9.0))
    params = cfg.parameter_values() | {"EI": 10.4}
    lag = (SensorLag("s1", 1.5e-3),)
    files = export_corrected(AugmentedModel(cfg, params, lag), tmp_path / "corrected", {"effect": "sensor_lag[s1]"},
                             targets=("statespace",))
    npz = tmp_path / "corrected" / "corrected.npz"
    assert npz in files
    u = band_limited_input(900, DT, 2.0, 300.0, seed=6)
    ctl = load_statespace(npz)
    y = control.forced_response(ctl, np.arange(len(u)) * DT, u.T, X0=rest_state(npz, u[0])).outputs.T
    design = em.simulate(design_model(cfg.with_parameters(**params)), u).outputs
    ref = lag[0].outputs(design, DT, tuple(cfg.output_names))
    assert _rel(y, ref) < 1e-10
    doc = json.loads((tmp_path / "corrected" / "corrected.json").read_text())
    assert "channel delays" not in doc["files"] and "delay-line states" in doc["files"]["corrected.npz"]
