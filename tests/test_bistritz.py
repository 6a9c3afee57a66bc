"""Tests of the Bistritz unit-circle zero-location test (ebb_model.stability.bistritz).

Ground truth:

* floating-point polynomials: the moduli of :func:`numpy.roots`, skipping the
  (few) polynomials with a root within ``1e-6`` of the unit circle;
* exact (``Fraction``) polynomials: the counts known by construction and/or
  the roots of the *square-free factors* of the polynomial (Yun's algorithm in
  exact rational arithmetic, then :func:`numpy.roots` of each factor), so that
  multiple zeros on the circle are located reliably.
"""
from __future__ import annotations

import itertools
import math
from fractions import Fraction as F

import numpy as np
import pytest

from ebb_model.stability.bistritz import ZeroLocation, bistritz, bistritz_sequence

Poly = list  # list of Fractions, highest power first


# ---------------------------------------------------------------------------
# exact polynomial helpers (highest power first)
# ---------------------------------------------------------------------------

def _trim(p: Poly) -> Poly:
    i = 0
    while i < len(p) and p[i] == 0:
        i += 1
    return list(p[i:])


def _frac(p) -> Poly:
    return [F(x) for x in p]


def _mul(a: Poly, b: Poly) -> Poly:
    out = [F(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def _product(*factors: Poly) -> Poly:
    out = [F(1)]
    for f in factors:
        out = _mul(out, _frac(f))
    return out


def _sub(a: Poly, b: Poly) -> Poly:
    n = max(len(a), len(b))
    a = [F(0)] * (n - len(a)) + list(a)
    b = [F(0)] * (n - len(b)) + list(b)
    return _trim([x - y for x, y in zip(a, b)])


def _divmod(a: Poly, b: Poly) -> tuple[Poly, Poly]:
    a = list(a)
    q = []
    while len(a) >= len(b):
        c = a[0] / b[0]
        q.append(c)
        for i in range(len(b)):
            a[i] -= c * b[i]
        a.pop(0)
    return q, _trim(a)


def _div(a: Poly, b: Poly) -> Poly:
    q, r = _divmod(a, b)
    assert not r
    return q


def _gcd(a: Poly, b: Poly) -> Poly:
    a, b = _trim(a), _trim(b)
    while b:
        a, b = b, _divmod(a, b)[1]
    return [x / a[0] for x in a]


def _deriv(p: Poly) -> Poly:
    n = len(p) - 1
    return _trim([c * (n - i) for i, c in enumerate(p[:-1])])


def _squarefree(p: Poly) -> list[tuple[Poly, int]]:
    """Yun's square-free factorisation: ``p = c * prod f_i^i``."""
    p = _trim(p)
    if len(p) <= 1:
        return []
    a = _gcd(p, _deriv(p))
    b = _div(p, a)
    c = _div(_deriv(p), a)
    d = _sub(c, _deriv(b))
    out, i = [], 1
    while len(b) > 1:
        g = _gcd(b, d) if d else [x / b[0] for x in b]
        if len(g) > 1:
            out.append((g, i))
        b = _div(b, g)
        c = _div(d, g) if d else []
        d = _sub(c, _deriv(b))
        i += 1
    return out


def _root_counts(p: Poly) -> ZeroLocation:
    """(inside, on, outside) from the roots of the square-free factors."""
    inside = on = outside = 0
    for factor, mult in _squarefree(p):
        for z in np.roots([float(x) for x in factor]):
            dist = abs(abs(z) - 1.0)
            assert not (1e-9 < dist < 1e-6), f"ambiguous root {z} of {factor}"
            if dist <= 1e-9:
                on += mult
            elif abs(z) < 1:
                inside += mult
            else:
                outside += mult
    return ZeroLocation(inside, on, outside)


def _has_reciprocal_factor(p: Poly) -> bool:
    """Whether gcd(D, D#) is nontrivial for the polynomial reduced as in the
    module (zeros at 0 and 1 removed): i.e. an essential singularity occurs."""
    p = _trim(p)
    while p[-1] == 0:
        p = p[:-1]
    while len(p) > 1 and sum(p) == 0:
        p = _div(p, [F(1), F(-1)])
    return len(p) > 1 and len(_gcd(p, p[::-1])) > 1


def _nonessential_hits(seq: list[np.ndarray]) -> int:
    """Number of T_k, 1 <= k <= n-1, with T_k(0) = 0 (and T_k not identically 0)."""
    return sum(1 for t in seq[1:-1] if t[-1] == 0)


# ---------------------------------------------------------------------------
# 1. random floating-point polynomials against numpy.roots
# ---------------------------------------------------------------------------

def _roots_poly(rng: np.random.Generator, deg: int, sigma: float) -> np.ndarray:
    """Real polynomial from random roots with log-moduli ~ N(0, sigma)."""
    roots: list[complex] = []
    while len(roots) < deg:
        r = math.exp(rng.normal(0.0, sigma))
        if len(roots) <= deg - 2 and rng.random() < 0.7:
            th = rng.uniform(0.0, math.pi)
            roots += [r * complex(math.cos(th), math.sin(th)), r * complex(math.cos(th), -math.sin(th))]
        else:
            roots.append(r * rng.choice([-1.0, 1.0]))
    return np.real(np.poly(roots)) * rng.uniform(0.1, 10.0) * rng.choice([-1.0, 1.0])


def _random_poly(rng: np.random.Generator, kind: str, deg: int) -> np.ndarray:
    if kind == "gauss":
        return rng.standard_normal(deg + 1)
    if kind == "uniform_wide_scale":           # coefficient scale 1e-100 .. 1e100
        return rng.uniform(-1.0, 1.0, deg + 1) * 10.0 ** rng.uniform(-100, 100)
    if kind == "cauchy":                       # heavy-tailed coefficients
        return rng.standard_cauchy(deg + 1)
    if kind == "kac_rescaled":                 # Gaussian poly D(rho z) with |d_0| = |d_n|:
        c = rng.standard_normal(deg + 1)       # roots cluster around the unit circle
        rho = abs(c[-1] / c[0]) ** (1.0 / deg) * math.exp(rng.normal(0.0, 0.05))
        return c * rho ** -np.arange(deg + 1.0)
    if kind == "sparse":                       # exact zeros, incl. leading/trailing ones
        c = rng.standard_normal(deg + 1)
        c[rng.random(deg + 1) < 0.3] = 0.0
        if not c.any():
            c[-1] = 1.0
        return c
    if kind == "near_circle":                  # roots within a few % of the circle
        return _roots_poly(rng, deg, 0.05)
    if kind == "moderate":
        return _roots_poly(rng, deg, 0.3)
    raise AssertionError(kind)


_KINDS = ("gauss", "uniform_wide_scale", "cauchy", "kac_rescaled", "sparse", "near_circle", "moderate")


def test_random_float_polynomials_agree_with_numpy_roots():
    rng = np.random.default_rng(20240521)
    total = 14_000
    skipped = 0
    checked = dict.fromkeys(_KINDS, 0)
    mismatches = []
    for i in range(total):
        kind = _KINDS[i % len(_KINDS)]
        c = _random_poly(rng, kind, int(rng.integers(1, 9)))
        moduli = np.abs(np.roots(c))           # np.roots strips leading zeros too
        if np.any(np.abs(moduli - 1.0) < 1e-6):
            skipped += 1
            continue
        expected = ZeroLocation(int(np.sum(moduli < 1)), 0, int(np.sum(moduli > 1)))
        got = bistritz(c)
        checked[kind] += 1
        if got != expected:
            mismatches.append((kind, c.tolist(), got, expected))
    assert not mismatches, mismatches[:5]
    assert skipped <= 0.01 * total, skipped
    assert min(checked.values()) >= 0.95 * total / len(_KINDS)


def test_float_and_exact_arithmetic_agree_on_the_same_numbers():
    # Fraction(x) is the exact value of the float x: both runs see one polynomial.
    rng = np.random.default_rng(7)
    for i in range(300):
        kind = _KINDS[i % len(_KINDS)]
        c = _random_poly(rng, kind, int(rng.integers(1, 9)))
        if np.any(np.abs(np.abs(np.roots(c)) - 1.0) < 1e-6):
            continue                           # float zero tests have a tolerance
        assert bistritz(c) == bistritz([F(x) for x in c]), (kind, c.tolist())


def test_high_degree_float():
    rng = np.random.default_rng(3)
    for deg in (20, 41, 60):
        c = rng.standard_normal(deg + 1)
        moduli = np.abs(np.roots(c))
        assert not np.any(np.abs(moduli - 1.0) < 1e-6)
        assert bistritz(c) == ZeroLocation(int(np.sum(moduli < 1)), 0, int(np.sum(moduli > 1)))


@pytest.mark.parametrize("factor", [2.0 ** 900, 2.0 ** -900, 1e200, 1e-200, 6e307, 1e-305, -3.7])
def test_scale_invariance(factor):
    c = np.array([2.0, -1.3, 0.4, 1.1, -0.2, 0.05])
    assert bistritz(c * factor) == bistritz(c)


# ---------------------------------------------------------------------------
# 2. exact cases hitting every branch
# ---------------------------------------------------------------------------

_H = F(1, 2)
_EXACT_CASES = {
    # zeros at z = 1 (divided out first)
    "z-1": ([1, -1], (0, 1, 0)),
    "(z-1)^2 (z-1/2)": (_product([1, -1], [1, -1], [1, -_H]), (1, 2, 0)),
    # z = -1: essential singularity at s = 1
    "z+1": ([1, 1], (0, 1, 0)),
    "(z+1)^3": (_product([1, 1], [1, 1], [1, 1]), (0, 3, 0)),
    "(z+1)(z-3)": (_product([1, 1], [1, -3]), (0, 1, 1)),
    # pairs on the circle
    "z^2+1": ([1, 0, 1], (0, 2, 0)),
    "z^2-z+1": ([1, -1, 1], (0, 2, 0)),
    "z^2+z+1": ([1, 1, 1], (0, 2, 0)),
    "z^2-6/5z+1": ([1, F(-6, 5), 1], (0, 2, 0)),
    "z^4-1": ([1, 0, 0, 0, -1], (0, 4, 0)),
    "(z-1)(z^2-z+1) antisymmetric": ([1, -2, 2, -1], (0, 3, 0)),
    # reciprocal pairs: essential singularity without circle zeros
    "(z-2)(z-1/2)": ([1, F(-5, 2), 1], (1, 0, 1)),
    "(z-2)(z-1/2)(z+1/3)": (_product([1, F(-5, 2), 1], [1, F(1, 3)]), (2, 0, 1)),
    "(z^2-z+2)(2z^2-z+1) reciprocal quadruple": (_product([1, -1, 2], [2, -1, 1]), (2, 0, 2)),
    "(z+3)(z+1/3)(z-4/5)": (_product([1, 3], [1, F(1, 3)], [1, F(-4, 5)]), (2, 0, 1)),
    # multiple circle zeros: repeated essential singularities
    "(z^2+1)^2": (_product([1, 0, 1], [1, 0, 1]), (0, 4, 0)),
    "(z^2+z+1)^2 (z+1)^3 (z-1)": (_product([1, 1, 1], [1, 1, 1], [1, 1], [1, 1], [1, 1], [1, -1]), (0, 8, 0)),
    "(z^2-6/5z+1)^2 (z-1/3)^2 (z+3)": (
        _product([1, F(-6, 5), 1], [1, F(-6, 5), 1], [1, F(-1, 3)], [1, F(-1, 3)], [1, 3]), (2, 4, 1)),
    "(z^2+1)^3 (z-2)(z-1/2)": (_product([1, 0, 1], [1, 0, 1], [1, 0, 1], [1, F(-5, 2), 1]), (1, 6, 1)),
    "circle + reciprocal + inside + outside": (
        _product([1, 1, 1], [1, F(-5, 2), 1], [1, F(1, 4)], [1, 0, F(9, 4)]), (2, 2, 3)),
    # zeros at z = 0
    "z^3": ([1, 0, 0, 0], (3, 0, 0)),
    "z^2 (z-3)": ([1, -3, 0, 0], (2, 0, 1)),
    "z (z+1)": ([1, 1, 0], (1, 1, 0)),
    # nonessential singularities (found by brute force, see the exhaustive test):
    # T_4 = -z^2 (m = 2), then T_2 = z (m = 1)
    "nonessential m=2": ([-2, -2, -2, -1, -2, -2], (3, 0, 2)),
    # T_n(0) = d_0 + d_n = 0 (delta_{n-1} = 0): not a singularity
    "T_n(0)=0": ([1, 1, 1, -1], None),
    "symmetric, no circle zeros?": ([1, 3, -1, 3, 1], None),
}


@pytest.mark.parametrize("name", list(_EXACT_CASES))
def test_exact_cases(name):
    coeffs, expected = _EXACT_CASES[name]
    coeffs = _frac(coeffs)
    got = bistritz(coeffs)
    assert got == _root_counts(coeffs), name
    if expected is not None:
        assert got == ZeroLocation(*expected), name
    assert got.degree == len(_trim(coeffs)) - 1


def test_nonessential_example_really_is_singular():
    seq = bistritz_sequence(_frac([-2, -2, -2, -1, -2, -2]))
    assert [t.tolist() for t in seq[1:4]] == [[0, 0, -1, 0, 0], [4, 3, 3, 4], [0, 1, 0]]
    assert _nonessential_hits(seq) == 2


def test_exhaustive_small_integer_polynomials():
    """Every integer polynomial of degree 1..4 with coefficients in -2..2 and of
    degree 5..6 with coefficients in -1..1, against the exact root counts; the
    branches of the recursion are counted to show they are exercised.  (Pure
    reciprocal pairs without circle zeros need larger coefficients, e.g.
    2z^2 - 5z + 2; they are in ``_EXACT_CASES`` and the random products.)"""
    branches = dict(nonessential=0, nonessential_m2=0, consecutive_nonessential=0,
                    tn0_zero=0, essential=0, essential_and_off_circle=0, multiple_circle=0, at_one=0)
    n_polys = 0
    space = [(d, range(-2, 3)) for d in range(1, 5)] + [(d, range(-1, 2)) for d in (5, 6)]
    for deg, values in space:
        for cs in itertools.product(values, repeat=deg + 1):
            if cs[0] == 0:
                continue
            n_polys += 1
            p = _frac(cs)
            got = bistritz(p)
            truth = _root_counts(p)
            assert got == truth, (cs, got, truth)

            seq = bistritz_sequence(p)
            zero_const = [t[-1] == 0 for t in seq]
            if any(zero_const[1:-1]):
                branches["nonessential"] += 1
            if any(len(t) >= 5 and t[-1] == 0 and t[-2] == 0 for t in seq[1:-1]):
                branches["nonessential_m2"] += 1
            if any(a and b for a, b in zip(zero_const[1:-2], zero_const[2:-1])):
                branches["consecutive_nonessential"] += 1
            if zero_const[0] and len(seq) > 1:
                branches["tn0_zero"] += 1
            if _has_reciprocal_factor(p):
                branches["essential"] += 1
                if got.inside + got.outside > 0:
                    branches["essential_and_off_circle"] += 1
            if any(m > 1 and any(abs(abs(z) - 1) < 1e-9 for z in np.roots([float(x) for x in f]))
                   for f, m in _squarefree(p)):
                branches["multiple_circle"] += 1
            if sum(p) == 0:
                branches["at_one"] += 1
    assert n_polys == 3120 + 486 + 1458
    assert all(v > 0 for v in branches.values()), branches
    assert branches["nonessential"] > 500 and branches["essential"] > 500, branches


def _rat(rng: np.random.Generator, lo: int, hi: int) -> F:
    q = int(rng.integers(1, 7))
    return F(int(rng.integers(lo * q, hi * q + 1)), q)


def test_random_exact_products_of_known_factors():
    """Products of factors with known zero locations, with multiplicities
    (degrees up to ~30): circle pairs, +-1, reciprocal pairs and quadruples,
    zeros at 0, ordinary zeros inside/outside."""
    rng = np.random.default_rng(11)
    for _ in range(150):
        p = [F(int(rng.choice([-3, -2, -1, 1, 2, 3])))]
        counts = np.zeros(3, dtype=int)
        for _ in range(int(rng.integers(1, 6))):
            kind = int(rng.integers(0, 8))
            if kind == 0:
                f, c = [1, -1], (0, 1, 0)
            elif kind == 1:
                f, c = [1, 1], (0, 1, 0)
            elif kind == 2:                    # z^2 - 2a z + 1, |a| < 1
                a = _rat(rng, -1, 1)
                while abs(a) >= 1:
                    a = _rat(rng, -1, 1)
                f, c = [1, -2 * a, 1], (0, 2, 0)
            elif kind == 3:                    # (z - r)(z - 1/r)
                r = _rat(rng, 2, 4) * int(rng.choice([-1, 1]))
                f, c = [1, -(r + 1 / r), 1], (1, 0, 1)
            elif kind == 4:                    # quadruple rho e^{+-it}, e^{+-it}/rho
                a, rho = _rat(rng, -1, 1) / 2, _rat(rng, 2, 3)
                f, c = _product([1, -2 * a * rho, rho * rho], [1, -2 * a / rho, 1 / (rho * rho)]), (2, 0, 2)
            elif kind == 5:
                f, c = [1, 0], (1, 0, 0)
            elif kind == 6:                    # real zero off the circle
                r = _rat(rng, -3, 3)
                while abs(r) == 1:
                    r = _rat(rng, -3, 3)
                f, c = [1, -r], ((1, 0, 0) if abs(r) < 1 else (0, 0, 1))
            else:                              # complex pair off the circle
                re, im = _rat(rng, -2, 2), _rat(rng, 1, 2)
                r2 = re * re + im * im
                if r2 == 1:
                    r2 = F(4)
                f, c = [1, -2 * re, r2], ((2, 0, 0) if r2 < 1 else (0, 0, 2))
            for _ in range(int(rng.choice([1, 1, 2, 3]))):
                p = _mul(p, _frac(f))
                counts += c
        assert bistritz(p) == ZeroLocation(*map(int, counts)), p


# ---------------------------------------------------------------------------
# the sequence itself
# ---------------------------------------------------------------------------

def _poly_mul_low(a, b):
    out = [F(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def test_sequence_structure_and_normal_recursion():
    d = _frac([3, -1, F(1, 2), 2, -4, 1])          # highest first
    seq = bistritz_sequence(d)
    n = 5
    assert len(seq) == n + 1
    for i, t in enumerate(seq):
        assert len(t) == n - i + 1 and t.dtype == object
        assert all(isinstance(x, F) for x in t)
        assert t.tolist() == t[::-1].tolist()        # symmetric
    low = d[::-1]
    dstar = low[::-1]
    assert seq[0][::-1].tolist() == [a + b for a, b in zip(low, dstar)]
    diff = [a - b for a, b in zip(low, dstar)]
    # (z - 1) T_{n-1} = D - D#
    assert _poly_mul_low([F(-1), F(1)], seq[1][::-1].tolist()) == diff
    # z T_{k-1} = delta_k (1 + z) T_k - T_{k+1} (normal case: all T_k(0) != 0)
    for j in range(2, n + 1):
        tk1, tk, tkm1 = (seq[j - 2][::-1].tolist(), seq[j - 1][::-1].tolist(), seq[j][::-1].tolist())
        assert tk[0] != 0
        delta = tk1[0] / tk[0]
        rhs = [delta * x - y for x, y in zip(_poly_mul_low([F(1), F(1)], tk), tk1)]
        assert rhs == [F(0)] + tkm1 + [F(0)]


def test_essential_restart_polynomial():
    # D = z^2 - 5/2 z + 1 is symmetric: T_1 vanishes at once, s = 2.
    # p = z T_2' - 2 T_2 = 5z - 4;  T_1 = p + p# = z + 1;  T_0 = (p - p#)/(z - 1) = 9
    seq = bistritz_sequence(_frac([1, F(-5, 2), 1]))
    assert [t.tolist() for t in seq] == [[2, -5, 2], [1, 1], [9]]
    # T_2(1) = -1, T_1(1) = 2, T_0(1) = 9: nu_n = nu_s = 1 -> inside 1, on 2*1 - 2 = 0
    assert bistritz(_frac([1, F(-5, 2), 1])) == ZeroLocation(1, 0, 1)


def test_sequence_small_cases():
    assert [t.tolist() for t in bistritz_sequence([1.0, -0.5])] == [[0.5, 0.5], [1.5]]
    assert [t.tolist() for t in bistritz_sequence([5])] == [[10]]
    # z = 1 and z = 0 are divided out: (z - 1) z (z - 1/2) -> z - 1/2
    assert [t.tolist() for t in bistritz_sequence(_product([1, -1], [1, 0], [1, -_H]))] == [
        [F(1, 2), F(1, 2)], [F(3, 2)]
    ]


# ---------------------------------------------------------------------------
# 3. textbook verdicts and float specifics
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("coeffs, expected, schur, stable", [
    ([1, -1, 0.5], (2, 0, 0), True, True),                 # zeros 0.5 +- 0.5j
    ([1, 2.5, 1], (1, 0, 1), False, False),                # zeros -0.5, -2
    ([1, -1.2, 0.07, 0.3, -0.08], (4, 0, 0), True, True),  # classic Jury-table example: 0.8, 0.5, 0.4, -0.5
    ([1, -1.3, -0.08, 0.24], (2, 0, 1), False, False),     # zeros 1.2, 0.5, -0.4
    ([1, -0.6, -0.81, 0.67, -0.12], (3, 1, 0), False, True),  # zeros -1, 0.8, 0.5, 0.3
    ([1, -2, 1], (0, 2, 0), False, True),                  # double zero at z = 1
    ([1, 0, 0, 0], (3, 0, 0), True, True),                 # deadbeat
    ([1.0, 0.0, 1.0], (0, 2, 0), False, True),             # +-j, exact in floats too
    ([1.0, -1.0, 1.0], (0, 2, 0), False, True),
    ([1.0, -1.5, 0.5], (1, 1, 0), False, True),            # (z - 1)(z - 0.5)
    ([2.0, -5.0, 2.0], (1, 0, 1), False, False),           # reciprocal pair in floats
])
def test_textbook_verdicts(coeffs, expected, schur, stable):
    z = bistritz(coeffs)
    assert z == ZeroLocation(*expected)
    assert z.schur_stable is schur and z.stable is stable
    moduli = np.abs(np.roots(coeffs))
    assert int(np.sum(moduli < 1 - 1e-6)) == expected[0]


@pytest.mark.parametrize("theta", [0.3, 1.1, 2.9])
def test_rounded_unit_circle_zeros_with_tolerance(theta):
    pair = [complex(math.cos(theta), math.sin(theta)), complex(math.cos(theta), -math.sin(theta))]
    c1 = np.real(np.poly(pair + [0.5, -3.0]))
    c2 = np.real(np.poly(pair * 2 + [0.5, 0.9j, -0.9j, 2.0]))
    assert bistritz(c1, tol=1e-9) == ZeroLocation(1, 2, 1)
    assert bistritz(c2, tol=1e-9) == ZeroLocation(3, 4, 1)


def test_integer_input_is_exact_and_leading_zeros_are_stripped():
    assert bistritz([0, 0, 2, -1]) == ZeroLocation(1, 0, 0)
    assert bistritz(np.array([1, 0, 1])) == ZeroLocation(0, 2, 0)
    assert bistritz_sequence(np.array([1, 0, 1]))[0].dtype == object
    assert bistritz([0.0, 3.0]) == ZeroLocation(0, 0, 0)
    assert bistritz([1.0, 2.0 + 0j]) == ZeroLocation(0, 0, 1)   # zero imaginary part accepted
    assert bistritz([F(1), F(-1, 2)], tol=1e-3) == ZeroLocation(1, 0, 0)  # tol ignored when exact


def test_zero_location_properties():
    z = ZeroLocation(2, 1, 0)
    assert z.stable and not z.schur_stable and z.degree == 3
    assert ZeroLocation(0, 0, 0).schur_stable
    assert not ZeroLocation(1, 0, 1).stable
    with pytest.raises(AttributeError):
        z.inside = 3  # frozen


# ---------------------------------------------------------------------------
# 4. errors
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("coeffs, match", [
    ([], "empty"),
    (np.array([]), "empty"),
    ([0, 0, 0], "zero polynomial"),
    ([0.0], "zero polynomial"),
    ([1.0, float("nan")], "not finite"),
    ([float("inf"), 1.0], "not finite"),
    ([[1, 2], [3, 4]], "1-D"),
    (3.0, "1-D"),
    (["a", 1], "not a real number"),
    ("12", "string"),
    ([1, 1j], "real"),
    ([None, 1], "not a real number"),
])
def test_invalid_coefficients(coeffs, match):
    with pytest.raises(ValueError, match=match):
        bistritz(coeffs)
    with pytest.raises(ValueError, match=match):
        bistritz_sequence(coeffs)


@pytest.mark.parametrize("tol", [-1e-12, float("nan"), float("inf"), "x"])
def test_invalid_tol(tol):
    with pytest.raises(ValueError, match="tol"):
        bistritz([1.0, 0.5], tol=tol)
