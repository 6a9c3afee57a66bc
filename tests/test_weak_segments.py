"""A local loss of bending stiffness (``[[weak_segments]]``; issue 31: a crack, a loose joint, a damaged clamp).

Reference: the generator's Hermite FE truth with the segment's ends on element boundaries (exact there), its own
convergence shown (80 → 160 elements changes the five lowest modes by at most 6.4e-7, so the 160-element truth
is about 4e-8 from its limit — h⁴ —, far below the 1e-5 the model is held to).  The FD model writes the
bending term as the second difference of the nodal moments with each cell's compliance-averaged EI; with a
uniform EI that is the D4 stencil exactly.  The FMUs carry the segments (``fmu_configs.mixed_config`` has one, so
every FMU test simulates it).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ebb_model import assemble, config_from_dict
from ebb_model.errors import ConfigError
from ebb_model.modal.modal import discrete_frequencies
from ebb_model.reference.hermite_fe import hermite_beam

from conftest import make_config

#: A cantilever (EI 10, ρA 1, L 1) with EI × 0.4 over 0.275 … 0.325 m.
SEGMENT = (0.3, 0.05, 0.4)


def _config(nodes: int, segment=SEGMENT):
    d = make_config("clamped", "free", nodes=nodes).to_dict()
    if segment is not None:
        d["weak_segments"] = [{"name": "crack", "x": segment[0], "length": segment[1], "factor": segment[2]}]
    return config_from_dict(d)


def _fe(ne: int, weak=True) -> np.ndarray:
    a, b = SEGMENT[0] - SEGMENT[1] / 2, SEGMENT[0] + SEGMENT[1] / 2
    return hermite_beam(1.0, ne, EI=10.0, rhoA=1.0, left=(math.inf, math.inf), right=(0.0, 0.0),
                        weak_segments=[(a, b, SEGMENT[2])] if weak else ()).natural_frequencies_hz(5)


def test_a_segment_of_full_stiffness_changes_nothing():
    f_full, _ = discrete_frequencies(_config(49, (0.3, 0.05, 1.0)), None, 5)
    f_plain, _ = discrete_frequencies(_config(49, None), None, 5)
    np.testing.assert_array_equal(f_full, f_plain)


def test_weak_segment_against_the_converged_fe_truth():
    truth, finer = _fe(80), _fe(160)
    assert np.max(np.abs(truth / finer - 1.0)) < 1e-6          # measured 6.4e-7 (mode 5)
    effect = finer / _fe(160, weak=False) - 1.0
    assert effect[0] < -0.04 and effect[2] < -0.04             # the crack matters: measured −4.9 %, −5.3 %
    errors = [np.abs(discrete_frequencies(_config(n), None, 5)[0] / finer - 1.0) for n in (39, 79)]
    # the model converges towards the truth: measured 1.3e-7 … 9.0e-5 at 39 nodes, 5.6e-9 … 5.8e-6 at 79 —
    # far below the effect itself
    assert np.all(errors[1] < 1e-5) and np.all(errors[1] <= errors[0])
    assert np.max(errors[1]) < 1e-3 * np.max(np.abs(effect))


def test_weak_segments_round_trip_and_lower_the_stiffness():
    cfg = _config(30)
    again = config_from_dict(cfg.to_dict())
    assert again.weak_segments == cfg.weak_segments
    u = np.random.default_rng(2).standard_normal((300, 1))
    from ebb_model import simulate

    y, plain = simulate(assemble(cfg), u).outputs, simulate(assemble(_config(30, None)), u).outputs
    assert np.max(np.abs(y - plain)) > 0.02 * np.max(np.abs(plain))


@pytest.mark.parametrize("segment,field", [
    ({"name": "w", "x": 0.5, "length": 0.05, "factor": 0.0}, "weak_segments[0].factor"),
    ({"name": "w", "x": 0.5, "length": 0.05, "factor": 1.5}, "weak_segments[0].factor"),
    ({"name": "w", "x": 0.5, "length": -0.05, "factor": 0.5}, "weak_segments[0].length"),
    ({"name": "w", "x": 0.99, "length": 0.05, "factor": 0.5}, "weak_segments[0].length"),
    ({"name": "w", "x": 0.5, "factor": 0.5}, "weak_segments[0].length"),
    ({"name": "w", "x": 0.5, "length": 0.05, "factor": float("nan")}, "weak_segments[0].factor"),
    ({"name": "y1", "x": 0.5, "length": 0.05, "factor": 0.5}, "names"),
])
def test_bad_weak_segments_name_the_field(segment, field):
    d = make_config().to_dict()
    d["weak_segments"] = [segment]
    with pytest.raises(ConfigError) as ei:
        config_from_dict(d)
    assert field in str(ei.value)
