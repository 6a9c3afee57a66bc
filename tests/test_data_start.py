"""What the records say before the search (identification.record_peaks, identification.data_start), the beam's
own coordinates of the polish (identification.coordinates) and the flags of a fit (identification.fit_hints)."""
from __future__ import annotations

import numpy as np
import pytest

from first_records import CASES, write_case
from ebb_model.reference import analytic_frequencies_hz
from identification.coordinates import BeamCoordinates
from identification.data_start import data_start
from identification.fit_hints import bound_flags, fit_hints
from identification.native import NativeEvaluator
from identification.parameters import parameter_space
from identification.record_peaks import resonance_peaks
from identification.run import _arrays, load_identification_config, read_data

CASE = {c.name: c for c in CASES}


def _evaluator(case, tmp_path):
    cfg_path, rec_path = write_case(case, tmp_path)
    cfg = load_identification_config(cfg_path)
    exps = read_data(cfg, [rec_path])
    return NativeEvaluator(cfg, parameter_space(cfg), _arrays(cfg, exps), stabilising=False)


def test_coordinates_round_trip_and_the_level_is_one_coordinate():
    names = ("EI", "rhoA", "c", "N", "x_F1")
    lo, hi = np.array([1.0, 0.1, 0.0, -50.0, 0.1]), np.array([40.0, 4.0, 5.0, 50.0, 0.9])
    bc = BeamCoordinates.of(names, lo, hi)
    x = np.array([10.0, 1.2, 0.7, 20.0, 0.4])
    t = bc.to_internal(x)
    np.testing.assert_allclose(bc.to_physical(t), x, rtol=1e-14)
    # one step of log rhoA scales EI, rhoA, c and N together (the outputs' level) and nothing else
    t2 = t.copy()
    t2[1] += np.log(1.1)
    np.testing.assert_allclose(bc.to_physical(t2), x * np.array([1.1, 1.1, 1.1, 1.1, 1.0]), rtol=1e-13)
    box = bc.box()
    assert np.all(box.lower <= t) and np.all(t <= box.upper)
    # outside the original box, a point is clipped back into it
    far = bc.to_physical(box.upper)
    assert np.all(far <= hi) and np.all(far >= lo)
    # EI known: the identity
    assert not BeamCoordinates.of(("rhoA", "c"), lo[1:3], hi[1:3]).active


@pytest.mark.parametrize("name", ["cantilever-velocity-chirp", "clamped-pinned-accel-hammer"])
def test_resonance_peaks_find_every_excited_mode(name, tmp_path):
    """Every mode of the truth in the excited band (a tenth of the sampling rate; the hammer's, 20 dB down
    before its first spectral zero at 200 Hz) and above four Welch bins (segments of a quarter of the record: a
    mode at 1.6 Hz on 1 Hz bins is not resolved, and the start matches the others) stands as a peak within 3 % or
    one bin, whichever is wider (the three-bin vertex of a lightly damped peak under a Hann window is biased by up
    to half a bin: 9.47 Hz for 9.92 Hz measured; the time-domain refinement of the start takes it from there)."""
    case = CASE[name]
    ev = _evaluator(case, tmp_path)
    exps = ev.experiments
    peaks, prominence = resonance_peaks([e.inputs for e in exps], [e.outputs for e in exps], case.dt)
    f = analytic_frequencies_hz(case.left, case.right, length=case.length, EI=case.truth["EI"],
                                rhoA=case.truth["rhoA"], N=case.truth.get("N", 0.0), n_modes=8)
    top = 0.1 / case.dt if case.excitation != "hammer" else 100.0
    for fm in f[(f > 16.0 / case.duration) & (f < top)]:
        assert np.min(np.abs(peaks - fm)) <= max(0.03 * fm, 4.0 / case.duration), (fm, peaks)
    assert prominence.shape == peaks.shape and np.all(prominence >= 6.0)


@pytest.mark.parametrize("name", ["cantilever-accel-random", "pinned-tension-velocity-chirp"])
def test_the_records_start_has_the_truths_frequency_scale(name, tmp_path):
    """From a config 30–60 % off: the start's EI/ρA within 1 % of the truth's (the level and the damping are the
    polish's), inside the bounds."""
    case = CASE[name]
    ev = _evaluator(case, tmp_path)
    start = data_start(ev)
    assert start is not None and start.n_evaluations > 0
    p = dict(zip(ev.space.names, start.x))
    assert abs((p["EI"] / p["rhoA"]) / (case.truth["EI"] / case.truth["rhoA"]) - 1.0) < 0.01, p
    assert np.all(start.x >= ev.space.lower) and np.all(start.x <= ev.space.upper)
    assert not start.notes


def test_bound_flags_and_hints():
    flags = bound_flags(("EI", "c"), np.array([1.0, 0.05]), np.array([20.0, 5.0]), np.array([7.0, 0.05]))
    assert flags == {"c": {"bound": "lower", "value": 0.05}}
    rng = np.random.default_rng(0)
    y = rng.standard_normal((500, 2))
    # the model's output is the record / 1000 (a record in mm read as m): both sensors want a gain of 1000
    hints = fit_hints(("a1", "a2"), [y], [y / 1000.0], {"a1": 1e4, "a2": 1e4}, level_free=True)
    assert any("gain of 1000 on a1" in h for h in hints) and any("common scale of 0.001" in h for h in hints)
    # a reversed sign is named as that
    assert "reversed sign" in fit_hints(("a1",), [y[:, :1]], [-y[:, :1]], {"a1": 400.0}, level_free=False)[0]
    # a fit at the floor gets no hint
    assert fit_hints(("a1",), [y[:, :1]], [y[:, :1]], {"a1": 1.0}, level_free=True) == []
