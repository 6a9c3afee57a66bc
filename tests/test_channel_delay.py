"""A channel's own delay (``delay`` on a sensor or a force channel, :mod:`ebb_model.acquisition.channel_delay`).

Truth: the periodic steady state of a cubic Hermite finite-element beam under a random-phase multisine to 0.4 fs,
bin by bin (:func:`~ebb_model.reference.exact_fe.periodic_fe_response`, shown converged in
``tests/test_bandlimited.py`` and again here), each sensor's bins times ``e^{−iωτ}`` — the delay exactly, with no
code shared with the model's band-limited interpolation of its output samples.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ebb_model as em
from ebb_model.acquisition.bandlimited import HALF_WIDTH
from ebb_model.acquisition.channel_delay import delay_outputs, effective_delays, without_delays
from ebb_model.errors import ConfigError
from ebb_model.modal.modal import frequency_response
from ebb_model.reference.exact_fe import periodic_fe_response
from ebb_model.reference.hermite_fe import hermite_beam
from ebb_model.io.tomlio import dumps as toml_dumps

from test_bad_input import one_line_error
from test_bandlimited import CASE, ENDS, SAMPLES, config, last_periods, multisine, noise_variances

DT = CASE["dt"]


def delayed(cfg: em.BeamConfig, sensors: tuple[float, ...], force: float = 0.0) -> em.BeamConfig:
    """``cfg`` with the sensors' and the force channel's delays, in samples."""
    d = cfg.to_dict()
    for s, k in zip(d["sensors"], sensors):
        s["delay"] = k * DT
    d["actuators"][0]["delay"] = force * DT
    return em.config_from_dict(d)


def truth(u: np.ndarray, elements: int, delays: tuple[float, ...]) -> np.ndarray:
    """The finite-element steady state with each sensor's bins delayed by ``delays`` samples (exactly)."""
    b = hermite_beam(CASE["length"], elements, left=ENDS[CASE["left"]], right=ENDS[CASE["right"]], **CASE["params"])
    y = periodic_fe_response(b, u, DT, CASE["actuator"], CASE["sensors"])
    w = 2.0 * np.pi * np.fft.rfftfreq(SAMPLES, DT)
    Y = np.fft.rfft(y, axis=0) * np.exp(-1j * np.outer(w, np.asarray(delays) * DT))
    return np.fft.irfft(Y, SAMPLES, axis=0)


@pytest.fixture(scope="module")
def broadband():
    u = multisine(0.4)
    return u, truth(u, 128, (0.0, 0.0))


@pytest.mark.parametrize("sensors, force", [((37.4, 3.0), 0.0), ((40.4, 6.0), 3.0), ((0.0, 0.0), 5.25)])
def test_a_delayed_channel_matches_the_delayed_truth(broadband, sensors, force):
    """Two accelerometers under a random force to 0.4 fs (the band-limited force between samples, 200 nodes): a
    fractional delay of 37.4 samples and a whole one of 3, the same with the force's channel 3 samples late (the
    sensors' delays taken after it), and a sensor 5.25 samples ahead of the force (a faster card): the delayed
    model against the delayed truth leaves what the undelayed model leaves against the undelayed truth.

    Error budget (measured): undelayed 0.36 / 0.66 noise variances (the grid's, ``tests/test_bandlimited.py``);
    the delay adds at most 2e-5 (the kernel's 2e-5 amplitude error is 2e-3 of a 1 % noise's standard deviation);
    asserted within 0.01 of the undelayed figure.  The truth moves by < 0.02 noise variances from 96 to 128
    elements with the delay applied (asserted below 0.05); an undelayed model against the delayed truth leaves
    thousands.  A channel ahead of the force is compared short of the record's end, which it reads beyond."""
    u, undelayed_truth = broadband
    effective = tuple(s - force for s in sensors)
    tr = truth(u, 128, effective)
    assert np.all(noise_variances(truth(u, 96, effective), tr) < 0.05)
    base = config(200, "bandlimited")
    model = em.fast_model(delayed(base, sensors, force))
    assert np.allclose(model.output_delays or (0.0, 0.0), effective, rtol=0, atol=1e-9)
    # a channel ahead of the force reads the response after the record's end, where the force is not recorded
    # (held at its last sample, as the band-limited force is): its last |d| + M samples are the record's edge
    end = SAMPLES - (math.ceil(-min(effective)) + HALF_WIDTH if min(effective) < 0 else 0)
    y = last_periods(model, u)[0]
    r = noise_variances(y[:end], tr[:end])
    r0 = noise_variances(last_periods(em.fast_model(base), u)[0][:end], undelayed_truth[:end])
    assert np.all(np.abs(r - r0) < 0.01) and np.all(r < 1.0), (r, r0)
    moved = [i for i, d in enumerate(effective) if d]
    assert np.all(noise_variances(last_periods(em.fast_model(base), u)[0], tr)[moved] > 100.0)


def test_whole_samples_shift_exactly_under_any_hold():
    """A delay of whole samples is exact under every force between samples, on the modal and the dense
    realisation: the output is the undelayed one shifted, held at its first value before the record."""
    u = np.random.default_rng(2).standard_normal((400, 1))
    for hold in ("cubic", "zoh", "foh"):
        base, cfg = config(20, hold), delayed(config(20, hold), (7.0, 0.0))
        for build in (em.fast_model, em.assemble):
            y = em.simulate(build(base), u).outputs
            yd = em.simulate(build(cfg), u).outputs
            np.testing.assert_array_equal(yd[:, 1], y[:, 1])
            np.testing.assert_array_equal(yd[7:, 0], y[:-7, 0])
            np.testing.assert_array_equal(yd[:7, 0], np.full(7, y[0, 0]))


def test_the_frequency_response_is_what_the_simulation_does():
    """The delayed model's frequency response against its own periodic steady state under the multisine (the
    response bin by bin, from the simulation): equal to 1e-4 relative over the band (the kernel's 3e-5, the
    transient's e^{-8})."""
    u = multisine(0.4)
    model = em.fast_model(delayed(config(60, "bandlimited"), (37.4, 3.0)))
    y = last_periods(model, u)[0]
    U, Y = np.fft.rfft(u), np.fft.rfft(y, axis=0)
    f = np.fft.rfftfreq(SAMPLES, DT)
    excited = np.abs(U) > 1e-6 * np.abs(U).max()
    H = frequency_response(model, f[excited]).H[:, :, 0]
    sim = Y[excited] / U[excited, None]
    assert np.max(np.abs(H - sim) / np.abs(H).max(axis=0)) < 1e-4


def test_delays_are_checked_in_the_config(tmp_path, capsys):
    """A fraction of a sample without the band-limited force between samples, a negative delay, force channels
    with different delays, a delay in the wrong unit: one line each naming the field; a delay of whole samples
    is taken under any hold, and a config round-trips its delays."""
    base = config(20, "cubic").to_dict()

    def refused(change, field: str) -> str:
        d = config(20, "cubic").to_dict()
        change(d)
        with pytest.raises(ConfigError, match=field) as info:
            em.config_from_dict(d)
        return str(info.value)

    assert "input = \"bandlimited\"" in refused(lambda d: d["sensors"][0].update(delay=2.5 * DT), "sensors.s0.delay")
    assert ">= 0 s" in refused(lambda d: d["sensors"][1].update(delay=-DT), "delay")
    d2 = dict(base, actuators=[{"name": "F1", "x": 0.55, "delay": DT}, {"name": "F2", "x": 0.3}])
    with pytest.raises(ConfigError, match="force channels' delays differ"):
        em.config_from_dict(d2)
    assert "is it in seconds" in refused(lambda d: d["sensors"][0].update(delay=2.0), "sensors.s0.delay")
    cfg = delayed(config(20, "cubic"), (4.0, 0.0), force=1.0)
    assert effective_delays(cfg) == (3.0, -1.0)
    assert em.config_from_dict(cfg.to_dict()) == cfg
    assert effective_delays(without_delays(cfg)) == ()
    toml = tmp_path / "bad.toml"
    toml.write_text(toml_dumps(dict(base, sensors=[dict(base["sensors"][0], delay=0.4 * DT),
                                                        base["sensors"][1]])))
    from ebb_cli import main
    assert main(["modes", str(toml)]) == 2
    assert "fraction of a sample" in one_line_error(capsys, "modes")


def test_the_interpolation_leaves_undelayed_columns_as_they_are():
    """A column without a delay is the column itself; no delays, the array itself (what is driven sample by sample
    carries the delays as a delay line: ``tests/test_delay_line.py``)."""
    y = np.random.default_rng(0).standard_normal((50, 2))
    out = delay_outputs(y, (0.0, 2.5))
    assert np.array_equal(out[:, 0], y[:, 0]) and not np.allclose(out[:, 1], y[:, 1])
    assert delay_outputs(y, ()) is y


def test_round_off_in_seconds_is_whole_samples():
    """A delay given in seconds at a sample time that is no binary fraction carries round-off: 3 samples at 1/3 ms
    are 3 (a whole shift, taken under the cubic), not 2.9999999999999996 (a fraction, refused there)."""
    d = config(20, "cubic").to_dict()
    d["time"]["dt"] = 1.0 / 3000.0
    d["sensors"][0]["delay"] = 3 * (1.0 / 3000.0) * (1 + 1e-15)
    assert effective_delays(em.config_from_dict(d))[0] == 3.0


def _lagged_record(tmp_path, lag_quarters: int, elements: int = 128):
    """An accelerometer record whose channel lags the force's by ``lag_quarters / 4`` samples: the independent
    truth (:func:`~ebb_model.reference.synthesize`, cubic Hermite elements exactly in time) at four times the
    sampling rate under a random force to 0.3 fs, its response read ``lag_quarters`` fine samples late — the delay
    with no code of the model's — and 1 % noise; the clamped–pinned beam of the band-limited tests, viscous
    damping only."""
    from ebb_model.reference import band_limited_input, synthesize

    n, R = 2400, 4
    d = config(60, "bandlimited").to_dict()
    d["sensors"] = [{"name": "a1", "x": 0.8, "kind": "acceleration"}]
    d["parameters"].pop("eta")                           # viscous damping only (c)
    fine = dict(d, time=dict(d["time"], dt=DT / R))
    uf = band_limited_input(n * R, DT / R, 2.0, 0.3 / DT, seed=3)
    yf = synthesize(em.config_from_dict(fine), uf, n_elements=elements, noise=0.0).outputs_clean[:, 0]
    k = np.arange(n) * R
    y = np.where(k >= lag_quarters, yf[np.clip(k - lag_quarters, 0, None)], 0.0)
    return uf[k, 0], y


def test_identify_takes_the_delay_and_says_nothing_false_without_it(tmp_path):
    """A record whose accelerometer lags the force by 10.25 samples (0.3 fs, 1 % noise), identified from a config
    as a newcomer writes it (nominal values 20–50 % off, bounds ×4): with the delay declared, default ``identify``
    reaches the floor with EI, ρA within 1 % and N within 2 % of the Euler scale; without it the fit stays far
    above the floor (a 10-sample lag is 4 rad of phase at the band's top) and no hint claims a reversed sign or a
    level the records do not have (both printed before: the start read the lag as a sign).

    Truth converged: 96 → 128 elements moves the lagged record by < 0.05 noise variances (asserted)."""
    from identification.run import identify
    from ebb_model.io.tomlio import dumps as toml_dumps

    u, y = _lagged_record(tmp_path, 41)
    _, y96 = _lagged_record(tmp_path, 41, elements=96)
    sigma = 0.01 * y.std()
    assert np.mean((y96 - y) ** 2) / sigma ** 2 < 0.05
    y = y + sigma * np.random.default_rng(5).standard_normal(y.size)
    rec = tmp_path / "rec.csv"
    np.savetxt(rec, np.column_stack([np.arange(y.size) * DT, u, y]), delimiter=",", header="time,F1,a1",
               comments="")
    truth = {"EI": 10.0, "rhoA": 1.0, "N": 20.0}
    for declared in (True, False):
        d = config(60, "bandlimited").to_dict()
        d["sensors"] = [{"name": "a1", "x": 0.8, "kind": "acceleration", **({"delay": 10.25 * DT} if declared
                                                                            else {})}]
        d["parameters"] = {"EI": {"value": 6.0, "identify": True, "bounds": [1.5, 24.0]},
                           "rhoA": {"value": 1.5, "identify": True, "bounds": [0.375, 6.0]},
                           "c": {"value": 1.2, "identify": True, "bounds": [0.3, 4.8]},
                           "N": {"value": 30.0, "identify": True, "bounds": [-120.0, 120.0]}}
        cfg = tmp_path / f"declared_{declared}.toml"
        cfg.write_text(toml_dumps(d))
        ident = identify(cfg, [rec], tmp_path / f"run_{declared}", progress=False, export=False).identified
        p, hints = ident["parameters"], " ".join(ident.get("hints", ()))
        if declared:
            assert ident["fit_gap_ratio"]["a1"] < 1.2, ident
            assert abs(p["EI"] / truth["EI"] - 1) < 0.01 and abs(p["rhoA"] / truth["rhoA"] - 1) < 0.01, p
            euler = math.pi ** 2 * truth["EI"] / 1.0 ** 2
            assert abs(p["N"] - truth["N"]) < 0.02 * euler, p
        else:
            assert ident["fit_gap_ratio"]["a1"] > 100.0, ident
            assert "opposite in sign" not in hints and "reversed sign" not in hints, hints
            assert "level asks for" not in hints, hints
