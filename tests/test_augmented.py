"""Native simulation of the signal-level and axial-force effects (diagnosis.problem.augmented, diagnosis.effects).

Every check is against an independent truth: closed-form responses of the
first-order lag, the frequency response 1/(1 + iωτ), the assembled LTI θ-scheme
(a different code path: condensed Φ = S^m and the dense/modal kernels), the
analytic natural frequencies of the axially loaded beam, and the exact
(elliptic-integral) period of the single-mode Duffing oscillator that
mid-plane stretching reduces to on a pinned–pinned beam.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import scipy.signal as ss
from conftest import make_config as _make_config
from scipy.special import ellipk

from diagnosis.problem.augmented import simulate_axial, simulate_effects
from diagnosis.problem.axial_terms import geometric_stiffness, stretch_integral
from diagnosis.effects.axial import AxialDrift, Stretching
from diagnosis.effects.lag import ActuatorLag, SensorLag, first_order_lag
from ebb_model import (
    ConfigError,
    DataError,
    ParameterError,
    StabilityError,
    assemble,
    discretise,
    simulate,
)
from ebb_model.reference.analytic import analytic_omegas
from ebb_model.simulate import simulate_config

# The axial recursion checked here is the θ-scheme's (sub-steps, nodal initial states, the explicit
# scheme's stability limit); the exact scheme's counterpart is checked in tests/test_axial_modal.py.
make_config = functools.partial(_make_config, scheme="theta")


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def _upward_crossings(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Times of upward zero crossings (linear interpolation between samples)."""
    i = np.where((y[:-1] < 0) & (y[1:] >= 0))[0]
    return t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])


def _phasor(t: np.ndarray, y: np.ndarray, omega: float) -> complex:
    """Least-squares complex amplitude ``Y`` of ``y ≈ Re(Y e^{iωt})``."""
    X = np.column_stack([np.cos(omega * t), -np.sin(omega * t)])
    (re, im), *_ = np.linalg.lstsq(X, y, rcond=None)
    return complex(re, im)


def _smooth_noise(n: int, seed: int = 0, cutoff: float = 0.02) -> np.ndarray:
    """Band-limited random force (below ~cutoff·fs/2), shape (n, 1)."""
    b, a = ss.butter(4, cutoff)
    return ss.lfilter(b, a, np.random.default_rng(seed).standard_normal(n))[:, None]


THREE_KINDS = [("d", 0.5, "displacement"), ("v", 0.7, "velocity"), ("a", 0.97, "acceleration")]


# ---------------------------------------------------------------------------
# first-order lag
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("tau", [1e-6, 5e-3, 0.02, 10.0])  # dt/τ from 100 down to 1e-5 (series branch)
def test_lag_ramp_exact(tau):
    dt, n = 1e-4, 3000
    t = np.arange(n) * dt
    a, b = 0.3, -2.0
    x = a + b * t
    y = first_order_lag(x, dt, tau)
    # τ y' + y = a + b t, y(0) = a (steady start at x[0])
    exact = a + b * (t - tau) + b * tau * np.exp(-t / tau)
    assert np.max(np.abs(y - exact)) < 1e-12 * max(1.0, abs(b) * t[-1])


def test_lag_step_from_rest_exact():
    dt, tau, n = 1e-4, 3e-3, 2000
    t = np.arange(n) * dt
    y = first_order_lag(np.ones(n), dt, tau, y0=0.0)
    np.testing.assert_allclose(y, 1.0 - np.exp(-t / tau), rtol=0, atol=1e-13)


def test_lag_one_sample_ramp_step():
    """Input 0 up to sample k0, 1 from k0+1 on (a step as a first-order hold sees it)."""
    dt, tau, n, k0 = 1e-4, 2e-3, 1500, 100
    t = np.arange(n) * dt
    x = (np.arange(n) > k0).astype(float)
    y = first_order_lag(x, dt, tau)
    s = t - t[k0]
    after = s >= dt
    exact = np.zeros(n)
    exact[after] = 1.0 - (tau / dt) * np.expm1(dt / tau) * np.exp(-s[after] / tau)
    np.testing.assert_allclose(y, exact, rtol=0, atol=1e-13)
    # and the ideal step response delayed by dt/2, to O((dt/τ)²)
    ideal = 1.0 - np.exp(-(s[after] - dt / 2) / tau)
    assert np.max(np.abs(y[after] - ideal)) < 0.1 * (dt / tau) ** 2


@pytest.mark.parametrize("freq", [5.0, 50.0, 300.0])
def test_lag_frequency_response(freq):
    dt, tau = 1e-4, 1e-3
    n = 20000
    t = np.arange(n) * dt
    omega = 2 * np.pi * freq
    y = first_order_lag(np.cos(omega * t), dt, tau)
    keep = t > 10 * tau  # transient of the steady start gone
    H = _phasor(t[keep], y[keep], omega)
    expected = 1.0 / (1.0 + 1j * omega * tau)
    assert abs(H - expected) < 0.2 * (omega * dt) ** 2 + 1e-9


def test_lag_columns_and_identity():
    dt = 1e-4
    rng = np.random.default_rng(3)
    x = rng.standard_normal((500, 3))
    y = first_order_lag(x, dt, 2e-3)
    for j in range(3):
        np.testing.assert_array_equal(y[:, j], first_order_lag(x[:, j], dt, 2e-3))
    np.testing.assert_array_equal(first_order_lag(x, dt, 0.0), x)
    # unit DC gain with the steady start: a constant passes unchanged
    np.testing.assert_allclose(first_order_lag(np.full(400, 2.5), dt, 1e-2), 2.5, rtol=0, atol=1e-13)


# ---------------------------------------------------------------------------
# axial recursion with no perturbation = the LTI scheme (substeps, all kinds)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("left,right,substeps", [("clamped", "free", 1), ("clamped", "free", 3),
                                                  ("pinned", "pinned", 2)])
def test_axial_recursion_without_perturbation_equals_assembled_scheme(left, right, substeps):
    cfg = make_config(left, right, nodes=40, c=0.5, eta=1e-4, N=5.0, substeps=substeps, sensors=THREE_KINDS)
    u = np.random.default_rng(1).standard_normal((3000, 1))
    ref = simulate(assemble(cfg), u).outputs  # condensed Φ = S^m, dense kernel
    y = simulate_axial(cfg, None, u)
    scale = np.max(np.abs(ref), axis=0)
    assert np.max(np.abs(y - ref) / scale) < 1e-10


def test_effects_all_off_is_fast_path():
    cfg = make_config("clamped", "free", nodes=40, c=0.5, substeps=2, sensors=THREE_KINDS)
    u = np.random.default_rng(2).standard_normal((2000, 1))
    ref = simulate_config(cfg, u).outputs
    y = simulate_effects(cfg, None, u, (SensorLag("d", 0.0),))
    np.testing.assert_allclose(y, ref, rtol=1e-12, atol=0)


@pytest.mark.parametrize("left,right,eta", [("clamped", "free", 0.0), ("pinned", "pinned", 1e-4)])
def test_constant_offset_converges_to_lti_beam_with_shifted_N(left, right, eta):
    """δN ≡ const through the explicit recursion → the LTI beam with N + δN, error O(τ²)."""
    u = _smooth_noise(4000, seed=4)
    dN = 2.0
    ratios = []
    for substeps in (1, 2):
        cfg = make_config(left, right, nodes=50, c=0.5, eta=eta, N=5.0, substeps=substeps, sensors=THREE_KINDS)
        base = simulate_config(cfg, u).outputs
        shifted = simulate_config(cfg.with_parameters(N=5.0 + dN), u).outputs
        y = simulate_axial(cfg, None, u, offset=dN)
        err = np.max(np.abs(y - shifted), axis=0) / np.max(np.abs(shifted - base), axis=0)
        assert np.all(err < 1e-3), err  # within 0.1 % of the effect of δN itself
        ratios.append(err)
    # halving τ divides the error by ~4 (second-order consistency)
    assert np.all(ratios[0] / ratios[1] > 3.5), ratios


# ---------------------------------------------------------------------------
# geometric stiffness and the stretching integral
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("left,right", [("pinned", "pinned"), ("clamped", "clamped"), ("clamped", "pinned")])
def test_geometric_stiffness_is_string_stencil_for_fixed_ends(left, right):
    cfg = make_config(left, right, nodes=30, N=7.0)
    Kg = geometric_stiffness(cfg)
    h = 1.0 / 31
    n = 30
    expected = (2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)) / h
    np.testing.assert_allclose(Kg, expected, rtol=0, atol=1e-9 / h)
    q = np.random.default_rng(0).standard_normal(n)
    assert stretch_integral(cfg, q) == pytest.approx(q @ Kg @ q, rel=1e-10)


@pytest.mark.parametrize("left,right", [("free", "clamped"), ("clamped", "free"), ("free", "free")])
def test_stretch_integral_of_linear_shape_is_exact(left, right):
    """A straight (rigid-body or clamped–free) shape of slope a: ∫w_x² = a² L exactly, free end nodes included."""
    L, a = 0.8, 0.03
    cfg = make_config(left, right, length=L, nodes=25)
    beam = discretise(cfg)
    x = beam.x[beam.unknown]
    w = a * (L - x) if right == "clamped" else a * x
    assert stretch_integral(cfg, w) == pytest.approx(a ** 2 * L, rel=1e-12)


@pytest.mark.parametrize("left,right", [("free", "clamped"), ("clamped", "free"), ("clamped", "clamped")])
def test_stretching_force_uses_the_stretch_integral(left, right):
    """At the first sample the stretching force is (EA/2L)·∫w_x² of the initial shape: the
    acceleration output equals that of a constant offset of exactly that force."""
    L, EA = 1.0, 3e5
    cfg = make_config(left, right, length=L, nodes=30, c=0.3,
                      sensors=[("a1", 0.5 * L, "acceleration"), ("a2", 0.9 * L, "acceleration")])
    beam = discretise(cfg)
    x = beam.x[beam.unknown]
    q0 = 0.01 * np.sin(1.3 * np.pi * x / L) + 0.004 * x / L + 0.002
    x0 = np.concatenate([q0, np.zeros(x.size)])
    u = np.zeros((1, 1))
    dN = EA / (2 * L) * stretch_integral(cfg, q0)
    y_ea = simulate_axial(cfg, None, u, EA=EA, x0=x0)
    y_off = simulate_axial(cfg, None, u, offset=dN, x0=x0)
    y_lin = simulate_axial(cfg, None, u, x0=x0)
    assert np.max(np.abs(y_off - y_lin)) > 1e-3 * np.max(np.abs(y_lin))  # the force matters
    np.testing.assert_allclose(y_ea, y_off, rtol=1e-11)


def test_stretch_integral_of_sine():
    L = 1.3
    cfg = make_config("pinned", "pinned", length=L, nodes=60)
    beam = discretise(cfg)
    A = 0.01
    q = A * np.sin(np.pi * beam.x[beam.unknown] / L)
    exact = A ** 2 * (np.pi / L) ** 2 * L / 2
    h = L / 61
    assert stretch_integral(cfg, q) == pytest.approx(exact, rel=(np.pi * h / L) ** 2 / 10)


# ---------------------------------------------------------------------------
# axial drift: instantaneous frequency against the analytic beam
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("left,right,EI,N0,rate,substeps", [
    ("pinned", "pinned", 100.0, 0.0, 500.0, 1),     # U: 0 → 10, ω₁ +39 %
    ("pinned", "pinned", 100.0, 0.0, 500.0, 2),     # the same with sub-steps
    ("clamped", "free", 400.0, 0.0, -400.0, 1),     # compression, U: 0 → -2, ω₁ -40 %
])
def test_axial_drift_tracks_analytic_frequency(left, right, EI, N0, rate, substeps):
    rhoA, L = 1.0, 1.0
    dt = 1e-4 * substeps
    n = round(2.0 / dt)  # a 2 s record
    xa = 1.0 if right == "free" else 0.5
    xs = xa if right == "free" else 1 / 3  # pinned–pinned: the sensor at L/3 does not see mode 3
    cfg = make_config(left, right, nodes=50, EI=EI, rhoA=rhoA, c=0.0, eta=1e-5, N=N0, dt=dt,
                      substeps=substeps, actuators=[("F", xa)], sensors=[("y", xs, "displacement")])

    def omega1(N: float) -> float:
        return analytic_omegas(left, right, N * L ** 2 / EI, 1)[0] * math.sqrt(EI / rhoA) / L ** 2

    m = int(math.pi / omega1(N0) / dt)  # half-sine pulse of half a period: mostly mode 1
    u = np.zeros((n, 1))
    u[:m, 0] = np.sin(np.pi * np.arange(m) / m)
    y = simulate_effects(cfg, None, u, (AxialDrift(rate),))[:, 0]
    t = np.arange(n) * dt
    tc = _upward_crossings(t, y)
    tm = 0.5 * (tc[1:] + tc[:-1])
    measured = 2 * np.pi / np.diff(tc)
    analytic = np.array([omega1(N0 + rate * s) for s in tm])
    assert abs(analytic[-1] / analytic[0] - 1) > 0.3  # the drift is large
    assert tm.size >= 10
    err = measured[1:] / analytic[1:] - 1
    assert np.max(np.abs(err)) < 2e-3, err
    # and without drift the frequency stays put (the drift is really what moves it)
    y0 = simulate_effects(cfg, None, u)[:, 0]
    f0 = 2 * np.pi / np.diff(_upward_crossings(t, y0))
    assert np.max(np.abs(f0[1:] / omega1(N0) - 1)) < 2e-3


# ---------------------------------------------------------------------------
# geometric stiffening: Duffing backbone of the pinned–pinned first mode
# ---------------------------------------------------------------------------
def test_geometric_stiffening_backbone():
    """On a pinned–pinned beam w = a(t) sin(πx/L) is invariant and a obeys ä + ω0² a + β a³ = 0,
    β = (π/L)² EA π²/(4 L² ρA); its period is 4K(m)/√(ω0² + βA²), m = βA²/(2(ω0² + βA²))."""
    EI, rhoA, L, EA, dt, n = 10.0, 1.0, 1.0, 1e5, 1e-4, 4000
    cfg = make_config("pinned", "pinned", nodes=50, EI=EI, rhoA=rhoA, c=0.0, N=0.0, dt=dt,
                      actuators=[("F", 0.5)], sensors=[("y", 0.5, "displacement")])
    beam = discretise(cfg)
    shape = np.sin(np.pi * beam.x[beam.unknown] / L)
    omega0 = math.pi ** 2 * math.sqrt(EI / rhoA) / L ** 2
    beta = (math.pi / L) ** 2 * EA * math.pi ** 2 / (4 * L ** 2) / rhoA
    u = np.zeros((n, 1))
    t = np.arange(n) * dt

    def free_decay_omega(A: float) -> float:
        x0 = np.concatenate([A * shape, np.zeros(shape.size)])
        y = simulate_axial(cfg, None, u, EA=EA, x0=x0)[:, 0]
        return 2 * np.pi / np.mean(np.diff(_upward_crossings(t, y)))

    lin = free_decay_omega(1e-6)
    assert lin == pytest.approx(omega0, rel=5e-4)  # linear at tiny amplitude (FD error O(h²))
    for A in (0.005, 0.01, 0.02):
        w2 = omega0 ** 2 + beta * A ** 2
        exact = 2 * np.pi * math.sqrt(w2) / (4 * ellipk(beta * A ** 2 / (2 * w2)))
        harmonic_balance = math.sqrt(omega0 ** 2 + 0.75 * beta * A ** 2)
        measured = free_decay_omega(A)
        assert measured / lin == pytest.approx(exact / omega0, rel=2e-5)
        assert measured / lin == pytest.approx(harmonic_balance / omega0, rel=5e-3)
    assert free_decay_omega(0.02) / lin > 1.3  # strong stiffening is really present


def test_geometric_stiffening_linear_at_small_amplitude():
    """The stretching force grows with the amplitude squared: linear in the limit, then a
    relative deviation from linearity ∝ amplitude², then clearly nonlinear."""
    cfg = make_config("clamped", "clamped", nodes=40, c=0.5, sensors=THREE_KINDS)
    u = 1e-3 * _smooth_noise(3000, seed=5)
    lin = simulate_config(cfg, u).outputs

    def deviation(scale: float) -> float:
        y = simulate_effects(cfg, None, scale * u, (Stretching(1e6),))
        return float(np.max(np.abs(y - scale * lin) / np.max(np.abs(scale * lin), axis=0)))

    assert deviation(1.0) < 1e-8                      # ~0.1 µm deflection: linear
    assert deviation(1e3) / deviation(1e2) == pytest.approx(100.0, rel=0.05)
    assert deviation(1e4) > 3e-2                      # ~1 mm deflection: clearly nonlinear


# ---------------------------------------------------------------------------
# actuator and sensor lag on the beam: the ratio to the lag-free output is 1/(1 + iωτ)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("where", ["actuator", "sensor"])
def test_lag_on_beam_frequency_response(where):
    dt, n, tau, freq = 1e-4, 12000, 2e-3, 40.0
    cfg = make_config("clamped", "free", nodes=40, EI=10.0, c=20.0, dt=dt,
                      actuators=[("F", 0.8)], sensors=THREE_KINDS)
    t = np.arange(n) * dt
    omega = 2 * np.pi * freq
    u = np.sin(omega * t)[:, None]
    base = simulate_effects(cfg, None, u)
    part = ActuatorLag(tau) if where == "actuator" else SensorLag("a", tau)
    y = simulate_effects(cfg, None, u, (part,))
    keep = t > 0.5  # transients gone (ζω ≈ 10 /s → e^-5)
    expected = 1.0 / (1.0 + 1j * omega * tau)
    for j, name in enumerate(("d", "v", "a")):
        ratio = _phasor(t[keep], y[keep, j], omega) / _phasor(t[keep], base[keep, j], omega)
        if where == "sensor" and name != "a":
            assert ratio == pytest.approx(1.0, abs=1e-12)  # other sensors untouched
        else:
            assert abs(ratio - expected) < 2e-3, (name, ratio, expected)


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------
def test_bad_input_errors():
    cfg = make_config(nodes=20)
    u = np.zeros((100, 1))
    with pytest.raises(ParameterError, match="tau"):
        first_order_lag(np.zeros(10), 1e-4, -1.0)
    with pytest.raises(ParameterError, match="tau"):
        first_order_lag(np.zeros(10), 1e-4, float("nan"))
    with pytest.raises(ParameterError, match="dt"):
        first_order_lag(np.zeros(10), 0.0, 1e-3)
    with pytest.raises(DataError, match="non-finite"):
        first_order_lag(np.array([0.0, np.nan]), 1e-4, 1e-3)
    with pytest.raises(ParameterError, match="actuator_lag.tau"):
        simulate_effects(cfg, None, u, (ActuatorLag(-1e-3),))
    with pytest.raises(ConfigError, match="nope"):
        simulate_effects(cfg, None, u, (SensorLag("nope", 1e-3),))
    with pytest.raises(ParameterError, match=r"sensor_lag\[y1\].tau"):
        simulate_effects(cfg, None, u, (SensorLag("y1", float("inf")),))
    with pytest.raises(ParameterError, match="axial_drift.rate"):
        simulate_effects(cfg, None, u, (AxialDrift(float("nan")),))
    with pytest.raises(ParameterError, match="geometric_stiffening.EA"):
        simulate_effects(cfg, None, u, (Stretching(-5.0),))
    bad = u.copy()
    bad[7, 0] = np.nan
    with pytest.raises(DataError, match="sample 7"):
        simulate_effects(cfg, None, bad, (AxialDrift(1.0),))
    with pytest.raises(DataError, match="shape"):
        simulate_effects(cfg, None, np.zeros((100, 2)))
    with pytest.raises(DataError, match="x0"):
        simulate_axial(cfg, None, u, x0=np.zeros(3))
    with pytest.raises(ParameterError, match="EI"):
        simulate_effects(cfg, {"EI": -1.0}, u, (AxialDrift(1.0),))


def test_unstable_scheme_is_reported():
    cfg = make_config(nodes=40, theta=0.0, dt=1e-3)  # explicit scheme far beyond its step limit
    with pytest.raises(StabilityError):
        simulate_effects(cfg, None, np.zeros((50, 1)), (AxialDrift(1.0),), check_stability=True)
