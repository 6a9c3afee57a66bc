"""Accuracy of the finite-difference beam against independent truths.

* analytic frequencies of the axially loaded beam (closed form / characteristic
  equations in :mod:`ebb_model.reference.analytic`), four boundary-condition
  pairs, U = N L²/EI ∈ {−0.5 U_cr, 0, 10, 100};
* the observed convergence order under grid refinement (50 → 100 → 200);
* a second, independent discretisation (cubic Hermite finite elements) where no
  closed form exists: elastic ends and point masses.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ebb_model import modes
from ebb_model.reference import analytic_omegas, critical_buckling_U, hermite_beam

from conftest import make_config

PAIRS = [("pinned", "pinned"), ("clamped", "clamped"), ("clamped", "pinned"), ("clamped", "free")]
EI, RHOA, L = 10.0, 1.0, 1.0


def fd_omegas(left: str, right: str, U: float, nodes: int, n_modes: int = 5, **kw) -> np.ndarray:
    cfg = make_config(left, right, nodes=nodes, EI=EI, rhoA=RHOA, N=U * EI / L ** 2, length=L, **kw)
    f = modes(cfg, n_modes=n_modes).frequencies_hz
    return 2 * np.pi * f * L ** 2 * math.sqrt(RHOA / EI)


def u_values(left: str, right: str) -> list[float]:
    return [-0.5 * critical_buckling_U(left, right), 0.0, 10.0, 100.0]


CASES = [(l, r, U) for l, r in PAIRS for U in u_values(l, r)]


@pytest.mark.parametrize("left,right,U", CASES, ids=[f"{l}-{r}-U{U:.3g}" for l, r, U in CASES])
def test_modes_1_to_5_within_half_percent_at_100_nodes(left, right, U):
    exact = analytic_omegas(left, right, U, 5)
    fd = fd_omegas(left, right, U, 100)
    rel = np.abs(fd / exact - 1)
    assert np.all(rel < 5e-3), f"relative errors {rel}"


@pytest.mark.parametrize("left,right,U", CASES, ids=[f"{l}-{r}-U{U:.3g}" for l, r, U in CASES])
def test_observed_convergence_order_is_two(left, right, U):
    exact = analytic_omegas(left, right, U, 5)
    errs = [np.abs(fd_omegas(left, right, U, n) - exact) for n in (50, 100, 200)]
    # h halves from 1/51 -> 1/101 -> 1/201: order = log(e1/e2)/log(h1/h2)
    h = [1 / 51, 1 / 101, 1 / 201]
    for (e1, h1), (e2, h2) in zip(zip(errs, h), zip(errs[1:], h[1:])):
        order = np.log(e1 / e2) / np.log(h1 / h2)
        assert np.all((order > 1.85) & (order < 2.3)), f"observed orders {order}"


def test_pinned_pinned_fd_modes_are_exact_sines():
    """For pinned ends the FD eigenvectors are sampled sines: an exact property of the stencil."""
    cfg = make_config("pinned", "pinned", nodes=40)
    m = modes(cfg, n_modes=4)
    x = m.x
    for n, shape in enumerate(m.shapes, start=1):
        s = np.sin(n * np.pi * x / L)
        s = s / s[np.argmax(np.abs(s))]
        assert np.allclose(shape, s * np.sign(shape @ s), atol=1e-9)


ELASTIC_CASES = [
    # (left kind, left springs, right kind, right springs, masses)
    ("elastic", (2.0e3, 50.0), "free", None, []),
    ("elastic", (math.inf, 20.0), "elastic", (500.0, math.inf), []),
    ("clamped", None, "pinned", None, [("m1", 0.37, 0.2), ("m2", 0.81, 0.05)]),
    ("elastic", (1.0e4, 1.0e2), "elastic", (3.0e3, 5.0), [("tip", 0.95, 0.1)]),
]


def _fe_end(kind: str, springs):
    return {"clamped": (math.inf, math.inf), "pinned": (math.inf, 0.0), "free": (0.0, 0.0)}.get(kind, springs)


@pytest.mark.parametrize("N", [0.0, 40.0])
@pytest.mark.parametrize("case", ELASTIC_CASES, ids=["elastic-free", "rot-spring-trans-spring",
                                                     "masses", "all-elastic-mass"])
def test_against_hermite_finite_elements(case, N):
    """Elastic ends and point masses: no closed form, so compare with a converged Hermite FE model."""
    lk, ls, rk, rs, masses = case
    fe = hermite_beam(L, 400, EI=EI, rhoA=RHOA, N=N, left=_fe_end(lk, ls), right=_fe_end(rk, rs),
                      point_masses=[(m, x) for _, x, m in masses])
    f_fe = fe.natural_frequencies_hz(5)
    errs = []
    for nodes in (100, 200):
        cfg = make_config(lk, rk, nodes=nodes, EI=EI, rhoA=RHOA, N=N, left_springs=ls, right_springs=rs,
                          masses=masses)
        f_fd = modes(cfg, n_modes=5).frequencies_hz
        errs.append(np.abs(f_fd / f_fe - 1))
    assert np.all(errs[0] < 5e-3), f"relative errors at 100 nodes {errs[0]}"
    # and the FD model converges to it (roughly) at second order
    ratio = errs[0] / np.maximum(errs[1], 1e-12)
    assert np.all(ratio > 2.5), f"error ratios under refinement {ratio}"
