"""Tests of the independent reference solutions (``ebb_model.reference``).

The analytic characteristic-equation solver and the cubic Hermite FE model are
checked against textbook numbers, closed forms, an independently assembled
4 x 4 boundary determinant and each other.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.integrate import quad

from ebb_model.errors import ParameterError
from ebb_model.reference import (
    CLAMPED,
    FREE,
    PINNED,
    HermiteBeam,
    analytic_frequencies_hz,
    analytic_omegas,
    critical_buckling_U,
    element_matrices,
    hermite_beam,
    hermite_shape_functions,
    newmark_simulate,
    solve_characteristic,
)

PAIRS = [("pinned", "pinned"), ("clamped", "clamped"), ("clamped", "pinned"), ("clamped", "free")]
ENDS = {"clamped": CLAMPED, "pinned": PINNED, "free": FREE}

# Deliberately non-unit physical parameters.
L_, EI_, RHOA_ = 1.3, 2.7, 0.45


def _omega_hz_to_nondim(f: np.ndarray) -> np.ndarray:
    return 2.0 * np.pi * f * L_**2 * math.sqrt(RHOA_ / EI_)


def _fe(pair: tuple[str, str], U: float, ne: int, **kw) -> HermiteBeam:
    return hermite_beam(
        L_, ne, EI=EI_, rhoA=RHOA_, N=U * EI_ / L_**2, left=ENDS[pair[0]], right=ENDS[pair[1]], **kw
    )


# ==========================================================================
# analytic
# ==========================================================================
@pytest.mark.parametrize(
    "pair, ref",
    [
        (("clamped", "clamped"), [22.3733, 61.6728, 120.9034]),
        (("clamped", "free"), [3.5160, 22.0345, 61.6972]),
        (("clamped", "pinned"), [15.4182, 49.9649]),
        (("pinned", "pinned"), [np.pi**2, 4 * np.pi**2, 9 * np.pi**2]),
    ],
)
def test_textbook_values_U0(pair, ref):
    om = analytic_omegas(*pair, 0.0, len(ref))
    # the references are rounded to 4 decimals: agreement to >= 4 significant digits
    np.testing.assert_allclose(om, ref, rtol=2e-5)
    # same numbers from the other end
    np.testing.assert_allclose(analytic_omegas(pair[1], pair[0], 0.0, len(ref)), om, rtol=0, atol=0)


def test_pair_order_and_aliases():
    for U in (-5.0, 0.0, 37.0):
        np.testing.assert_array_equal(
            analytic_omegas("pinned", "clamped", U, 6), analytic_omegas("clamped", "pinned", U, 6)
        )
        np.testing.assert_array_equal(
            analytic_omegas("free", "clamped", U / 10, 6), analytic_omegas("clamped", "free", U / 10, 6)
        )
    np.testing.assert_array_equal(analytic_omegas("Clamped", "FIXED", 3.0, 4),
                                  analytic_omegas("clamped", "clamped", 3.0, 4))


@pytest.mark.parametrize("U", [-0.999 * np.pi**2, -5.0, -1e-9, 0.0, 1e-9, 1.0, 10.0, 100.0, 1e3, 1e4])
def test_pinned_pinned_determinant_matches_closed_form(U):
    n = 25
    closed = analytic_omegas("pinned", "pinned", U, n)
    k = np.arange(1, n + 1) * np.pi
    np.testing.assert_allclose(closed, k * np.sqrt(k**2 + U), rtol=1e-15)
    numeric = solve_characteristic("pinned", "pinned", U, n)
    np.testing.assert_allclose(numeric, closed, rtol=1e-12)


def _bc_rows(kind: str, x: float, a: float, b: float, U: float) -> np.ndarray:
    """Boundary rows for W = A e^{-a x} + B e^{a(x-1)} + C cos bx + D sin bx."""

    def d(k: int) -> np.ndarray:
        return np.array(
            [
                (-a) ** k * math.exp(-a * x),
                a**k * math.exp(a * (x - 1.0)),
                b**k * math.cos(b * x + k * math.pi / 2),
                b**k * math.sin(b * x + k * math.pi / 2),
            ]
        )

    if kind == "clamped":
        rows = [d(0), d(1)]
    elif kind == "pinned":
        rows = [d(0), d(2)]
    else:  # free: moment and shear (EI w''' - N w') vanish
        rows = [d(2), d(3) - U * d(1)]
    return np.array([r / np.linalg.norm(r) for r in rows])


def _det_ratio(pair: tuple[str, str], U: float, Om: float) -> float:
    root = math.sqrt(U * U + 4 * Om * Om)
    a, b = math.sqrt((U + root) / 2), math.sqrt((-U + root) / 2)
    A = np.vstack([_bc_rows(pair[0], 0.0, a, b, U), _bc_rows(pair[1], 1.0, a, b, U)])
    s = np.linalg.svd(A, compute_uv=False)
    return s[-1] / s[0]


@pytest.mark.parametrize("pair", PAIRS)
@pytest.mark.parametrize("frac", [-0.5, 0.0, 1.0])
def test_characteristic_equations_against_boundary_determinant(pair, frac):
    """Roots are singular points of an independently built 4x4 BC matrix;
    points halfway between roots are not."""
    U = frac * critical_buckling_U(*pair) if frac < 0 else {0.0: 0.0, 1.0: 25.0}[frac]
    om = analytic_omegas(*pair, U, 6)
    for w in om:
        assert _det_ratio(pair, U, w) < 1e-9
    for w in 0.5 * (om[:-1] + om[1:]):
        assert _det_ratio(pair, U, w) > 1e-3


@pytest.mark.parametrize(
    "pair, asym",
    [
        (("clamped", "clamped"), lambda n: (n + 0.5) * np.pi),
        (("clamped", "free"), lambda n: (n - 0.5) * np.pi),
        (("clamped", "pinned"), lambda n: (n + 0.25) * np.pi),
    ],
)
def test_no_mode_skipped_high_modes(pair, asym):
    """At U = 0, sqrt(Omega_n) approaches its asymptote; a skipped mode would
    shift the index by one (an error of pi)."""
    n = 40
    k = np.sqrt(analytic_omegas(*pair, 0.0, n))
    idx = np.arange(1, n + 1)
    assert np.all(np.abs(k[5:] - asym(idx[5:])) < 1e-6)
    assert np.all(np.abs(k - asym(idx)) < 0.35)  # a skipped mode would be off by ~pi
    # beta spacing ~ pi for all U (tension and compression)
    for U in (-0.9 * critical_buckling_U(*pair), 50.0, 1e4):
        om = analytic_omegas(*pair, U, n)
        beta = np.sqrt((-U + np.sqrt(U * U + 4 * om**2)) / 2)
        gaps = np.diff(beta)
        assert np.all(gaps > 0.5 * np.pi) and np.all(gaps < 1.5 * np.pi)


def test_critical_buckling():
    assert critical_buckling_U("pinned", "pinned") == pytest.approx(np.pi**2, rel=1e-15)
    assert critical_buckling_U("clamped", "clamped") == pytest.approx(4 * np.pi**2, rel=1e-15)
    assert critical_buckling_U("free", "clamped") == pytest.approx(np.pi**2 / 4, rel=1e-15)
    ucp = critical_buckling_U("pinned", "clamped")
    assert ucp == pytest.approx(20.1907286, rel=1e-7)  # 2.0457 pi^2
    for pair in PAIRS:
        ucr = critical_buckling_U(*pair)
        o1 = [analytic_omegas(*pair, -ucr * (1 - eps), 1)[0] for eps in (1e-2, 1e-4, 1e-6)]
        assert o1[0] > o1[1] > o1[2] and o1[2] < 0.05  # Omega_1 -> 0 like sqrt(eps)
        # the FE model agrees: near-buckling frequency tends to 0 as well
        fe = _fe(pair, -ucr * (1 - 1e-2), 40).natural_frequencies_hz(1)
        assert _omega_hz_to_nondim(fe)[0] == pytest.approx(o1[0], rel=1e-4)


def test_invalid_inputs():
    for pair in [("free", "free"), ("pinned", "free"), ("free", "pinned")]:
        with pytest.raises(ValueError, match="not supported"):
            analytic_omegas(*pair, 0.0, 3)
        with pytest.raises(ValueError):
            critical_buckling_U(*pair)
    with pytest.raises(ValueError, match="unknown boundary"):
        analytic_omegas("sliding", "clamped", 0.0, 3)
    with pytest.raises(ValueError, match="buckling"):
        analytic_omegas("pinned", "pinned", -np.pi**2, 3)
    with pytest.raises(ValueError, match="maximum"):
        analytic_omegas("clamped", "clamped", 2e4, 3)
    with pytest.raises(ValueError):
        analytic_omegas("clamped", "clamped", float("nan"), 3)
    with pytest.raises(ValueError):
        analytic_omegas("clamped", "clamped", 0.0, 0)
    with pytest.raises(ValueError):
        analytic_frequencies_hz("clamped", "free", length=-1.0, EI=1.0, rhoA=1.0, N=0.0, n_modes=2)


def test_frequencies_hz_units():
    N = 13.0
    f = analytic_frequencies_hz("pinned", "pinned", length=L_, EI=EI_, rhoA=RHOA_, N=N, n_modes=4)
    n = np.arange(1, 5)
    # f_n = (n pi / L)^2 sqrt(EI/rhoA) sqrt(1 + N L^2/(n^2 pi^2 EI)) / (2 pi)
    expected = ((n * np.pi / L_) ** 2 * np.sqrt(EI_ / RHOA_)
                * np.sqrt(1 + N * L_**2 / (n**2 * np.pi**2 * EI_)) / (2 * np.pi))
    np.testing.assert_allclose(f, expected, rtol=1e-14)
    f_cf = analytic_frequencies_hz("clamped", "free", length=L_, EI=EI_, rhoA=RHOA_, N=0.0, n_modes=1)
    assert f_cf[0] == pytest.approx(3.516015 / (2 * np.pi * L_**2) * np.sqrt(EI_ / RHOA_), rel=1e-6)


# ==========================================================================
# Hermite FE: element level
# ==========================================================================
def test_element_matrices_match_gauss_quadrature():
    l, EI, rhoA, N = 0.37, 2.1, 0.8, -3.3
    gx, gw = np.polynomial.legendre.leggauss(6)  # exact for degree <= 11
    M = np.zeros((4, 4))
    Kb = np.zeros((4, 4))
    Kg = np.zeros((4, 4))
    for x, w in zip((gx + 1) / 2, gw / 2):
        Nf = hermite_shape_functions(x, l)
        # d/dx = (1/l) d/dxi of the cubics, written out by hand
        d1 = np.array([-6 * x + 6 * x**2, l * (1 - 4 * x + 3 * x**2), 6 * x - 6 * x**2, l * (3 * x**2 - 2 * x)]) / l
        d2 = np.array([-6 + 12 * x, l * (-4 + 6 * x), 6 - 12 * x, l * (6 * x - 2)]) / l**2
        M += w * l * rhoA * np.outer(Nf, Nf)
        Kb += w * l * EI * np.outer(d2, d2)
        Kg += w * l * N * np.outer(d1, d1)
    Me, Kbe, Kge = element_matrices(l, EI, rhoA, N)
    np.testing.assert_allclose(Me, M, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(Kbe, Kb, rtol=1e-12, atol=1e-12 * np.abs(Kbe).max())
    np.testing.assert_allclose(Kge, Kg, rtol=1e-12, atol=1e-12 * np.abs(Kge).max())
    # interpolation: N(0) = (1, 0, 0, 0), N(1) = (0, 0, 1, 0), rigid translation sums to 1
    np.testing.assert_allclose(hermite_shape_functions(0.0, l), [1, 0, 0, 0], atol=0)
    np.testing.assert_allclose(hermite_shape_functions(1.0, l), [0, 0, 1, 0], atol=1e-15)
    s = hermite_shape_functions(0.3, l)
    assert s[0] + s[2] == pytest.approx(1.0, abs=1e-15)


# ==========================================================================
# Hermite FE vs analytic
# ==========================================================================
@pytest.mark.parametrize("pair", PAIRS)
@pytest.mark.parametrize("ufrac", ["-0.5cr", 0.0, 10.0, 100.0])
def test_fe_converges_to_analytic(pair, ufrac):
    U = -0.5 * critical_buckling_U(*pair) if ufrac == "-0.5cr" else float(ufrac)
    om = analytic_omegas(*pair, U, 5)
    f_ref = analytic_frequencies_hz(*pair, length=L_, EI=EI_, rhoA=RHOA_, N=U * EI_ / L_**2, n_modes=5)
    np.testing.assert_allclose(_omega_hz_to_nondim(f_ref), om, rtol=1e-13)

    fe40 = _fe(pair, U, 40).natural_frequencies_hz(5)
    err40 = np.abs(fe40 / f_ref - 1)
    assert np.all(err40 < 1e-3), err40
    assert np.all(err40 < 5e-5), err40  # actually measured ~3e-5 at worst
    # Rayleigh–Ritz: FE is an upper bound (up to eigen-solver round-off ~1e-8)
    assert np.all(fe40 >= f_ref * (1 - 1e-7))

    # observed order ~4 in frequency (modes 1-3, meshes 4 -> 8 -> 16)
    e = [np.abs(_fe(pair, U, ne).natural_frequencies_hz(3) / f_ref[:3] - 1) for ne in (4, 8, 16)]
    order = np.log2(e[1] / e[2])
    assert np.all((order > 3.7) & (order < 4.4)), order


def test_free_end_is_natural_and_order_of_ends_irrelevant():
    a = hermite_beam(L_, 20, EI=EI_, rhoA=RHOA_, N=4.0, left=CLAMPED, right=FREE).natural_frequencies_hz(6)
    b = hermite_beam(L_, 20, EI=EI_, rhoA=RHOA_, N=4.0, left=FREE, right=CLAMPED).natural_frequencies_hz(6)
    np.testing.assert_allclose(a, b, rtol=1e-8)  # round-off only


# ==========================================================================
# elastic ends, point masses, damping matrices
# ==========================================================================
def test_elastic_ends_tend_to_clamped_and_pinned():
    ne, U = 24, 10.0
    N = U * EI_ / L_**2
    kt_unit, kr_unit = EI_ / L_**3, EI_ / L_
    clamped = _fe(("clamped", "clamped"), U, ne).natural_frequencies_hz(5)
    pinned = _fe(("pinned", "pinned"), U, ne).natural_frequencies_hz(5)
    prev_c = prev_p = None
    for s in (1e6, 1e8, 1e10):  # s must exceed the modal stiffnesses (Omega_5^2 ~ 1e5)
        ends = (s * kt_unit, s * kr_unit)
        fc = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, N=N, left=ends, right=ends).natural_frequencies_hz(5)
        fp = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, N=N, left=(s * kt_unit, 0.0),
                          right=(s * kt_unit, 0.0)).natural_frequencies_hz(5)
        assert np.all(fc < clamped * (1 + 1e-12)) and np.all(fp < pinned * (1 + 1e-12))
        ec, ep = np.max(np.abs(fc / clamped - 1)), np.max(np.abs(fp / pinned - 1))
        if prev_c is not None:
            assert 80 < prev_c / ec < 120 and 80 < prev_p / ep < 120  # error ~ 1/k
        prev_c, prev_p = ec, ep
    big = 1e12
    fc = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, N=N, left=(big * kt_unit, big * kr_unit),
                      right=(big * kt_unit, big * kr_unit)).natural_frequencies_hz(5)
    np.testing.assert_allclose(fc, clamped, rtol=1e-8)  # measured ~1e-9
    fp = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, N=N, left=(big * kt_unit, 0.0),
                      right=(big * kt_unit, 0.0)).natural_frequencies_hz(5)
    np.testing.assert_allclose(fp, pinned, rtol=1e-8)
    # soft supports lower the frequencies; free-free has two rigid-body modes
    ff = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, left=FREE, right=FREE).natural_frequencies_hz(4)
    assert ff[0] < 1e-5 * ff[2] and ff[1] < 1e-5 * ff[2]
    # free-free flexible mode: (4.7300)^2
    assert _omega_hz_to_nondim(ff[2:3])[0] == pytest.approx(22.3733, rel=1e-5)


def test_point_mass_midspan_pinned_pinned():
    ne = 20
    base = _fe(("pinned", "pinned"), 0.0, ne).natural_frequencies_hz(4)
    m = 0.3 * RHOA_ * L_
    loaded = _fe(("pinned", "pinned"), 0.0, ne, point_masses=[(m, L_ / 2)]).natural_frequencies_hz(4)
    assert loaded[0] < 0.9 * base[0]
    assert loaded[1] == pytest.approx(base[1], rel=1e-10)  # node at midspan
    assert loaded[3] == pytest.approx(base[3], rel=1e-10)
    # Rayleigh estimate with the sine mode: f1^2 ~ f1_0^2 / (1 + 2 m/(rhoA L)) (upper bound)
    assert loaded[0] < base[0] / math.sqrt(1 + 2 * m / (RHOA_ * L_)) * (1 + 1e-9)
    assert loaded[0] > 0.98 * base[0] / math.sqrt(1 + 2 * m / (RHOA_ * L_))


def test_point_mass_interpolation_rigid_translation():
    """Masses at arbitrary x: the rigid translation r = (1, 0, 1, 0, ...)
    has kinetic mass r^T M r = rhoA L + sum(m)."""
    masses = [(0.2, 0.0), (0.7, 0.123), (1.1, L_ / 3), (0.05, L_)]
    b = hermite_beam(L_, 7, EI=EI_, rhoA=RHOA_, left=FREE, right=FREE, point_masses=masses)
    r = np.zeros(b.M.shape[0])
    r[0::2] = 1.0
    assert r @ b.M @ r == pytest.approx(RHOA_ * L_ + sum(m for m, _ in masses), rel=1e-13)
    # first moment: r_x = (x_i, 1, ...) gives rhoA L^2/2 + sum m x
    rx = np.zeros_like(r)
    rx[0::2] = np.linspace(0, L_, 8)
    rx[1::2] = 1.0
    assert r @ b.M @ rx == pytest.approx(RHOA_ * L_**2 / 2 + sum(m * x for m, x in masses), rel=1e-13)
    # displacement row interpolates exactly for a cubic field
    coef = np.array([0.3, -1.2, 0.7, 2.0])
    xs = np.linspace(0, L_, 8)
    q = np.zeros_like(r)
    q[0::2] = np.polyval(coef, xs)
    q[1::2] = np.polyval(np.polyder(coef), xs)
    for x in (0.0, 0.05, 0.61, L_):
        assert b.displacement_row(x) @ q == pytest.approx(np.polyval(coef, x), abs=1e-12)
    with pytest.raises(ValueError):
        b.load_vector(1.01 * L_)


def test_damping_matrices():
    c, eta = 0.8, 3e-3
    b0 = hermite_beam(L_, 9, EI=EI_, rhoA=RHOA_, N=2.0, left=CLAMPED, right=PINNED,
                      point_masses=[(0.4, 0.5)])
    bc = hermite_beam(L_, 9, EI=EI_, rhoA=RHOA_, N=2.0, c=c, left=CLAMPED, right=PINNED)
    bm = hermite_beam(L_, 9, EI=EI_, rhoA=RHOA_, left=CLAMPED, right=PINNED)
    be = hermite_beam(L_, 9, EI=EI_, rhoA=RHOA_, N=2.0, eta=eta, left=CLAMPED, right=PINNED,
                      point_masses=[(0.4, 0.5)])
    np.testing.assert_array_equal(b0.C, 0.0)
    np.testing.assert_allclose(bc.C, c / RHOA_ * bm.M, rtol=1e-14)  # no point masses in C
    np.testing.assert_allclose(be.C, eta * bm.K, rtol=1e-14)  # bending part only (N = 0 in bm)
    assert not b0.M.flags.writeable
    with pytest.raises(ValueError):
        hermite_beam(L_, 4, EI=-1.0, rhoA=1.0)
    with pytest.raises(ValueError):
        hermite_beam(L_, 4, EI=1.0, rhoA=1.0, left=(-1.0, 0.0))


def test_static_deflection_with_tension():
    """Simply supported, tension N, midspan load P:
    w(L/2) = P/(2 N k) (k L/2 - tanh(k L/2)), k = sqrt(N/EI)."""
    P, N = 1.7, 40.0
    k = math.sqrt(N / EI_)
    exact = P / (2 * N * k) * (k * L_ / 2 - math.tanh(k * L_ / 2))
    b = hermite_beam(L_, 40, EI=EI_, rhoA=RHOA_, N=N, left=PINNED, right=PINNED)
    w = b.displacement_row(L_ / 2) @ np.linalg.solve(b.K, P * b.load_vector(L_ / 2))
    assert w == pytest.approx(exact, rel=1e-6)


# ==========================================================================
# Newmark
# ==========================================================================
def test_newmark_step_load_tends_to_static_cantilever():
    P = 2.5
    b0 = hermite_beam(L_, 10, EI=EI_, rhoA=RHOA_, left=CLAMPED, right=FREE)
    f1 = b0.natural_frequencies_hz(1)[0]
    c = 2 * 0.7 * RHOA_ * 2 * np.pi * f1  # ~70 % of critical in mode 1
    b = hermite_beam(L_, 10, EI=EI_, rhoA=RHOA_, c=c, eta=1e-4, left=CLAMPED, right=FREE)
    dt = 1 / (50 * f1)
    u = np.full((50 * 12, 1), P)
    y = newmark_simulate(
        b, forces_x=[L_],
        sensors=[(L_, "displacement"), (L_, "velocity"), (L_, "acceleration"), (L_ / 2, "displacement")],
        u=u, dt=dt, substeps=2,
    )
    static_tip = P * L_**3 / (3 * EI_)
    assert y[-1, 0] == pytest.approx(static_tip, rel=1e-6)
    assert y[-1, 3] == pytest.approx(P * (L_ / 2) ** 2 * (3 * L_ - L_ / 2) / (6 * EI_), rel=1e-6)
    assert abs(y[-1, 1]) < 1e-6 * static_tip * f1 and abs(y[-1, 2]) < 1e-4 * static_tip * f1**2
    # at t0 the beam is at rest and the acceleration already reflects u[0]
    assert y[0, 0] == 0.0 and y[0, 1] == 0.0
    a0 = b.displacement_row(L_) @ np.linalg.solve(b.M, P * b.load_vector(L_))
    assert y[0, 2] == pytest.approx(a0, rel=1e-12)
    assert a0 > 0


def test_newmark_free_vibration_frequency():
    N = 5.0
    b = hermite_beam(L_, 16, EI=EI_, rhoA=RHOA_, N=N, left=PINNED, right=PINNED)
    f1 = b.natural_frequencies_hz(1)[0]
    per = 100
    dt = 1 / (per * f1)
    # hold for 2.5 periods: mode 1 is then at its extreme (2x static), at rest
    n_hold, n_free = 5 * per // 2, 40 * per
    u = np.zeros((n_hold + n_free, 1))
    u[:n_hold] = 1.0
    y = newmark_simulate(b, forces_x=[L_ / 2], sensors=[(L_ / 2, "displacement")], u=u, dt=dt)[:, 0]
    z = y[n_hold + 1:]
    z = z - z.mean()
    i = np.flatnonzero(np.sign(z[:-1]) != np.sign(z[1:]))
    tc = (i + z[i] / (z[i] - z[i + 1])) * dt  # linear interpolation of crossings
    half_period = np.polyfit(np.arange(tc.size), tc, 1)[0]
    f_meas = 1 / (2 * half_period)
    # average-acceleration Newmark: tan(w_d h / 2) = w h / 2 (period elongation)
    w, h = 2 * np.pi * f1, dt
    f_newmark = 2 / h * math.atan(w * h / 2) / (2 * np.pi)
    assert f_meas == pytest.approx(f_newmark, rel=2e-4)
    f_an = analytic_frequencies_hz("pinned", "pinned", length=L_, EI=EI_, rhoA=RHOA_, N=N, n_modes=1)[0]
    assert f_meas == pytest.approx(f_an, rel=1e-3)


def _exact_zoh(beam: HermiteBeam, Phi: np.ndarray, rows: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
    """Exact ZOH response of the semi-discrete FE system (matrix exponential)."""
    n = beam.M.shape[0]
    Minv = np.linalg.inv(beam.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ beam.K, -Minv @ beam.C]])
    B = np.vstack([np.zeros((n, Phi.shape[1])), Minv @ Phi])
    big = np.zeros((2 * n + B.shape[1],) * 2)
    big[: 2 * n, : 2 * n] = A
    big[: 2 * n, 2 * n:] = B
    E = sla.expm(big * dt)
    Ad, Bd = E[: 2 * n, : 2 * n], E[: 2 * n, 2 * n:]
    x = np.zeros(2 * n)
    out = []
    for k in range(u.shape[0]):
        acc = Minv @ (Phi @ u[k] - beam.C @ x[n:] - beam.K @ x[:n])
        out.append(np.concatenate([rows @ x[:n], rows @ x[n:], rows @ acc]))
        x = Ad @ x + Bd @ u[k]
    return np.array(out)


def test_newmark_matches_exact_zoh_and_converges_second_order():
    # White ZOH input excites every FE mode, so the high modes must be resolved
    # (h * omega_max ~ 1) and damped: coarse mesh, Kelvin–Voigt damping.
    b = hermite_beam(L_, 4, EI=EI_, rhoA=RHOA_, N=3.0, c=0.2, eta=2e-3, left=CLAMPED, right=FREE,
                     point_masses=[(0.1, 0.8)])
    f1 = b.natural_frequencies_hz(1)[0]
    dt = 1 / (20 * f1)
    rng = np.random.default_rng(1)
    u = rng.normal(size=(120, 2))
    fx = [0.4, L_]
    xs = 0.9
    sensors = [(xs, "displacement"), (xs, "velocity"), (xs, "acceleration")]
    Phi = np.column_stack([b.load_vector(x) for x in fx])
    ref = _exact_zoh(b, Phi, b.displacement_row(xs)[None, :], u, dt)
    errs = []
    for s in (16, 32, 64):
        y = newmark_simulate(b, forces_x=fx, sensors=sensors, u=u, dt=dt, substeps=s)
        errs.append(np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0))
    errs = np.array(errs)
    # measured (disp, vel, acc): 9.5e-5, 7.6e-4, 1.7e-3 relative at 64 substeps
    assert np.all(errs[-1] < [2e-4, 1.5e-3, 3e-3]), errs
    ratio = errs[:-1] / errs[1:]
    assert np.all((ratio > 3.5) & (ratio < 4.5)), ratio  # second order in h


def test_newmark_input_validation():
    b = hermite_beam(L_, 4, EI=EI_, rhoA=RHOA_, left=CLAMPED, right=FREE)
    with pytest.raises(ValueError):
        newmark_simulate(b, forces_x=[L_], sensors=[(L_, "strain")], u=np.zeros((5, 1)), dt=0.01)
    with pytest.raises(ValueError):
        newmark_simulate(b, forces_x=[L_, 0.5], sensors=[(L_, "velocity")], u=np.zeros((5, 1)), dt=0.01)
    with pytest.raises(ValueError):
        newmark_simulate(b, forces_x=[L_], sensors=[(L_, "velocity")], u=np.zeros((5, 1)), dt=0.0)
    y = newmark_simulate(b, forces_x=[L_], sensors=[(L_, "velocity")], u=np.ones(5), dt=0.01)
    assert y.shape == (5, 1)


# ==========================================================================
# rotary inertia, Winkler foundation, axial-stiffness matrix, linear input
# ==========================================================================


@pytest.mark.parametrize("rhoI, kf, N", [(0.0, 0.0, 0.0), (3e-3, 0.0, 2.0), (0.0, 40.0, -1.5), (2e-2, 25.0, 5.0)])
def test_rayleigh_winkler_pinned_pinned_closed_form(rhoI, kf, N):
    """Pinned-pinned modes are sin(n pi x/L) for every rhoI, kf, N:
    omega_n^2 = (EI k^4 + N k^2 + kf) / (rhoA + rhoI k^2), k = n pi / L."""
    n = np.arange(1, 7)
    k = n * np.pi / L_
    w = np.sqrt((EI_ * k**4 + N * k**2 + kf) / (RHOA_ + rhoI * k**2))
    errs = []
    for ne in (30, 60):
        fe = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, N=N, rhoI=rhoI, kf=kf, left=PINNED, right=PINNED)
        errs.append(np.abs(2 * np.pi * fe.natural_frequencies_hz(6) / w - 1.0))
    assert errs[1].max() < 1e-5  # measured 7e-6 (mode 6), 3e-9 (mode 1)
    np.testing.assert_allclose(errs[0][2:] / errs[1][2:], 16.0, rtol=0.1)  # fourth-order convergence


def test_rotary_inertia_and_foundation_matrices():
    b0 = hermite_beam(L_, 12, EI=EI_, rhoA=RHOA_, N=0.7, left=CLAMPED, right=FREE)
    b1 = hermite_beam(L_, 12, EI=EI_, rhoA=RHOA_, N=0.7, left=CLAMPED, right=FREE, rhoI=0.0, kf=0.0)
    np.testing.assert_array_equal(b0.M, b1.M)  # backward compatible defaults
    np.testing.assert_array_equal(b0.K, b1.K)
    rhoI, kf = 0.013, 55.0
    b2 = hermite_beam(L_, 12, EI=EI_, rhoA=RHOA_, N=0.7, left=CLAMPED, right=FREE, rhoI=rhoI, kf=kf)
    # M gains rhoI * int N'^T N' (the axial matrix), K gains kf/rhoA * translational mass
    np.testing.assert_allclose(b2.M - b0.M, rhoI * b0.K_axial, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b2.K - b0.K, (kf / RHOA_) * b0.M, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(b2.C, b0.C)  # viscous damping acts on rhoA only
    # K_axial = dK/dN
    b3 = hermite_beam(L_, 12, EI=EI_, rhoA=RHOA_, N=3.7, left=CLAMPED, right=FREE)
    np.testing.assert_allclose(b3.K - b0.K, 3.0 * b0.K_axial, rtol=1e-10, atol=1e-10)
    with pytest.raises(ParameterError, match="rhoI"):
        hermite_beam(L_, 4, EI=EI_, rhoA=RHOA_, rhoI=-1.0)
    with pytest.raises(ParameterError, match="kf"):
        hermite_beam(L_, 4, EI=EI_, rhoA=RHOA_, kf=float("nan"))


def test_axial_matrix_integrates_slope_squared_exactly_for_cubics():
    """q^T K_axial q = int_0^L w_x^2 dx, exact for a cubic w (Hermite interpolation is exact)."""
    ne = 7
    b = hermite_beam(L_, ne, EI=EI_, rhoA=RHOA_, left=FREE, right=FREE)
    x = np.linspace(0.0, L_, ne + 1)
    def w(x):
        return 0.3 - 1.2 * x + 0.8 * x**2 - 0.45 * x**3

    def dw(x):
        return -1.2 + 1.6 * x - 1.35 * x**2

    q = np.column_stack([w(x), dw(x)]).ravel()
    exact = quad(lambda s: dw(s) ** 2, 0.0, L_)[0]
    assert q @ b.K_axial @ q == pytest.approx(exact, rel=1e-13)


def test_newmark_linear_interpolation_option():
    b = hermite_beam(L_, 8, EI=EI_, rhoA=RHOA_, c=0.3, left=CLAMPED, right=FREE)
    kw = {"forces_x": [L_], "sensors": [(L_, "displacement"), (0.5 * L_, "acceleration")], "dt": 0.002, "substeps": 3}
    const = np.ones(200)
    # a constant force: hold and linear interpolation coincide
    np.testing.assert_allclose(newmark_simulate(b, u=const, interpolation="linear", **kw),
                               newmark_simulate(b, u=const, **kw), rtol=1e-12, atol=1e-14)
    # a ramp: the held force lags the linear one by half a sample on average
    ramp = np.arange(400) * 1e-3
    y_lin = newmark_simulate(b, u=ramp, interpolation="linear", **kw)[:, 0]
    y_hold = newmark_simulate(b, u=ramp, **kw)[:, 0]
    y_shift = newmark_simulate(b, u=ramp + 0.5e-3, **kw)[:, 0]  # hold of the ramp advanced by half a sample
    assert np.abs(y_lin - y_hold)[-50:].min() > 0
    np.testing.assert_allclose(y_lin[-50:], y_shift[-50:], rtol=2e-3)
    with pytest.raises(ParameterError, match="interpolation"):
        newmark_simulate(b, u=const, interpolation="cubic", **kw)
