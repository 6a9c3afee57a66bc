"""The family's modes continued in the axial load (:mod:`ebb_model.modal.mode_continuation`).

Independent truth: on a pinned–pinned grid the FD beam's modes are sines, ``ψ_j(x) ∝ sin(jπx/L)``, with
``ω̃²_j = (16/h⁴) sin⁴(jπh/2L) + U (4/h²) sin²(jπh/2L)`` per unit ``EI``, ``ρA`` (``M̃ = h I``): closed forms,
evaluated to a few ulps, against which the direct decomposition and the continued modes are both measured.
"""
from __future__ import annotations

import numpy as np
import pytest

import ebb_model as em
from ebb_model.modal.mode_continuation import (PANEL_DEGREE, PANEL_WIDTH, Panel, chebyshev_points, lebesgue_constant,
                                         panel_index)
from ebb_model.modal.mode_family import _direct_modes, continuation_panel, continuation_stem, family_key, unit_modes
from ebb_model.parameter_values import resolve_parameters

from conftest import make_config


def _pinned(nodes: int = 40, N: float = 0.0, **kw):
    return make_config("pinned", "pinned", nodes=nodes, N=N, EI=1.0, rhoA=1.0, c=0.3, dt=5e-4,
                       actuators=[("F1", 0.3)], sensors=[("d", 0.7, "displacement"), ("a", 0.45, "acceleration")],
                       **kw)


def _key(cfg, **values):
    return family_key(cfg, resolve_parameters(cfg, values or None))


def _closed_form(nodes: int, U: float, modes: int) -> tuple[np.ndarray, np.ndarray]:
    """The pinned–pinned FD beam's lowest ``ω̃²`` and mass-normalised shapes on ``nodes`` interior points."""
    h = 1.0 / (nodes + 1)
    j = np.arange(1, modes + 1)
    s = np.sin(j * np.pi * h / 2.0)
    x = h * np.arange(1, nodes + 1)
    psi = np.sin(np.outer(x, j) * np.pi)
    return 16.0 / h ** 4 * s ** 4 + U * 4.0 / h ** 2 * s ** 2, psi / np.sqrt(h * np.sum(psi ** 2, axis=0))


def _errors(w2_f: np.ndarray, psi: np.ndarray, U: float, nodes: int) -> tuple[float, float]:
    """Largest relative ``ω²`` error and shape error (relative to each mode's largest entry) of the finer grid's
    modes against the closed form, signs aligned."""
    w2, shapes = _closed_form(nodes, U, w2_f.size)
    psi = psi * np.sign(np.sum(psi * shapes, axis=0))
    return (float(np.max(np.abs(w2_f / w2 - 1.0))),
            float(np.max(np.abs(psi - shapes) / np.max(np.abs(shapes), axis=0))))


def test_the_interpolation_itself_is_exact_to_round_off():
    # the panel's interpolant built from the closed form (no eigen-solver): what the width and the degree leave,
    # far below the direct solve's round-off (1.7e-10 relative on this grid) that the test below allows
    fine = 81
    for panel in (-1, 0, 3):
        a = panel * PANEL_WIDTH
        nodes, weights = chebyshev_points(a, a + PANEL_WIDTH, PANEL_DEGREE)
        data = [_closed_form(fine, float(U), 40) for U in nodes]
        exact = Panel(nodes, weights, np.array([d[0] for d in data]), np.array([d[0] for d in data]),
                      np.array([d[1] for d in data]))
        for U in np.random.default_rng(panel + 5).uniform(a, a + PANEL_WIDTH, 5):
            w2, _, psi = exact.at(float(U))
            e_w, e_psi = _errors(w2, psi, float(U), fine)
            assert e_w < 1e-13 and e_psi < 1e-13, (panel, U, e_w, e_psi)


@pytest.mark.parametrize("nodes", [40, 70])
def test_continued_modes_are_as_close_to_the_closed_form_as_direct_ones(nodes):
    # the continued modes are the panel points' direct solves combined by the barycentric weights: their error is
    # at most Λ times the points' largest (Λ the Lebesgue constant, 2.42; measured up to 1.11x), and the
    # interpolation's own error is far below (test above)
    cfg = _pinned(nodes)
    lam = lebesgue_constant()
    fine = 2 * nodes + 1
    for U in np.random.default_rng(nodes).uniform(-8.0, 40.0, 8):
        key = _key(cfg, N=float(U))
        stem = continuation_stem(key)
        index = panel_index(float(U))
        panel = continuation_panel((stem, index))
        assert panel is not None, U
        unit = unit_modes(key)
        assert unit.built is None                           # continued, no decomposition of its own
        at_points = np.max([_errors(panel.fine_frequencies2[i], panel.shapes[i], float(V), fine)
                            for i, V in enumerate(panel.nodes)], axis=0)
        direct = _errors(_direct_modes(key)[1], _direct_modes(key)[2], float(U), fine)
        got = _errors(unit.fine_frequencies2, unit.shapes, float(U), fine)
        assert got[0] <= lam * at_points[0] and got[1] <= lam * at_points[1], (U, got, at_points, direct)
        # and of the direct solve's own size at the same U (measured: 0.13–3.4x)
        assert got[0] <= 5.0 * max(direct[0], at_points[0]), (U, got, direct)


def test_near_buckling_and_rigid_body_modes_are_solved_directly():
    # pinned–pinned buckles at U = π² (compression): the panel [-16, -8] holds it; a free–free beam's rigid-body
    # modes are round-off; both are refused, and their members equal the direct route's to the last bit
    for cfg, N in ((_pinned(40), -12.0), (make_config("free", "free", nodes=40, N=3.0), 3.0)):
        key = _key(cfg, N=N)
        stem = continuation_stem(key)
        assert stem is not None
        assert continuation_panel((stem, panel_index(key.N * key.length ** 2))) is None
        unit = unit_modes(key)
        w2, w2_f, psi = _direct_modes(key)
        assert unit.built is not None
        assert np.array_equal(unit.frequencies2, w2) and np.array_equal(unit.shapes, psi)


def test_attachments_and_an_unloaded_beam_keep_their_own_decomposition():
    # point masses, springs, weak segments, rotary inertia and elastic ends change K̃ or M̃ beyond U and k_f:
    # not continued; N = 0 is a panel point, solved as before (bitwise)
    assert continuation_stem(_key(_pinned(30, N=5.0, masses=[("m", 0.4, 0.1)]))) is None
    assert continuation_stem(_key(_pinned(30, N=5.0, springs=[("s", 0.4, 100.0)]))) is None
    assert continuation_stem(_key(make_config("elastic", "pinned", N=5.0, left_springs=(1e4, 50.0)))) is None
    key = _key(_pinned(30))
    assert unit_modes(key).built is not None
    assert np.array_equal(unit_modes(key).shapes, _direct_modes(key)[2])


def test_a_foundation_shifts_every_frequency_and_moves_no_shape():
    # K̃ + κ M̃ with M̃ = diag(V): ω̃² + κ exactly, the same shapes; against the direct decomposition with the
    # foundation assembled, to the unloaded family's round-off: eps times its ω² ratio (2.3e-10 here) relative to
    # ω̃².  A shift leaves the errors of both decompositions where they are in absolute terms (the top modes' ~3e-3,
    # the Richardson pair's own, at every κ), so they are measured against ω̃², not ω̃² + κ: against ω̃² + κ with the
    # shifted ratio (5.6e3 at κ = 3e4) the top modes left 1.5e-11 for a bound of 1.0e-11 on one machine's LAPACK.
    # Measured here: 0.37, 0.06 and 0.85 of the bound at κ = 0, 50, 3e4.
    cfg = _pinned(40, N=7.0)
    p = resolve_parameters(cfg)
    stem_unit = unit_modes(family_key(cfg, p))
    w20 = _direct_modes(family_key(cfg, p))[0]
    bound = np.finfo(float).eps * w20.max() / w20.min()
    for kf in (0.0, 50.0, 3e4):
        unit = unit_modes(family_key(cfg, p | {"kf": kf}))
        assert np.array_equal(unit.frequencies2, stem_unit.frequencies2 + kf)
        assert np.array_equal(unit.shapes, stem_unit.shapes)
        w2, _, psi = _direct_modes(family_key(cfg, p | {"kf": kf}))
        assert np.max(np.abs(unit.frequencies2 - w2) / (w2 - kf)) <= 8.0 * bound


def test_difference_jacobians_see_the_physics_not_the_eigen_solver():
    # an N moved by δ of itself moves the outputs by δ times their sensitivity: doubling δ doubles the change.
    # At a difference Jacobian's step (δ = 1e-8) the direct decompositions' round-off made that 10–30 % wrong on
    # this bench (measured: |Δ₂ − 2Δ₁|/|Δ₂| = 0.096 displacement, 0.29 acceleration); continued, 4.5e-6 and 1.8e-5
    # (the rest of the model's rounding and the curvature, δ²)
    cfg = make_config("clamped", "pinned", nodes=60, N=23.0, c=0.8, dt=5e-4,
                      sensors=[("d", 0.7, "displacement"), ("a", 0.45, "acceleration")])
    u = np.random.default_rng(1).standard_normal((3000, 1))

    def outputs(N: float) -> np.ndarray:
        return em.simulate(em.fast_model(cfg, {"N": N}), u).outputs

    y = outputs(23.0)
    one, two = outputs(23.0 * (1 + 1e-8)) - y, outputs(23.0 * (1 + 2e-8)) - y
    assert np.all(np.linalg.norm(two - 2.0 * one, axis=0) <= 1e-3 * np.linalg.norm(two, axis=0))


def test_a_panel_is_a_pure_function_of_its_stem_and_index():
    # built again from nothing, the same numbers; a member's modes do not depend on which members came before
    cfg = _pinned(30, N=11.0)
    key = _key(cfg)
    where = (continuation_stem(key), panel_index(key.N * key.length ** 2))
    first = continuation_panel(where)
    continuation_panel.cache_clear()
    unit_modes.cache_clear()
    again = continuation_panel(where)
    assert again is not first and np.array_equal(again.shapes, first.shapes)


def test_a_model_reads_a_continued_members_shapes_only_where_its_loads_and_sensors_are():
    # the model combines the panel's shapes on the rows of its loads and sensors; the whole shapes are formed
    # only when something asks (here: never, for a decoupled model) — and a row's numbers do not depend on
    # whether they were
    cfg = _pinned(40, N=13.0)
    p = resolve_parameters(cfg)
    unit_modes.cache_clear()
    em.fast_model(cfg, p)
    unit = unit_modes(family_key(cfg, p))
    assert unit.built is None and "shapes" not in vars(unit)
    J = np.array([3, 4, 20, 31])
    before = unit.shape_rows(J)
    whole = unit.shapes
    assert np.array_equal(unit.shape_rows(J), before)
    # the rows and the whole are two roundings of one combination: budget a few ulps of each mode's largest
    # entry (measured: 1 ulp)
    scale = np.max(np.abs(whole), axis=0)
    assert np.max(np.abs(whole[J] - before) / scale) <= 4 * np.finfo(float).eps
