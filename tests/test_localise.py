"""Gap localisation (diagnosis.localise, identification.noise, diagnosis.report.plots) on synthetic truth.

All signals are built here from analytic SDOF / multi-mode responses (scipy.signal, ZOH
discretisation, which maps each continuous pole exactly) — not from the project's beam model —
so the planted deviation (which mode, how much, when, at what amplitude) is known exactly.
"""
from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from scipy import signal

from diagnosis.localise import estimate_frf, localise
from identification.noise import noise_estimate, noise_std
from ebb_model.errors import ConfigError, DataError

DT = 1e-3
N = 30000
FREQS = [20.0, 55.0, 130.0]
ZETAS = [0.02, 0.02, 0.02]
RES = np.array([[1.0, 0.6, 0.3], [0.5, -0.8, 0.6]])  # residues (sensor × mode)
NAMES = ["a", "b"]


def _input(rng: np.random.Generator, n: int = N, k: int = 1, fmax: float = 200.0) -> np.ndarray:
    """Band-limited Gaussian force(s), shape (n, k)."""
    sos = signal.butter(6, fmax, fs=1 / DT, output="sos")
    return signal.sosfilt(sos, rng.standard_normal((n + 1000, k)), axis=0)[1000:]


def _sdof_ba(f: float, z: float):
    wn = 2 * np.pi * f
    b, a, _ = signal.cont2discrete(([wn ** 2], [1, 2 * z * wn, wn ** 2]), DT, method="zoh")
    return b.ravel(), a


def _modal(u: np.ndarray, freqs, zetas, res) -> np.ndarray:
    """Σ_k res[:, k] · SDOF_k(u): response of a modal model, shape (n, n_sensors)."""
    out = np.zeros((len(u), res.shape[0]))
    for k, (f, z) in enumerate(zip(freqs, zetas)):
        b, a = _sdof_ba(f, z)
        out += signal.lfilter(b, a, u)[:, None] * res[:, k][None, :]
    return out


def _sdof_time_varying(u: np.ndarray, f_t: np.ndarray, z: float) -> np.ndarray:
    """q'' + 2ζω(t) q' + ω(t)² q = ω̄² u by the trapezoidal rule (2×2 implicit step in closed form)."""
    h = DT
    w = 2 * np.pi * np.asarray(f_t, dtype=float)
    g = float(np.mean(w)) ** 2
    q = np.zeros(len(u))
    x = v = 0.0
    for k in range(len(u) - 1):
        r1 = x + 0.5 * h * v
        r2 = v + 0.5 * h * (-w[k] ** 2 * x - 2 * z * w[k] * v + g * (u[k] + u[k + 1]))
        m21, m22 = 0.5 * h * w[k + 1] ** 2, 1 + h * z * w[k + 1]
        det = m22 + 0.5 * h * m21
        x, v = (r1 * m22 + 0.5 * h * r2) / det, (r2 - m21 * r1) / det
        q[k + 1] = x
    return q


def _noisy(y: np.ndarray, rng: np.random.Generator, rel: float) -> tuple[np.ndarray, np.ndarray]:
    sig = rel * y.std(axis=0)
    return y + sig * rng.standard_normal(y.shape), sig


def _mode(loc, sensor: str, k: int):
    return next(m for m in loc.modes if m.sensor == sensor and m.mode == k)


# ------------------------------------------------------------------------------------------ noise
def test_noise_std_band_limited_and_lightly_damped():
    """Known white noise under a band-limited signal and a ζ = 0.002 resonance: within 10 %."""
    for seed in range(3):
        rng = np.random.default_rng(seed)
        w = _input(rng, 40000, fmax=100.0)[:, 0]
        b, a = _sdof_ba(50.0, 0.002)
        r = signal.lfilter(b, a, w)
        sig = 0.01
        y = np.c_[w / w.std(), r / r.std()] + sig * rng.standard_normal((40000, 2))
        for band in ((0.0, 100.0), None):
            est = noise_estimate(y, DT, band=band)
            assert est.method == ("psd_floor", "psd_floor")
            np.testing.assert_allclose(est.std, sig, rtol=0.10)
        # the signal itself is 100× the noise: a plain std would be off by 100×
        assert noise_std(y, DT)[1] < 0.02 * y[:, 1].std()


def test_noise_std_fallback_difference_mad():
    """Excited band reaching Nyquist → difference/MAD fallback, exact for an oversampled signal."""
    rng = np.random.default_rng(4)
    t = np.arange(4000) * DT
    sig = 0.05
    y = np.sin(2 * np.pi * 3.0 * t) + 0.5 * np.sin(2 * np.pi * 11.0 * t) + sig * rng.standard_normal(t.size)
    est = noise_estimate(y, DT, band=(0.0, 480.0))
    assert est.method == ("difference_mad",) and est.f_range is None
    assert est.std[0] == pytest.approx(sig, rel=0.10)


def test_noise_std_bad_input():
    y = np.ones(1000)
    y[10] = np.nan
    with pytest.raises(DataError, match="non-finite"):
        noise_std(y, DT)
    with pytest.raises(ConfigError, match="dt"):
        noise_std(np.ones(1000), 0.0)
    with pytest.raises(ConfigError, match="band"):
        noise_std(np.ones(1000), DT, band=(50.0, 10.0))


# ------------------------------------------------------------------------------------------ FRF
def test_frf_estimate_matches_analytic_transfer_function():
    """H1 estimate of a noise-free SDOF equals its exact discrete transfer function."""
    rng = np.random.default_rng(11)
    u = _input(rng)[:, 0]
    b, a = _sdof_ba(55.0, 0.02)
    y = signal.lfilter(b, a, u)
    est = estimate_frf(DT, u, y, nperseg=4096)
    sel = est.excited[:, 0] & (est.f > 1.0) & (est.f < 180.0)
    _, h = signal.freqz(b, a, worN=est.f[sel], fs=1 / DT)
    rel = np.abs(est.H[sel, 0, 0] / h - 1)
    assert np.median(rel) < 0.01 and np.max(rel) < 0.1
    assert np.min(est.coherence[sel, 0]) > 0.95


# ------------------------------------------------------------------------------------------ modes
def test_shifted_resonance_found_at_the_right_mode():
    rng = np.random.default_rng(0)
    u = _input(rng)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, _ = _noisy(_modal(u, [20.0, 55.0 * 0.98, 130.0], ZETAS, RES), rng, 0.05)
    loc = localise(DT, u, y, y_hat, NAMES, FREQS, ZETAS)
    assert loc.gap_detected
    for s in NAMES:
        m2 = _mode(loc, s, 2)
        assert m2.fit_ok and "frequency" in m2.significant
        assert m2.freq_shift_rel == pytest.approx(-0.02, rel=0.2)
        assert "damping" not in m2.significant
        assert m2.band_excess_fraction > 0.8
        for k in (1, 3):
            mk = _mode(loc, s, k)
            assert not mk.significant and abs(mk.freq_shift_rel) < 0.002
    lines = [x for x in loc.summary if re.search(r"\bmode \d", x)]
    assert lines and all("mode 2 (55 Hz)" in x and "below model" in x for x in lines)
    assert not any("drift" in x or "nonlinearity" in x for x in loc.summary)


def test_damping_mismatch_found_at_the_right_mode():
    rng = np.random.default_rng(1)
    u = _input(rng)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, _ = _noisy(_modal(u, FREQS, [0.02, 0.04, 0.02], RES), rng, 0.03)
    loc = localise(DT, u, y, y_hat, NAMES, FREQS, ZETAS)
    for s in NAMES:
        m2 = _mode(loc, s, 2)
        assert m2.damping_resolved and "damping" in m2.significant and "frequency" not in m2.significant
        assert m2.damping_ratio == pytest.approx(2.0, rel=0.2)
        assert m2.measured_damping == pytest.approx(0.04, rel=0.2)
        for k in (1, 3):
            assert not _mode(loc, s, k).significant
    assert any("mode 2" in x and "damping" in x for x in loc.summary)


def test_lightly_damped_unresolved_modes_and_a_sensor_at_a_node():
    """ζ = 0.002: half-power bandwidth below the Welch resolution; sensor b sits at a node of mode 2."""
    rng = np.random.default_rng(13)
    u = _input(rng, n=20000)[:, 0]
    res = np.array([[1.0, 0.5], [0.8, 0.0]])
    freqs, zetas = [40.0, 90.0], [0.002, 0.002]
    y_hat = _modal(u, freqs, zetas, res)
    y, _ = _noisy(_modal(u, [40.0, 90.0 * 0.98], zetas, res), rng, 0.02)
    loc = localise(DT, u, y, y_hat, NAMES, freqs, zetas)
    a1, a2, b1, b2 = loc.modes
    assert a2.observed and "frequency" in a2.significant
    assert a2.freq_shift_rel == pytest.approx(-0.02, rel=0.2)
    assert not a2.damping_resolved and "damping" not in a2.significant  # not measurable: not claimed
    assert not b2.observed and b2.significant == () and not np.isfinite(b2.freq_shift_rel)
    assert a1.significant == () and b1.significant == ()
    assert any("sensor a: the resonance nearest mode 2 (90 Hz) measured" in x for x in loc.summary)
    assert not any("sensor b: the resonance nearest mode 2" in x for x in loc.summary)


# ------------------------------------------------------------------------------------------ drift
def test_time_varying_frequency_gives_a_trend_constant_offset_does_not():
    rng = np.random.default_rng(2)
    u = _input(rng, fmax=150.0)[:, 0]
    t = np.arange(N) * DT
    y_hat = _sdof_time_varying(u, np.full(N, 40.0), 0.02)
    # frequency drifting linearly by 2 % over the record (a model fitted to it sits at the mean)
    y_drift, _ = _noisy(_sdof_time_varying(u, 40.0 * (1 + 0.02 * (t / t[-1] - 0.5)), 0.02), rng, 0.03)
    loc = localise(DT, u, y_drift, y_hat, ["s"], [40.0], [0.02])
    w = loc.windows[0]
    assert w.drift and w.phase_p < 1e-4 and abs(w.phase_change_deg) > 5
    assert any("drift" in x for x in loc.summary)
    # same error size but constant in time: a frequency shift, not a drift
    y_const, _ = _noisy(_sdof_time_varying(u, np.full(N, 40.4), 0.02), rng, 0.03)
    loc = localise(DT, u, y_const, y_hat, ["s"], [40.0], [0.02])
    w = loc.windows[0]
    assert loc.gap_detected and not w.drift and min(w.rms_p, w.gain_p, w.phase_p) > 1e-3
    assert not any("drift" in x for x in loc.summary)
    assert _mode(loc, "s", 1).freq_shift_rel == pytest.approx(0.01, rel=0.2)


def test_sweep_with_linear_model_error_is_neither_drift_nor_nonlinearity():
    """A chirp makes frequency a function of time and amplitude: a LTI error must not look like either."""
    rng = np.random.default_rng(5)
    t = np.arange(N) * DT
    u = signal.chirp(t, 5, t[-1], 200) + 0.01 * rng.standard_normal(N)
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, _ = _noisy(_modal(u, [20.0, 55.0 * 0.98, 130.0], ZETAS, RES), rng, 0.02)
    loc = localise(DT, u, y, y_hat, NAMES, FREQS, ZETAS)
    assert loc.gap_detected
    assert not any(w.drift for w in loc.windows) and not any(a.nonlinear for a in loc.amplitude)
    assert all(_mode(loc, s, 2).freq_shift_rel == pytest.approx(-0.02, rel=0.2) for s in NAMES)


# ------------------------------------------------------------------------------------------ amplitude
def test_amplitude_dependent_gain_gives_a_significant_slope_linear_gain_does_not():
    rng = np.random.default_rng(3)
    u = _input(rng)[:, 0]
    y_lin = _modal(u, FREQS, ZETAS, RES)
    env = np.abs(signal.hilbert(y_lin, axis=0))
    y_nl, _ = _noisy(y_lin * (1 + 0.05 * env / y_lin.std(axis=0)), rng, 0.05)
    loc = localise(DT, u, y_nl, y_lin, NAMES, FREQS, ZETAS)
    for a in loc.amplitude:
        assert a.nonlinear and a.gain_slope > 0 and a.gain_p < 1e-4
        assert a.rms_exponent > 1.3  # residual grows faster than any linear error could
    assert sum("nonlinearity" in x for x in loc.summary) == 2
    # a 10 % linear gain error: a gap, but not amplitude dependent
    y_gain, _ = _noisy(1.1 * y_lin, rng, 0.05)
    loc = localise(DT, u, y_gain, y_lin, NAMES, FREQS, ZETAS)
    assert loc.gap_detected
    assert not any(a.nonlinear for a in loc.amplitude)
    assert not any("nonlinearity" in x for x in loc.summary)
    for a in loc.amplitude:
        assert a.rms_exponent < 1.1


def test_multisine_lines_only():
    """Three excited lines (like the lab shaker test): unexcited modes are said to be so, nothing invented."""
    rng = np.random.default_rng(8)
    t = np.arange(N) * DT
    u = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) for f in (100.0, 120.0, 150.0))
    u = u + 0.01 * rng.standard_normal(N)
    freqs, zetas = [6.6, 41.3, 117.5], [0.005] * 3
    res = np.array([[1.0, 0.6, 0.3]])
    y_hat = _modal(u, freqs, zetas, res)
    y, _ = _noisy(_modal(u, [6.6, 41.3, 117.5 * 0.99], zetas, res), rng, 0.01)
    loc = localise(DT, u, y, y_hat, ["acc"], freqs, zetas)
    assert [m.excited for m in loc.modes] == [False, False, True]
    m3 = loc.modes[2]
    assert "amplitude/phase" in m3.significant and m3.band_excess_fraction > 0.9
    assert not loc.windows[0].drift and not loc.amplitude[0].nonlinear
    assert any("mode 3" in x for x in loc.summary)
    assert not any("mode 1" in x or "mode 2" in x for x in loc.summary)


# ------------------------------------------------------------------------------------------ noise only
@pytest.mark.parametrize("seed", [100, 101, 102])
def test_perfect_model_with_white_noise_names_nothing(seed):
    rng = np.random.default_rng(seed)
    u = _input(rng)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, sig = _noisy(y_hat, rng, 0.05)
    loc = localise(DT, u, y, y_hat, NAMES, FREQS, ZETAS)
    assert not loc.gap_detected and loc.summary == ()
    for s, true_sig in zip(loc.sensors, sig):
        assert s.gap_ratio == pytest.approx(1.0, abs=0.15)
        assert s.noise_std == pytest.approx(true_sig, rel=0.07)
        assert s.model_error_fraction < 0.15
    assert all(h.white for h in loc.whiteness)
    assert not any(c.significant for c in loc.cross_correlation)
    assert not any(w.drift for w in loc.windows) and not any(a.nonlinear for a in loc.amplitude)
    assert not any(m.significant for m in loc.modes)
    assert "no significant gap" in loc.table_text()


# ------------------------------------------------------------------------------------------ input correlation
def test_input_correlated_error_detected_by_cross_correlation():
    rng = np.random.default_rng(7)
    u = _input(rng, k=2)
    y_hat = _modal(u[:, 0], FREQS, ZETAS, RES) + _modal(u[:, 1], FREQS, ZETAS, RES[::-1])
    y, sig = _noisy(y_hat, rng, 0.05)
    err = np.zeros(N)
    err[5:] = u[:-5, 0]  # unmodelled direct path from F1, delayed 5 samples, as large as the noise
    y = y + np.outer(err / err.std(), sig)
    loc = localise(DT, u, y, y_hat, NAMES, FREQS, ZETAS, input_names=["F1", "F2"])
    for c in loc.cross_correlation:
        if c.input == "F1":
            assert c.significant and c.max_lag == 5 and c.max_abs > 10 * c.band
        else:
            assert not c.significant
    assert all(s.gap_detected for s in loc.sensors)
    assert all(any(f"sensor {s}: residual correlated with input F1" in x for x in loc.summary) for s in NAMES)
    assert not any("input F2" in x for x in loc.summary)


# ------------------------------------------------------------------------------------------ outputs
def test_to_dict_is_json_and_table_has_rows():
    rng = np.random.default_rng(9)
    u = _input(rng, n=8000)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, _ = _noisy(_modal(u, [20.0, 55.0 * 0.97, 130.0], ZETAS, RES), rng, 0.05)
    # modes given out of order: indices refer to the caller's list
    loc = localise(DT, u, y, y_hat, NAMES, [130.0, 20.0, 55.0], [0.02, 0.02, 0.02])
    m = next(m for m in loc.modes if m.sensor == "a" and m.mode == 3)
    assert m.model_freq_hz == 55.0 and "frequency" in m.significant
    assert m.freq_shift_rel == pytest.approx(-0.03, rel=0.2)
    d = json.loads(json.dumps(loc.to_dict(), allow_nan=False))
    assert set(d) >= {"sensors", "modes", "bands", "windows", "amplitude", "whiteness", "cross_correlation",
                      "summary", "gap_detected"}
    assert len(d["modes"]) == 6 and len(d["cross_correlation"]) == 2
    rows = loc.table()
    assert rows[0] == ("sensor", "where", "quantity", "value") and len(rows) > 20
    assert all(len(r) == 4 for r in rows)


def test_plots_are_written(tmp_path):
    from diagnosis.report.plots import plot_localisation

    rng = np.random.default_rng(10)
    u = _input(rng, n=6000)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y, _ = _noisy(_modal(u, [20.0, 55.0 * 0.97, 130.0], ZETAS, RES), rng, 0.05)
    loc = localise(DT, u, y, y_hat, NAMES, FREQS, ZETAS)
    files = plot_localisation(loc, DT, u, y, y_hat, tmp_path / "plots")
    assert {p.name for p in files} == {"residuals.png", "frf.png", "windows.png", "amplitude.png",
                                       "correlation.png", "bands.png"}
    for p in files:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(DataError):
        plot_localisation(loc, DT, u, y[:, :1], y_hat[:, :1], tmp_path)


# ------------------------------------------------------------------------------------------ bad input
def test_bad_input_raises_typed_errors_naming_the_problem():
    rng = np.random.default_rng(12)
    u = _input(rng, n=4000)[:, 0]
    y_hat = _modal(u, FREQS, ZETAS, RES)
    y = y_hat + 0.01 * rng.standard_normal(y_hat.shape)

    def call(**kw):
        args = {"dt": DT, "u": u, "y": y, "y_hat": y_hat, "sensor_names": NAMES, "mode_freqs_hz": FREQS,
                "mode_damping": ZETAS}
        args.update(kw)
        return localise(**args)

    y_nan = y.copy()
    y_nan[100, 1] = np.nan
    with pytest.raises(DataError, match=r"y contains a non-finite value at sample 100, column 1"):
        call(y=y_nan)
    with pytest.raises(DataError, match="u contains a non-finite value"):
        call(u=np.where(np.arange(u.size) == 7, np.inf, u))
    with pytest.raises(DataError, match="y_hat has shape"):
        call(y_hat=y_hat[:, :1])
    with pytest.raises(DataError, match="u has 3999 samples"):
        call(u=u[:-1])
    with pytest.raises(DataError, match="sensor_names"):
        call(sensor_names=["a"])
    with pytest.raises(DataError, match="constant"):
        call(u=np.ones_like(u))
    with pytest.raises(DataError, match="samples"):
        call(u=u[:100], y=y[:100], y_hat=y_hat[:100])
    for bad_dt in (0.0, -1e-3, math.nan, "x"):
        with pytest.raises(ConfigError, match="dt"):
            call(dt=bad_dt)
    with pytest.raises(ConfigError, match="mode_freqs_hz"):
        call(mode_freqs_hz=[20.0, 55.0, 600.0])
    with pytest.raises(ConfigError, match="mode_damping"):
        call(mode_damping=[0.02, 0.02])
    with pytest.raises(ConfigError, match="windows"):
        call(windows=1)
    with pytest.raises(ConfigError, match="amplitude_bins"):
        call(amplitude_bins=1)
    with pytest.raises(ConfigError, match="noise_std"):
        call(noise_std=[0.1, -0.1])
