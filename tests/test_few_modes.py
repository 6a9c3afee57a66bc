"""The few lowest ``ω²`` by Lanczos on the inverted banded pencil (:mod:`ebb_model.space.few_modes`) against the same
matrices' eigenvalues in 32-digit arithmetic (mpmath: Cholesky of ``K``, ``L⁻¹ M L⁻ᵀ``, its symmetric
eigenproblem) — the truth for the matrices themselves, so every error measured is the solver's."""
from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
import scipy.linalg as sla

from conftest import make_config
from ebb_model.space.few_modes import MAX_BANDWIDTH, _bandwidth, _cholesky, inverse_eigenvalues
from ebb_model.modal.mode_family import family_key, unit_pair
from ebb_model.space.richardson_pair import lowest_modes
from ebb_model.parameter_values import resolve_parameters


def _unit_beams(ends, nodes=20, **kw):
    cfg = make_config(*ends, nodes=nodes, dt=1e-4, **kw)
    return unit_pair(family_key(cfg, resolve_parameters(cfg, cfg.parameter_values())))


def _digits32(K: np.ndarray, M: np.ndarray, m: int) -> np.ndarray:
    """The ``m`` lowest ``ω²`` of the float matrices, computed with 32 digits."""
    with mp.workdps(32):
        L = mp.cholesky(mp.matrix(K.tolist()))
        Li = L ** -1
        mu = mp.eigsy(Li * mp.matrix(M.tolist()) * Li.T, eigvals_only=True)
        return np.array(sorted(float(1 / v) for v in mu)[:m])


CASES = {"cantilever": (("clamped", "free"), {}),
         "compressed, a mass and a spring": (("clamped", "pinned"), {"N": -5.0, "masses": [("m", 0.3, 0.1)],
                                                                    "springs": [("k", 0.6, 400.0)]}),
         "under tension": (("pinned", "pinned"), {"N": 30.0})}


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_lowest_modes_to_the_matrices_own_eigenvalues(name):
    """What is left is the Cholesky factor's rounding, of the dense solver's order; the iteration adds nothing.

    Budgets, measured on these grids (20–42 unknowns): against 32 digits at most 7.1e-12 relative (mode 1 of the
    cantilever; LAPACK's dense solver on the inverted pencil: 3.5e-11 there, 1.0e-12 where Lanczos' factor gives
    5.2e-12 — the same algorithm's rounding in another order), asserted 3e-11; against the dense eigenvalues of
    ``C`` formed from its own factor at most 4e-15, asserted 1e-13 (an accepted Ritz value is off by at most
    ``r²/gap ≤ ε θ``)."""
    ends, kw = CASES[name]
    for beam in _unit_beams(ends, **kw):
        m = 4
        truth = _digits32(beam.K, beam.M, m)
        mu = inverse_eigenvalues(beam.K, beam.M, m)
        assert mu is not None
        got = 1.0 / mu[::-1]
        err = np.abs(got - truth) / truth
        assert np.all(err <= 3e-11), (name, beam.n_unknowns, err)
        L = _own_factor(beam.K)
        Li = sla.solve_triangular(L, np.eye(L.shape[0]), lower=True)
        C = Li @ beam.M @ Li.T
        own = np.linalg.eigvalsh(0.5 * (C + C.T))[-m:]
        np.testing.assert_allclose(mu, own, rtol=1e-13)
        # the modes' path takes them (a quarter of the unknowns at most), the same numbers
        assert np.array_equal(lowest_modes(beam, m, vectors=False), 1.0 / mu[::-1])


def _own_factor(K: np.ndarray) -> np.ndarray:
    """The banded Cholesky factor the iteration uses, as a dense lower-triangular matrix."""
    kd = _bandwidth(K, K)
    band, ok = _cholesky(np.ascontiguousarray(K), kd)
    assert ok
    n = K.shape[0]
    L = np.zeros((n, n))
    for d in range(kd + 1):
        L[np.arange(d, n), np.arange(0, n - d)] = band[d:, d]
    return L


def test_what_lanczos_leaves_to_the_dense_solver():
    """A wide band, more modes than a quarter of the unknowns: ``None``.  Free ends (``K`` singular; its Cholesky
    need not fail, rounding leaves tiny pivots): the modes' path sees the huge ``μ`` of the rigid-body modes and
    solves the direct problem, as it does after LAPACK's solver."""
    free = _unit_beams(("free", "free"))[0]
    direct = sla.eigh(free.K, free.M, eigvals_only=True, subset_by_index=(0, 2))
    assert np.array_equal(lowest_modes(free, 3, vectors=False), direct)
    beam = _unit_beams(("clamped", "pinned"))[0]
    n = beam.n_unknowns
    assert inverse_eigenvalues(beam.K, beam.M, n // 4 + 1) is None
    wide = beam.M.copy()
    wide[0, MAX_BANDWIDTH + 1] = wide[MAX_BANDWIDTH + 1, 0] = 1e-9 * wide[0, 0]
    assert inverse_eigenvalues(beam.K, wide, 3) is None
    assert inverse_eigenvalues(beam.K, beam.M, 3) is not None
