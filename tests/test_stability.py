"""Stability: dispersion relation + Bistritz versus growth factors, explicit limit, bounds, finite beam."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ebb_model import StabilityError, analyse_stability, assemble, bistritz, fast_model
from ebb_model.stability import dispersion_coefficients, growth_factors, stability_bounds, wavenumbers

from conftest import make_config


def test_growth_factor_at_most_one_exactly_when_bistritz_says_stable():
    """Random parameter sets, including unstable ones (explicit θ, negative damping, compression)."""
    rng = np.random.default_rng(11)
    kap = wavenumbers(1.0, 30, 65)
    h = 1.0 / 31
    agree = 0
    n_unstable = 0
    for _ in range(400):
        p = {"EI": 10 ** rng.uniform(-1, 3), "rhoA": 10 ** rng.uniform(-1, 1),
             "c": rng.uniform(-0.5, 2.0), "eta": rng.choice([0.0, 10 ** rng.uniform(-7, -3)]),
             "N": rng.uniform(-300, 300)}
        theta = rng.choice([0.0, 0.1, 0.2, 0.25, 0.5])
        tau = 10 ** rng.uniform(-6, -3)
        co = dispersion_coefficients(p, h=h, tau=tau, theta=theta, kappa=kap)
        g = growth_factors(co)
        for row, gi in zip(co, g):
            zl = bistritz(row)
            stable = zl.outside == 0
            n_unstable += not stable
            # the two verdicts must agree, up to round-off for zeros on the circle
            if stable:
                assert gi <= 1 + 1e-9, (p, theta, tau, row, gi, zl)
            else:
                assert gi > 1 - 1e-12, (p, theta, tau, row, gi, zl)
            agree += 1
    assert n_unstable > 1000  # the sample really exercises both verdicts
    assert agree == 400 * kap.size


@pytest.mark.parametrize("theta", [0.0, 0.1, 0.2])
def test_explicit_time_step_limit(theta):
    """θ < 1/4: stable iff τ ≤ 2 / (ω_max √(1 − 4θ)) with ω_max² = (16 EI/h⁴ + 4N/h²)/ρA."""
    EI, rhoA, N, nodes = 10.0, 1.0, 30.0, 40
    h = 1.0 / (nodes + 1)
    w_max = math.sqrt((16 * EI / h ** 4 + 4 * N / h ** 2) / rhoA)
    tau_lim = 2 / (w_max * math.sqrt(1 - 4 * theta))
    for factor, expect in ((0.999, True), (1.001, False)):
        cfg = make_config(nodes=nodes, EI=EI, rhoA=rhoA, N=N, theta=theta, dt=factor * tau_lim)
        rep = analyse_stability(cfg)
        assert rep.grid_stable is expect
        assert rep.dt_max == pytest.approx(tau_lim, rel=1e-12)
        assert (rep.max_growth_factor <= 1 + 1e-12) is expect


def test_theta_quarter_undamped_is_marginal_and_unconditionally_stable():
    cfg = make_config(dt=1e-2, nodes=60)
    rep = analyse_stability(cfg)
    assert rep.grid_stable and rep.beam_stable and rep.marginal
    assert rep.max_growth_factor == pytest.approx(1.0, abs=1e-12)
    assert rep.dt_max == math.inf


def test_damping_makes_it_strictly_stable():
    rep = analyse_stability(make_config(c=0.5, eta=1e-5))
    assert rep.grid_stable and not rep.marginal
    assert rep.max_growth_factor < 1


def test_bounds_are_sharp():
    """Just inside each finite bound the grid is stable, just outside it is not."""
    cfg = make_config(theta=0.0, dt=2e-5, nodes=30, N=20.0)
    b = stability_bounds(cfg)
    for name in ("EI", "rhoA", "N"):
        lo, hi = b[name]
        for edge, step in ((lo, -1), (hi, +1)):
            if not math.isfinite(edge) or edge == 0.0:
                continue
            inside = analyse_stability(cfg, {name: edge * (1 - step * 1e-6 * np.sign(edge))})
            outside = analyse_stability(cfg, {name: edge * (1 + step * 1e-6 * np.sign(edge))})
            assert inside.grid_stable, (name, edge)
            assert not outside.grid_stable, (name, edge)


def test_grid_and_finite_beam_disagree_under_compression_and_it_is_reported():
    """Clamped–clamped at half its buckling load (U = −2π²): the unbounded grid (Euler load π²) says
    unstable, the finite beam is stable; a cantilever beyond π²/4 buckles although the grid says stable."""
    cc = make_config("clamped", "clamped", N=-2 * math.pi ** 2 * 10.0)
    rep = analyse_stability(cc)
    assert rep.beam_stable and not rep.grid_stable and not rep.agree
    assert any("finite beam is stable" in m for m in rep.messages)
    assemble(cc)  # the finite beam is fine: no error

    cf = make_config("clamped", "free", N=-0.5 * math.pi ** 2 * 10.0, c=0.1)
    rep = analyse_stability(cf)
    assert rep.grid_stable and not rep.beam_stable
    assert any("finite beam is not" in m for m in rep.messages)
    with pytest.raises(StabilityError, match="N = "):
        assemble(cf)


def test_spectral_radius_matches_dense_phi():
    cfg = make_config(N=40.0, eta=1e-4, c=0.2, nodes=20, substeps=2)
    assert fast_model(cfg).spectral_radius() == pytest.approx(assemble(cfg).spectral_radius(), rel=1e-12)


def test_unstable_explicit_scheme_is_refused_naming_parameters():
    h = 1 / 31
    w_max = math.sqrt(16 * 10.0 / h ** 4)
    cfg = make_config(theta=0.0, nodes=30, dt=1.2 * 2 / w_max, scheme="theta")  # the seed's explicit scheme
    with pytest.raises(StabilityError, match="EI = 10 lies outside the Bistritz bounds"):
        assemble(cfg)
