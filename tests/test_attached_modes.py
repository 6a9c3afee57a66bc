"""A beam with one point mass or one spring: modes by a rank-one update of the continued bases without it
(:mod:`ebb_model.modal.attached_modes`), against 40-digit eigenpairs of the same matrices and against the direct
route."""
from __future__ import annotations

from dataclasses import replace

import mpmath
import numpy as np
import pytest

from ebb_model.modal.attached_modes import CHECK_BASIS_SHAPES
from ebb_model.beam import PointMass, PointSpring
from ebb_model.modal.mode_continuation import CHECK_FREQUENCIES, panel_index
from ebb_model.modal.mode_family import (_direct_modes, _unit_beam, attached_panel, attachment, continuation_panel,
                                   family_key, unit_modes)
from ebb_model.space.richardson_pair import companion_nodes

from conftest import make_config

EPS = np.finfo(float).eps


def _key(ends, nodes, kind, x, size, U, kf=0.0, second=None):
    """The family of a unit beam with ``kind`` (``"spring"``, ``"mass"``) of ``size`` at ``x`` (of the length), and
    the ``second`` ``(kind, x, size)`` too when given."""
    cfg = make_config(*ends, nodes=nodes, dt=5e-4, EI=1.0, rhoA=1.0, actuators=[("F1", 0.55)],
                      sensors=[("a1", 0.35, "acceleration")])
    base = family_key(cfg, dict(cfg.parameter_values()))
    key = replace(base, N=U / base.length ** 2, kf=kf)
    for kind_, x_, size_ in [(kind, x, size)] + ([second] if second else []):
        x_ *= base.length
        key = replace(key, springs=key.springs + (PointSpring("", x_, size_),)) if kind_ == "spring" else \
            replace(key, masses=key.masses + (PointMass("", x_, size_),))
    return key


def _forty_digits(key, count):
    """The finer grid's ``count`` lowest ``ω²`` and mass-normalised shapes of ``key``'s unit beam, in 40 digits."""
    beam = _unit_beam(key, max(key.nodes, companion_nodes(key.nodes)))
    mpmath.mp.dps = 40
    Li = mpmath.inverse(mpmath.cholesky(mpmath.matrix(beam.M.tolist())))
    S = Li * mpmath.matrix(beam.K.tolist()) * Li.T
    E, Q = mpmath.eigsy((S + S.T) / 2)
    order = sorted(range(beam.n_unknowns), key=lambda i: E[i])[:count]
    V = Li.T * Q
    return (np.array([float(E[i]) for i in order]),
            np.array([[float(V[r, i]) for i in order] for r in range(beam.n_unknowns)]))


def _errors(w2, psi, w2_ref, psi_ref, scale):
    """``ω²`` and shape differences (each mode's relative to its largest entry, signs aligned) in units of
    ``scale``."""
    sign = np.sign(np.sum(psi * psi_ref, axis=0))
    return (float(np.max(np.abs(w2 / w2_ref - 1.0))) / scale,
            float(np.max(np.abs(psi * sign - psi_ref) / np.max(np.abs(psi_ref), axis=0))) / scale)


@pytest.mark.parametrize("ends,nodes,kind,x,size,U,second", [
    (("clamped", "pinned"), 12, "spring", 0.37, 40.0, 5.0, None),
    (("clamped", "pinned"), 12, "mass", 0.62, 0.05, 3.0, None),
    (("clamped", "free"), 14, "spring", 0.8, 3.0, 0.0, None),
    (("pinned", "pinned"), 15, "mass", 0.3, 0.2, 10.0, None),
    (("clamped", "pinned"), 13, "mass", 0.45, 0.08, 6.0, ("spring", 0.7, 25.0))])
def test_the_update_against_forty_digit_eigenpairs(ends, nodes, kind, x, size, U, second):
    """Independent truth: the same finite-difference matrices (the finer grid's, with the attachment) solved in
    40-digit arithmetic.  The updated modes are within the panel's acceptance of a direct solve
    (``CHECK_FREQUENCIES = 8`` times ``eps·ω²_max/ω²_min``) of it, shapes likewise — measured at most 1.7 (``ω²``)
    and 1.6 (shapes), with a mass and a spring 0.08 and 0.53; the direct decomposition: 0.23 and 1.5."""
    key = _key(ends, nodes, kind, x, size, U, second=second)
    assert attachment(key) is not None
    unit = unit_modes(key)
    assert unit.built is None                         # updated, not decomposed
    w2_ref, psi_ref = _forty_digits(key, unit.fine_frequencies2.size)
    scale = EPS * float(w2_ref.max() / w2_ref.min())
    got = _errors(unit.fine_frequencies2, unit.shapes, w2_ref, psi_ref, scale)
    assert got[0] <= CHECK_FREQUENCIES and got[1] <= CHECK_FREQUENCIES, got


@pytest.mark.parametrize("ends,nodes", [(("clamped", "pinned"), 60), (("clamped", "free"), 40),
                                        (("pinned", "pinned"), 33), (("clamped", "clamped"), 120)])
def test_the_update_is_the_direct_decomposition_to_its_round_off(ends, nodes):
    """Springs of 0.1–1000 and masses of 0.001–0.3 (per unit ``EI``, ``ρA``) anywhere, one or two, ``U`` of 0 or
    −3…40, with or without a foundation: the Richardson and the finer grid's ``ω²`` within ``CHECK_FREQUENCIES``
    of the direct route's round-off scale ``eps·ω²_max/ω²_min`` (measured at most 2.5; two attachments 2.1), the
    shapes within the panel's acceptance ``CHECK_BASIS_SHAPES`` (measured at most 155, on the 120-node grid's three
    highest modes, which no route resolves better; its lowest 20 agree to 1e-11; two attachments 97)."""
    rng = np.random.default_rng(nodes)

    def attached(kind):
        size = 10 ** rng.uniform(-1, 3) if kind == "spring" else 10 ** rng.uniform(-3, -0.5)
        return kind, float(rng.uniform(0.02, 1.0)), size

    for trial in range(9):
        kind, x, size = attached(("spring", "mass")[trial % 2])
        second = attached(("spring", "mass")[(trial // 2) % 2]) if trial >= 6 else None
        U = float(rng.choice([0.0, rng.uniform(-3, 40)]))
        key = _key(ends, nodes, kind, x, size, U, kf=float(rng.choice([0.0, rng.uniform(0, 50)])), second=second)
        unit = unit_modes(key)
        assert unit.built is None
        w2, w2_f, psi = _direct_modes(key)
        scale = EPS * float(w2_f.max() / w2_f.min())
        assert float(np.max(np.abs(unit.frequencies2 / w2 - 1.0))) / scale <= CHECK_FREQUENCIES
        errors = _errors(unit.fine_frequencies2, unit.shapes, w2_f, psi, scale)
        assert errors[0] <= CHECK_FREQUENCIES and errors[1] <= CHECK_BASIS_SHAPES, (kind, size, U, errors)


def test_what_is_not_updated_is_decomposed_as_before():
    """Three attachments, an attachment of size zero, and a grid whose panel the rule for the lowest modes refuses
    (a 150-node cantilever: its finer grid's lowest ``ω²`` is below 1e-8 of its largest) take the direct route,
    bit for bit."""
    two = _key(("clamped", "pinned"), 30, "spring", 0.4, 10.0, 2.0, second=("mass", 0.5, 0.01))
    two = replace(two, springs=two.springs + (PointSpring("", 0.2, 5.0),))
    zero = _key(("clamped", "pinned"), 30, "mass", 0.4, 0.0, 2.0)
    refused = _key(("clamped", "free"), 150, "spring", 0.4, 10.0, 2.0)
    assert attachment(two) is None and attachment(zero) is None
    stem = attachment(refused)[0]
    assert attached_panel((stem, panel_index(2.0))) is None
    for key in (two, zero, refused):
        unit = unit_modes(key)
        w2, w2_f, psi = _direct_modes(key)
        assert np.array_equal(unit.frequencies2, w2) and np.array_equal(unit.shapes, psi)


def test_a_member_is_a_pure_function_of_its_key():
    """Which panels were built before does not change a member's modes (the memos cleared between)."""
    a = _key(("clamped", "pinned"), 40, "spring", 0.3, 50.0, 6.0)
    b = _key(("clamped", "pinned"), 40, "mass", 0.7, 0.02, 3.0)
    first = [unit_modes(k).shapes.copy() for k in (a, b)]
    for memo in (unit_modes, attached_panel, continuation_panel):
        memo.cache_clear()
    second = [unit_modes(k).shapes.copy() for k in (b, a)][::-1]
    assert all(np.array_equal(x, y) for x, y in zip(first, second))
