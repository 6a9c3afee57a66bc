"""The acquisition's anti-alias filter on a sensor (ebb_model/acquisition/antialias.py): exact in time, in every route.

Truth, independent of the code under test:

* the Butterworth filter against ``scipy.signal.butter`` (its own pole placement and polynomial form);
* the filtered model's two discretisations against each other: the pole route (the filter's partial fractions
  appended to the beam's diagonal form, ``exact_modal``) and the dense route (the filter's own states in series
  after the beam, one matrix exponential, ``exact_statespace``) share only the beam's continuous modal matrices;
* the anti-alias physics: a mode above the Nyquist frequency reaches the record attenuated by the filter's gain at
  the mode's own frequency (an analog filter before the sampler), not at its alias's (a digital filter after).
"""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as ss

from ebb_model import config_from_dict, load_config, simulate
from ebb_model.acquisition.antialias import AntiAlias
from ebb_model.errors import ConfigError
from ebb_model.exact.exact_modal import exact_modal, exact_statespace
from ebb_model.modal.modal import frequency_response
from ebb_model.parameter_values import resolve_parameters
from ebb_model.simulate import fast_model
from ebb_model.modal.truncation import design_modal_model

sys.path.insert(0, str(Path(__file__).resolve().parent / "fmu_hosts"))
from fmu_configs import mixed_config  # noqa: E402
from fmu_loops import fmpy_outputs  # noqa: E402

SEED = Path(__file__).resolve().parents[1] / "examples" / "seed_clamped.toml"


def _rel(y: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)


def filtered_mixed(orders=(3, 4, 5)) -> dict:
    """The FMU tests' mixed bench (two forces, displacement/velocity/acceleration sensors, a point mass coupling
    the damping, a spring, a weak segment, an elastic end), each sensor behind its own Butterworth."""
    d = mixed_config()
    for s, order, corner in zip(d["sensors"], orders, (900.0, 1500.0, 2000.0)):
        s["antialias"] = {"order": order, "corner": corner}
    return d


@pytest.mark.parametrize("order", [1, 2, 3, 4, 5, 8])
def test_the_filter_is_the_butterworth_low_pass(order):
    f = AntiAlias(order, 250.0)
    b, a = ss.butter(order, 2 * np.pi * 250.0, analog=True)
    w = 2 * np.pi * np.array([1.0, 50.0, 250.0, 400.0, 2000.0])
    _, h = ss.freqs(b, a, w)
    np.testing.assert_allclose(f.response(1j * w), h, rtol=1e-11)
    assert abs(abs(f.response(2j * np.pi * 250.0)) - 2 ** -0.5) < 1e-12          # -3 dB at the corner
    # the group delay at DC: the phase slope of scipy's polynomial form (central difference, error ~ (dω)^2)
    dw = 1e-3
    _, h2 = ss.freqs(b, a, [dw, 2 * dw])
    slope = -(np.unwrap(np.angle(h2))[1] - np.angle(h2)[0]) / dw
    assert abs(f.group_delay - slope) < 1e-8 * f.group_delay


def test_the_pole_route_and_the_dense_route_agree():
    cfg = config_from_dict(filtered_mixed())
    p = resolve_parameters(cfg, None)
    modal, dense = exact_modal(cfg, p), exact_statespace(cfg, p)
    assert modal.filters == 6       # 3 + 4 + 5 poles, one silent partner for the two lone real poles: 12 → 6 blocks
    rng = np.random.default_rng(3)
    u = rng.standard_normal((3000, 2))
    y_modal, y_dense = simulate(modal, u).outputs, simulate(dense, u).outputs
    # two discretisations of one continuous system: round-off of the dense exponential (norm ~ |A| dt ~ 1e2)
    assert np.all(_rel(y_modal, y_dense) < 1e-9)
    # the filtered acceleration has no feedthrough from the force at the same sample beyond the input's
    # reconstruction (the lookahead of the cubic): the unfiltered one has its mass-line term as well
    plain = exact_modal(config_from_dict(mixed_config()), p)
    assert np.all(np.abs(modal.D[2]) < 0.05 * np.abs(plain.D[2]).max())
    assert np.all(_rel(y_modal, simulate(plain, u).outputs) > 1e-3)          # the filters change the record


def test_a_mode_above_nyquist_is_attenuated_at_its_own_frequency():
    """The alias of each mode between 0.55 and 0.95 fs, with and without a 6th-order filter at 0.4 fs: it drops by
    the filter's gain at the mode (analog, before the sampler), not at the alias (a digital filter's, ~1)."""
    cfg = load_config(SEED)                      # clamped-clamped; sensor y2 at 0.75 L sees every mode
    p = resolve_parameters(cfg, None)
    fs = 1.0 / cfg.time.dt
    filt = AntiAlias(6, 0.4 * fs)
    filtered = replace(cfg, sensors=tuple(replace(s, antialias=filt) for s in cfg.sensors))
    plain_model, filtered_model = fast_model(cfg, p), fast_model(filtered, p)
    freqs = plain_model.frequencies_hz
    above = np.sort(freqs[(freqs > 0.55 * fs) & (freqs < 0.95 * fs)])
    assert above.size >= 10
    for f_mode in above:
        # the undamped image's peak, right at the alias, is a pole (1/0): read the pole's residue instead, the
        # mean of the ratio a hair (1e-12 relative) either side, which cancels the other modes' share to first
        # order (measured: |H(f_mode)| to 1.2e-5; 9e-4 at 1e-11, 1e-1 at 1e-10 — the quadratic remainder)
        f_alias = (fs - f_mode) * (1.0 + np.array([-1e-12, 1e-12]))
        ratio = np.mean(np.abs(frequency_response(filtered_model, f_alias).H[:, 1, 0])
                        / np.abs(frequency_response(plain_model, f_alias).H[:, 1, 0]))
        at_mode, at_alias = abs(filt.response(2j * np.pi * f_mode)), abs(filt.response(2j * np.pi * (fs - f_mode)))
        np.testing.assert_allclose(ratio, at_mode, rtol=1e-4, err_msg=f"mode at {f_mode:.0f} Hz")
        assert at_alias > 0.5 and at_mode < 0.15     # the two readings differ: at least 3.9-fold, up to 200-fold


def test_the_filter_keeps_through_the_design_model_and_the_axial_kernel():
    from diagnosis.problem.axial_modal import simulate_axial_exact

    cfg = config_from_dict(filtered_mixed((4, 2, 6)))
    p = resolve_parameters(cfg, None)
    rng = np.random.default_rng(5)
    u = rng.standard_normal((2000, 2))
    y = simulate(fast_model(cfg, p), u).outputs
    # the axial perturbation's kernel with no perturbation is the exact model, filters included
    assert np.all(_rel(simulate_axial_exact(cfg, p, u), y) < 1e-11)
    design = design_modal_model(cfg, p)
    assert design.filters == exact_modal(cfg, p).filters            # a design model never drops a filter
    names = design.to_statespace().state_names
    assert sum(n.startswith("filter") for n in names) == 2 * design.filters


def test_the_pythonfmu_fmu_carries_the_filter(tmp_path):
    from fmu_build import build_fmu

    cfg = config_from_dict(filtered_mixed())
    fmu = build_fmu(cfg, tmp_path / "filtered.fmu")
    rng = np.random.default_rng(7)
    u = rng.standard_normal((400, 2))
    y_fmu = fmpy_outputs(fmu, u, protocol="before")
    y = simulate(fast_model(cfg), u).outputs
    assert np.all(_rel(y_fmu, y) < 1e-10)


def test_the_standalone_fmu_carries_the_filter_in_both_interfaces(tmp_path):
    """Co-simulation: the C model (the filters' states in series, integrated with the beam by one matrix
    exponential) equals the Python model to the two eigen-solvers' round-off.  Model exchange: the ODE the FMU
    gives a host is the beam's modal system with each filter in series on its sensor's continuous output."""
    import fmpy
    from test_fmu_standalone import _me_instance, _state_matrix

    from ebb_model.acquisition.antialias import series_statespace
    from ebb_model.exact.exact_modal import modal_matrices, modal_state_matrix
    from fmu_build.standalone import build_standalone_fmu

    cfg = config_from_dict(filtered_mixed())
    fmu = build_standalone_fmu(cfg, tmp_path / "filtered_standalone.fmu")
    rng = np.random.default_rng(7)
    u = rng.standard_normal((400, 2))
    y_fmu = fmpy_outputs(fmu, u, protocol="before")
    # budget: the Python and C eigen-solvers differ by round-off (test_fmu_standalone.py: 1e-10 on every record)
    assert np.all(_rel(y_fmu, simulate(fast_model(cfg), u).outputs) < 1e-10)

    md = fmpy.read_model_description(str(fmu))
    mm = modal_matrices(cfg, cfg.parameter_values())
    k, nf = mm.frequencies2.size, sum(s.antialias.order for s in cfg.sensors)
    assert md.numberOfContinuousStates == 2 * k + nf
    names = [v.name for v in md.modelVariables]
    assert sum(n.startswith("filters.") for n in names) == sum(n.startswith("der(filters.") for n in names) == nf
    me, _ = _me_instance(fmu)
    A = _state_matrix(me, 2 * k + nf)
    ref, _, _, _ = series_statespace(modal_state_matrix(mm.frequencies2, mm.Cm),
                                     np.vstack([np.zeros_like(mm.Fm), mm.Fm]), mm.C, mm.D,
                                     [s.antialias for s in cfg.sensors])
    # the filters' own sections are the same realisation; the modes are defined up to their sign
    np.testing.assert_allclose(A[2 * k:, 2 * k:], ref[2 * k:, 2 * k:], rtol=1e-12, atol=1e-12 * abs(ref).max())
    np.testing.assert_allclose(np.abs(A), np.abs(ref), atol=1e-10 * abs(ref[2 * k:]).max())


def test_the_config_round_trips_and_bad_filters_are_named():
    cfg = config_from_dict(filtered_mixed())
    again = config_from_dict(cfg.to_dict())
    assert [s.antialias for s in again.sensors] == [s.antialias for s in cfg.sensors]
    bad = {"order": ({"order": 0, "corner": 100.0}, "antialias.order"),
           "float order": ({"order": 2.0, "corner": 100.0}, "antialias.order"),
           "high": ({"order": 11, "corner": 100.0}, "antialias.order"),
           "corner": ({"order": 2, "corner": -1.0}, "antialias.corner"),
           "nan": ({"order": 2, "corner": float("nan")}, "antialias.corner"),
           "missing": ({"order": 2}, "antialias.corner"),
           "far above": ({"order": 2, "corner": 1e9}, "antialias.corner"),
           "unknown": ({"order": 2, "corner": 100.0, "kind": "bessel"}, "antialias"),
           "not a table": (4, "antialias")}
    for label, (table, where) in bad.items():
        d = mixed_config()
        d["sensors"][0]["antialias"] = table
        with pytest.raises(ConfigError) as err:
            config_from_dict(d)
        assert f"sensors[0].{where}" in str(err.value), label
    d = filtered_mixed()
    d["time"]["scheme"] = "theta"
    with pytest.raises(ConfigError, match="needs scheme"):
        config_from_dict(d)


def test_the_model_matches_an_independent_truth_behind_the_same_filters():
    """The finite-element truth (Hermite elements, exact in time under the spline force) with scipy's Butterworth
    poles realised in series on each channel, against the model: the filter adds nothing to the model's own error
    (its grid's), while it changes the record by far more than that error."""
    from ebb_model.reference.excitation import band_limited_input
    from ebb_model.reference.synthetic import synthesize

    d = {"beam": {"length": 1.0, "nodes": 60, "left": "clamped", "right": "free"}, "time": {"dt": 2.5e-4},
         "parameters": {"EI": {"value": 12.0}, "rhoA": {"value": 1.5}, "c": {"value": 0.3}, "eta": {"value": 2e-5},
                        "N": {"value": 0.0}},
         "actuators": [{"name": "F1", "x": 0.7}],
         "sensors": [{"name": "d1", "x": 0.5, "kind": "displacement"},
                     {"name": "a1", "x": 0.9, "kind": "acceleration"}]}
    plain = config_from_dict(d)
    fs = 1.0 / plain.time.dt
    u = band_limited_input(4000, plain.time.dt, 5.0, 0.2 * fs, seed=1)
    truth_plain = synthesize(plain, u, noise=0.0).outputs
    err_plain = _rel(simulate(fast_model(plain), u).outputs, truth_plain)       # measured 7.1e-4, 1.3e-2
    for filt in (AntiAlias(4, 0.3 * fs), AntiAlias(7, 0.25 * fs)):
        cfg = replace(plain, sensors=tuple(replace(s, antialias=filt) for s in plain.sensors))
        truth = synthesize(cfg, u, noise=0.0).outputs
        err = _rel(simulate(fast_model(cfg), u).outputs, truth)
        # budget: the grid's error itself, passed through the filter (measured within 2.5 % of the plain one)
        assert np.all(err < 1.1 * err_plain), (filt, err, err_plain)
        assert np.all(_rel(truth, truth_plain) > 5 * err_plain), filt     # the filter is far from negligible


def test_a_filter_on_the_force_channel_cancels_the_sensors_identical_one():
    """One acquisition records every channel through the same filter: the record relates the filtered force to
    the filtered outputs exactly as the bare beam relates force and response (H G H⁻¹ = G); any other combination
    would need the force's filter undone and is refused, naming the channel."""
    from fmu_build.standalone.description import n_filter_states

    plain = mixed_config()
    same = mixed_config()
    for channel in same["actuators"] + same["sensors"]:
        channel["antialias"] = {"order": 4, "corner": 1500.0}
    cfg, ref = config_from_dict(same), config_from_dict(plain)
    assert config_from_dict(cfg.to_dict()).actuators == cfg.actuators
    u = np.random.default_rng(2).standard_normal((1000, 2))
    np.testing.assert_array_equal(simulate(fast_model(cfg), u).outputs, simulate(fast_model(ref), u).outputs)
    assert n_filter_states(cfg) == 0                      # the standalone FMU carries no filter states either
    lacking = mixed_config()
    lacking["actuators"][0]["antialias"] = lacking["actuators"][1]["antialias"] = {"order": 4, "corner": 1500.0}
    lacking["sensors"][1]["antialias"] = {"order": 4, "corner": 1500.0}
    with pytest.raises(ConfigError) as err:
        config_from_dict(lacking)
    assert "sensors.d1.antialias" in str(err.value) and "sensors.a1.antialias" in str(err.value)
    assert "sensors.v1" not in str(err.value)
    differing = mixed_config()
    differing["actuators"][0]["antialias"] = {"order": 4, "corner": 1500.0}
    with pytest.raises(ConfigError, match="force channels' anti-alias filters differ"):
        config_from_dict(differing)
