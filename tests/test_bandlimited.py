"""The band-limited force between samples (``[time] input = "bandlimited"``, :mod:`ebb_model.acquisition.bandlimited`).

Truth: the periodic steady state of a cubic Hermite finite-element beam under a random-phase multisine (exactly
band-limited and periodic over the record), from its frequency response bin by bin — no time stepping at all,
and no code shared with the finite-difference model; shown converged (96 → 128 elements) far below what is
asserted.  The model is simulated over several periods of the same record and its last period compared, the
transient shown gone (the period before it agrees as well).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate as si

import ebb_model as em
from ebb_model.acquisition import bandlimited as bl
from ebb_model.errors import ConfigError
from ebb_model.exact.exact_modal import continuous_modes, exact_statespace
from ebb_model.modal.modal import frequency_response
from ebb_model.exact.recursion import run_modal_recursion
from ebb_model.reference.exact_fe import periodic_fe_response
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.hermite_fe import hermite_beam

INF = math.inf
ENDS = {"clamped": (INF, INF), "pinned": (INF, 0.0), "free": (0.0, 0.0)}

# the lightly damped clamped–pinned beam of tests/test_exact_scheme.py (ζ 2.1 % at mode 1 down to 0.2 % at mode
# 8), 2 kHz, two accelerometers: a random force to 0.2 fs and to 0.4 fs reaches modes 1–8 and 1–10
CASE = dict(length=1.0, left="clamped", right="pinned", params=dict(EI=10.0, rhoA=1.0, c=2.0, eta=2e-6, N=20.0),
            dt=5e-4, actuator=0.55, sensors=((0.35, "acceleration"), (0.8, "acceleration")))
SAMPLES = 3000          # one period of the multisine: 1.5 s
PERIODS = 6             # simulated; the slowest mode (ζω = 1.1 /s) leaves e^{-8} of its start after five


def config(nodes: int, hold: str, case: dict = CASE) -> em.BeamConfig:
    return em.config_from_dict({
        "beam": {"length": case["length"], "nodes": nodes, "left": case["left"], "right": case["right"]},
        "time": {"dt": case["dt"], "input": hold},
        "parameters": {k: {"value": v} for k, v in case["params"].items()},
        "actuators": [{"name": "F1", "x": case["actuator"]}],
        "sensors": [{"name": f"s{i}", "x": x, "kind": k} for i, (x, k) in enumerate(case["sensors"])],
    })


def multisine(top: float, seed: int = 4) -> np.ndarray:
    """A random-phase multisine on the record's DFT grid from 2 Hz to ``top`` × fs, unit RMS, no fade: exactly
    band-limited and periodic over the record."""
    return band_limited_input(SAMPLES, CASE["dt"], 2.0, top / CASE["dt"], seed=seed, fade=0.0)[:, 0]


def fe_steady_state(u: np.ndarray, elements: int) -> np.ndarray:
    """The finite-element beam's periodic response to the periodic force ``u``, bin by bin."""
    b = hermite_beam(CASE["length"], elements, left=ENDS[CASE["left"]], right=ENDS[CASE["right"]], **CASE["params"])
    return periodic_fe_response(b, u, CASE["dt"], CASE["actuator"], CASE["sensors"])


def last_periods(model, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    y = em.simulate(model, np.tile(u, PERIODS)[:, None]).outputs
    return y[-SAMPLES:], y[-2 * SAMPLES:-SAMPLES]


def noise_variances(y: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Mean squared error per sensor in units of a 1 % noise's variance."""
    return ((y - truth) ** 2).mean(axis=0) / (0.01 * truth.std(axis=0)) ** 2


def test_the_kernel_interpolates_and_reconstructs_the_band():
    """φ(j) = δ_j; a tone anywhere in 0 … 0.4 fs is reconstructed between samples to RECONSTRUCTION_ERROR, and
    not above the band (at 0.48 fs the images are no longer stopped: the bound is a real one)."""
    j = np.arange(-bl.HALF_WIDTH - 2, bl.HALF_WIDTH + 3)
    assert np.allclose(bl.kernel(j), (j == 0).astype(float), atol=1e-15)
    err = bl.reconstruction_error()
    assert err <= bl.RECONSTRUCTION_ERROR, err
    assert bl.reconstruction_error(0.48) > 100 * bl.RECONSTRUCTION_ERROR


@pytest.mark.parametrize("s", [1e-3 + 0j, -0.5 + 30j, -10 + 3000j, -3 + 2e4j, -2e5 + 0j, -50 + 2e5j])
def test_pole_weights_equal_adaptive_quadrature(s):
    """``W_m = T ∫₀¹ e^{sT(1−σ)} φ(σ − m) dσ`` against scipy's adaptive quadrature (Gauss–Kronrod, every tap
    at once), |sT| from 1e-6 to 200 (one to 64 panels): within 1e-12 of the largest weight."""
    T = 1e-3
    _, W = bl.pole_weights(np.array([s]), T)
    a = s * T
    m = np.arange(-bl.HALF_WIDTH + 1, bl.HALF_WIDTH + 1)

    def integrand(x: float) -> np.ndarray:
        v = np.exp(a * (1 - x)) * bl.kernel(x - m)
        return np.concatenate([v.real, v.imag])

    parts = si.quad_vec(integrand, 0.0, 1.0, epsabs=1e-16, epsrel=1e-13, limit=5000)[0]
    ref = T * (parts[:m.size] + 1j * parts[m.size:])
    assert np.abs(W[:, 0] - ref).max() <= 1e-12 * np.abs(ref).max()


def test_pole_weights_beyond_the_panels_take_the_series():
    """Above 2⁶ panels (|sT| > 256) eight terms of the series in 1/(sT), the kernel's derivatives at the interval
    ends from its Chebyshev interpolant: against 2¹³ panels within 1e-12 (measured ≤ 3e-13 at |sT| = 257, any
    damping), light to critical damping and a real pole."""
    sigma, weights, table = bl._panel_table(13)
    for size in (257.0, 400.0, 1e3, 1.7e4):
        for zeta in (0.0, 1e-4, 0.3, 1.0):
            a = size * (-zeta + 1j * np.sqrt(1.0 - zeta ** 2))
            _, W = bl.pole_weights(np.array([a]), 1.0)
            ref = table @ (np.exp(a * (1 - sigma)) * weights)
            assert np.abs(W[:, 0] - ref).max() <= 1e-12 * np.abs(ref).max(), a


def test_every_realisation_of_the_band_limited_model_agrees():
    """The compiled modal recursion, its numba fallback, the dense quadrature route (matrix exponentials, no
    poles), the modal form as one StateSpace and the frequency response: one model, to round-off — with an
    accelerometer's feedthrough, one behind an anti-alias filter and a displacement sensor."""
    d = config(40, "bandlimited").to_dict()
    d["sensors"] = [{"name": "a", "x": 0.35, "kind": "acceleration"},
                    {"name": "af", "x": 0.6, "kind": "acceleration", "antialias": {"order": 4, "corner": 700.0}},
                    {"name": "w", "x": 0.8, "kind": "displacement"}]
    cfg = em.config_from_dict(d)
    model = em.fast_model(cfg)
    assert model.advance == bl.ADVANCE and model.D_record is not None
    u = multisine(0.4)[:, None]
    y = em.simulate(model, u).outputs
    scale = np.abs(y).max(axis=0)
    ua = bl.lead_in(u, model.advance)
    numba = run_modal_recursion(model.T, model.G, model.Cm, model.D, ua, model.delays, -(model.hold @ ua[0]),
                                compiled=False, D_taps=model.feedthrough_taps())[model.advance:]
    assert np.all(np.abs(numba - y).max(axis=0) <= 1e-12 * scale)
    assert np.all(np.abs(em.simulate(model.to_statespace(), u).outputs - y).max(axis=0) <= 1e-12 * scale)
    dense = exact_statespace(cfg, {})
    assert dense.advance == bl.ADVANCE
    assert np.all(np.abs(em.simulate(dense, u).outputs - y).max(axis=0) <= 1e-10 * scale)
    f = [37.0, 300.0, 790.0]
    H = frequency_response(model, f).H
    largest = np.abs(H).max(axis=0)
    assert np.all(np.abs(frequency_response(model.to_statespace(), f).H - H) <= 1e-12 * largest)
    # the dense route's matrix exponentials of the stiff (q, q̇) system are its own limit: with the cubic the same
    # comparison gives 2.7e-7 of each output's largest response (here 4.5e-8)
    assert np.all(np.abs(frequency_response(dense, f).H - H) <= 1e-6 * largest)


def test_the_time_integration_is_exact_for_a_band_limited_force():
    """Against the model's own continuous-time frequency response (the same poles, exact for a periodic
    band-limited force): the band-limited reconstruction leaves 2e-5 noise variances at 0.4 fs (bound 1e-3:
    the kernel's 2e-5 amplitude error is 2e-3 of a 1 % noise's standard deviation, 4e-6 of its variance, with
    a margin for the transient's e^{-8}); the cubic there leaves hundreds."""
    u = multisine(0.4)
    cfg = config(60, "bandlimited")
    cm = continuous_modes(cfg, {})
    w = 2j * np.pi * np.fft.rfftfreq(SAMPLES, CASE["dt"])
    CV = cm.output_rows()
    H = (CV[None] * (cm.inputs[:, 0][None, None, :] / (w[:, None, None] - cm.poles[None, None, :]))).sum(2)
    H += cm.D[:, 0].real[None, :]
    own = np.fft.irfft(H * np.fft.rfft(u)[:, None], SAMPLES, axis=0)
    last, before = last_periods(em.fast_model(cfg), u)
    r, r_before = noise_variances(last, own), noise_variances(before, own)
    assert np.all(r <= 1e-3) and np.all(r_before <= 1e-3), (r, r_before)
    cubic, _ = last_periods(em.fast_model(config(60, "cubic")), u)
    assert np.all(noise_variances(cubic, own) > 100), noise_variances(cubic, own)


@pytest.fixture(scope="module")
def truths():
    """The finite-element truth for a force to 0.2 fs and to 0.4 fs, with its refinement (96 → 128 elements)."""
    out = {}
    for top in (0.2, 0.4):
        u = multisine(top)
        y96, y128 = fe_steady_state(u, 96), fe_steady_state(u, 128)
        out[top] = (u, y128, noise_variances(y96, y128))
    return out


@pytest.mark.parametrize("top", [0.2, 0.4])
def test_a_random_force_to_the_band_edge_is_at_the_noise_floor(truths, top):
    """A random force to 0.2 fs and to 0.4 fs through two accelerometers, at the true parameters: the band-limited
    force between samples leaves less than one noise variance against converged finite elements; the default
    cubic leaves more than 3 at 0.2 fs and more than 100 at 0.4 fs.

    Error budget (measured): the truth moves by < 0.02 noise variances from 96 to 128 elements (asserted
    below 0.05); the time integration is exact to 2e-5 (test above); what remains, 0.12 at 0.2 fs and
    0.29 / 0.50 at 0.4 fs, is the grid's: Richardson-extrapolated modes 8–10 lie 1e-5 … 4e-5 low at 200 nodes
    (at 60 nodes 8e-5 … 2e-4, and the same force leaves 2.6–14 noise variances there)."""
    u, truth, refinement = truths[top]
    assert np.all(refinement < 0.05), refinement
    last, before = last_periods(em.fast_model(config(200, "bandlimited")), u)
    r = noise_variances(last, truth)
    assert np.all(r < 1.0), r
    assert np.all(np.abs(noise_variances(before, truth) - r) < 0.01)      # the transient is gone
    cubic, _ = last_periods(em.fast_model(config(200, "cubic")), u)
    rc = noise_variances(cubic, truth)
    assert np.all(rc > (3.0 if top == 0.2 else 100.0)), rc


def test_a_causal_model_takes_the_cubic():
    """What is driven sample by sample — a design model, its StateSpace, an FMU — cannot read the record ahead:
    the design model of a band-limited config is the cubic's, a StateSpace of the band-limited model is refused
    with one line, and the theta-scheme refuses the reconstruction in the config."""
    from ebb_model.modal.truncation import design_model

    bandl, cubic = config(30, "bandlimited"), config(30, "cubic")
    assert bl.causal_config(bandl).time.input_hold == "cubic"
    a, b = design_model(bandl, {}), design_model(cubic, {})
    assert a.advance == 0 and np.array_equal(a.A, b.A) and np.array_equal(a.B, b.B)
    with pytest.raises(ConfigError, match="ahead of the record"):
        exact_statespace(bandl, {}).to_control()
    d = bandl.to_dict()
    d["time"]["scheme"] = "theta"
    with pytest.raises(ConfigError, match="needs scheme"):
        em.config_from_dict(d)


def test_a_broadband_force_with_the_cubic_gets_a_hint_and_nothing_else_does():
    """A force reaching 0.2 fs or more (here white noise through a low-pass at fs/2.56) with the cubic between
    samples: one sentence naming the band edge, how far off the cubic is there and the setting that models a DAQ's
    record; a force to 0.1 fs (the first-records family's), the band-limited config or the θ-scheme: none."""
    from scipy import signal

    rng = np.random.default_rng(3)
    fs = 1.0 / CASE["dt"]
    broadband = signal.sosfiltfilt(signal.butter(8, fs / 2.56, fs=fs, output="sos"), rng.standard_normal(6000))
    narrow = signal.sosfiltfilt(signal.butter(8, 0.1 * fs, fs=fs, output="sos"), rng.standard_normal(6000))
    cubic = config(30, "cubic")
    note = bl.hold_hint(cubic, [broadband[:, None]])
    assert note is not None and "% off" in note and 'input = "bandlimited"' in note
    edge = float(note.split("reaches ")[1].split(" of")[0])
    assert 0.2 <= edge <= 0.5 and f"{100 * bl._cubic_error(edge):.0f} % off" in note
    assert bl.hold_hint(cubic, [narrow[:, None]]) is None
    assert bl.hold_hint(config(30, "bandlimited"), [broadband[:, None]]) is None
    d = cubic.to_dict()
    d["time"].update(scheme="theta", input="foh")
    assert bl.hold_hint(em.config_from_dict(d), [broadband[:, None]]) is None


def test_a_record_from_rest_is_read_from_its_first_sample():
    """A force faded in from zero, recorded with silence before it or from its first sample: the same outputs from
    the first sample on, to round-off (the silence is what the model holds before a record).  The recursion reads the
    record :data:`~ebb_model.acquisition.bandlimited.ADVANCE` samples ahead; run from the record's first sample it took
    ``u[ADVANCE]`` for the first ``ADVANCE`` samples — a step of the force whose lowest mode rang through the record
    (here 1 % and 3 % of the outputs' largest values; a cantilever of the hint family: 3-4 noise variances at the
    truth)."""
    d = config(40, "bandlimited").to_dict()
    d["sensors"] = [{"name": "a", "x": 0.35, "kind": "acceleration"}, {"name": "w", "x": 0.8, "kind": "displacement"}]
    model = em.fast_model(em.config_from_dict(d))
    u = multisine(0.4)[:, None]
    u *= np.minimum(1.0, np.arange(u.shape[0]) / 100.0)[:, None]          # from zero
    y = em.simulate(model, u).outputs
    quiet = em.simulate(model, np.vstack([np.zeros((60, 1)), u])).outputs[60:]
    scale = np.abs(y).max(axis=0)
    assert np.all(np.abs(quiet - y).max(axis=0) <= 1e-10 * scale), np.abs(quiet - y).max(axis=0) / scale
