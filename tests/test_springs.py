"""Springs to ground anywhere along the beam (``[[springs]]``; issue 31: an intermediate support).

Oracle: a pinned–pinned beam with a spring ``k`` at mid-span.  Its antisymmetric modes do not move the spring
(``Ω = (2nπ)²``); its symmetric modes are, on the half beam ``w = A sin βx + B sinh βx`` with ``w'(L/2) = 0``
and the shear jump ``2 EI w'''(L/2⁻) = k w(L/2)``, the roots of

.. math::  -4 EI β³ \\cos(βL/2) = k\\,\\big(\\sin(βL/2) - \\cos(βL/2)\\tanh(βL/2)\\big),

``ω = β² √(EI/ρA)`` (k = 0: ``β = π/L``; k → ∞: ``tan = tanh``, the half beam clamped–pinned).  The model
(Richardson over two FD grids) converges to it as ``h⁴``; the generator's Hermite FE truth too (its own
refinement shown).  The FMUs carry the springs: ``tests/fmu_hosts/fmu_configs.mixed_config`` has one, so every
FMU test (pythonfmu, the C FMU, fmpy, libcosim, ecos, the plain C host) simulates it.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from ebb_model import assemble, config_from_dict, simulate
from ebb_model.errors import ConfigError, ParameterError
from ebb_model.modal.modal import discrete_frequencies
from ebb_model.reference.hermite_fe import hermite_beam

from conftest import make_config

EI, RHOA, L, K = 10.0, 1.0, 1.0, 2000.0


def _midspan_spring_frequencies(n: int) -> np.ndarray:
    """The lowest ``n`` natural frequencies [Hz] of the pinned–pinned beam with ``K`` at mid-span (module
    docstring), roots bracketed on a fine grid of β and polished by Brent's method to 1e-14."""
    a = L / 2

    def g(b: float) -> float:
        c = math.cos(b * a)
        return -4.0 * EI * b ** 3 * c - K * (math.sin(b * a) - c * math.tanh(b * a))

    grid = np.linspace(0.5, 45.0, 90_000)
    v = np.array([g(b) for b in grid])
    symmetric = [brentq(g, grid[i], grid[i + 1], xtol=1e-14) for i in np.flatnonzero(v[:-1] * v[1:] < 0)]
    antisymmetric = [2 * m * math.pi / L for m in range(1, n + 1)]
    beta = np.sort(np.array(symmetric + antisymmetric))[:n]
    return beta ** 2 * math.sqrt(EI / RHOA) / (2 * math.pi)


def test_midspan_spring_against_the_analytic_frequencies():
    exact = _midspan_spring_frequencies(5)
    assert exact[0] / (math.pi ** 2 * math.sqrt(EI / RHOA) / (2 * math.pi * L ** 2)) > 1.05   # the spring matters
    errors = []
    for nodes in (49, 99):
        f, _ = discrete_frequencies(make_config("pinned", "pinned", nodes=nodes, springs=[("s", 0.5, K)]), None, 5)
        errors.append(np.abs(f / exact - 1.0))
    # Richardson over two grids: O(h⁴) — measured 1.1e-7 … 1.5e-5 at 49 nodes, 16.0× less at 99
    assert np.all(errors[1] < 1e-6)
    np.testing.assert_allclose(errors[0] / errors[1], 16.0, rtol=0.05)
    # the generator's truth, converged: 40 → 80 Hermite elements change mode 5 by 1.5e-5, and the 80-element
    # model is 1e-6 from the closed form
    fe = [hermite_beam(L, ne, EI=EI, rhoA=RHOA, left=(math.inf, 0.0), right=(math.inf, 0.0),
                       point_springs=[(K, 0.5)]).natural_frequencies_hz(5) for ne in (40, 80)]
    assert np.all(np.abs(fe[1] / exact - 1.0) < 2e-6)
    assert np.all(np.abs(fe[1] / fe[0] - 1.0) < 2e-5)


def test_a_spring_at_a_node_of_a_mode_does_not_move_it():
    """Mode 2 of the pinned–pinned beam has its node at mid-span: the spring leaves it where it was."""
    plain, _ = discrete_frequencies(make_config("pinned", "pinned", nodes=49), None, 3)
    sprung, _ = discrete_frequencies(make_config("pinned", "pinned", nodes=49, springs=[("s", 0.5, K)]), None, 3)
    assert sprung[1] == pytest.approx(plain[1], rel=1e-10)     # the eigen-solvers' round-off: measured 2e-12
    assert sprung[0] > 1.05 * plain[0]


def test_springs_in_the_config_round_trip_and_add_to_the_stiffness():
    cfg = make_config("clamped", "free", nodes=20, springs=[("support", 0.6, 500.0), ("stinger", 0.9, 80.0)])
    again = config_from_dict(cfg.to_dict())
    assert again.springs == cfg.springs and [s.name for s in again.springs] == ["support", "stinger"]
    u = np.random.default_rng(1).standard_normal((400, 1))
    y = simulate(assemble(cfg), u).outputs
    plain = simulate(assemble(make_config("clamped", "free", nodes=20)), u).outputs
    assert np.max(np.abs(y - plain)) > 0.05 * np.max(np.abs(plain))


@pytest.mark.parametrize("springs,field", [
    ([{"name": "k", "x": 0.5, "k": -1.0}], "springs[0].k"),
    ([{"name": "k", "x": 0.5}], "springs[0].k"),
    ([{"name": "k", "x": 1.5, "k": 10.0}], "springs[0].x"),
    ([{"name": "k", "x": 0.5, "k": float("nan")}], "springs[0].k"),
    ([{"name": "F1", "x": 0.5, "k": 10.0}], "names"),
    ([{"name": "k", "x": 0.5, "k": 10.0, "c": 1.0}], "springs[0].c"),
    ({"name": "k"}, "springs"),
])
def test_bad_springs_name_the_field(springs, field):
    d = make_config().to_dict()
    d["springs"] = springs
    with pytest.raises(ConfigError) as ei:
        config_from_dict(d)
    assert field in str(ei.value)


def test_a_spring_too_stiff_for_the_matrices_is_refused():
    cfg = make_config(nodes=20, springs=[("k", 0.5, 1e30)])
    with pytest.raises(ParameterError, match=r"springs\.k: 1e\+30 N/m is more than 1e\+12 times"):
        assemble(cfg)
