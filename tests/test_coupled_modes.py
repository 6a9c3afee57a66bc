"""Modes coupled by point masses on a viscously damped beam (:mod:`ebb_model.modal.coupled_modes`) against the dense
eigenproblem of the same modal system and against the Van Loan matrix exponential (no eigenvectors at all)."""
from __future__ import annotations

import numpy as np
import pytest

import ebb_model as em
import ebb_model.modal.coupled_modes as cmod
from conftest import make_config
from ebb_model.exact.exact_modal import continuous_modes, exact_modal, exact_statespace, modal_matrices, \
    modal_state_matrix
from ebb_model.theta.modal_form import basis_condition
from ebb_model.modal.modal_poles import modal_poles
from ebb_model.reference.excitation import band_limited_input


def beam(masses: list[tuple[float, float]], *, eta: float = 0.0, rhoI: float = 0.0, c: float = 3.0,
         nodes: int = 40, N: float = 20.0, springs: list[tuple[float, float]] | None = None,
         left: str = "clamped", left_springs: tuple[float, float] | None = None) -> em.BeamConfig:
    """A clamped–pinned beam under tension with viscous damping (ζ 0.3–3 % over its first modes) and point
    masses ``(x, mass)`` — one on a node and others between nodes, so each spreads over one or two unknowns."""
    cfg = make_config(left, "pinned", nodes=nodes, dt=5e-4, c=c, eta=eta, N=N, actuators=[("F1", 0.55)],
                      sensors=[("a1", 0.35, "acceleration"), ("v1", 0.62, "velocity"), ("d1", 0.8, "displacement")],
                      masses=[(f"m{i}", x, m) for i, (x, m) in enumerate(masses)],
                      springs=[(f"k{i}", x, k) for i, (x, k) in enumerate(springs or [])], left_springs=left_springs)
    if rhoI == 0.0:
        return cfg
    d = cfg.to_dict()
    d["parameters"]["rhoI"] = {"value": rhoI}
    return em.config_from_dict(d)


MASSES = {"one mass between nodes": [(0.3, 0.08)], "one on a node": [(10 / 41, 0.05)],
          "two masses": [(0.3, 0.08), (0.77, 0.2)]}


def _sorted(s: np.ndarray) -> np.ndarray:
    return s[np.lexsort((s.real, np.round(s.imag, 6)))]


@pytest.mark.parametrize("name", sorted(MASSES))
def test_low_rank_route_equals_the_dense_eigenproblem(name):
    """Poles and the transfer function of every mode from the structured route against ``eig`` of the
    ``2k × 2k`` state matrix of the same ``C_m``.

    Budget: both carry the round-off of an eigen-decomposition, ``eps · cond(V)`` relative per pole (cond of the
    dense route's column-scaled basis, computed here; at most ~10 on these beams), times 100 for the
    difference of two such solutions summed over the modes.
    """
    cfg = beam(MASSES[name])
    mm = modal_matrices(cfg, cfg.parameter_values())
    assert mm.damping is None and mm.low_rank is not None        # coupled, and the structure was recognised
    assert mm.low_rank.G.shape[1] == sum(1 if abs(x * 41 - round(x * 41)) < 1e-9 else 2 for x, _ in MASSES[name])
    _equals_the_dense_route(cfg, mm)


def _equals_the_dense_route(cfg: em.BeamConfig, mm) -> np.ndarray:
    """The structured ``C_m``, poles and transfer function against ``ΨᵀCΨ`` and ``eig`` of the dense state matrix
    (budgets of :func:`test_low_rank_route_equals_the_dense_eigenproblem`); the structured route's poles."""
    dense_Cm = mm.shapes.T @ discretised_C(cfg) @ mm.shapes
    # the structured C_m is Ψᵀ C Ψ with Ψᵀ M Ψ = I taken as exact: equal to the modes' orthogonality round-off
    np.testing.assert_allclose(mm.Cm, 0.5 * (dense_Cm + dense_Cm.T), rtol=0, atol=1e-10 * np.abs(mm.Cm).max())
    found = cmod.coupled_modes(mm.frequencies2, mm.low_rank, mm.Fm)
    assert found is not None
    lam, V, B = found
    s_dense, V_dense = np.linalg.eig(modal_state_matrix(mm.frequencies2, mm.Cm))
    B_dense = np.linalg.solve(V_dense, np.vstack([np.zeros_like(mm.Fm), mm.Fm]))
    tol = 100 * np.finfo(float).eps * basis_condition(V_dense)
    np.testing.assert_allclose(_sorted(lam), _sorted(s_dense), rtol=tol)
    k = mm.frequencies2.size
    for f in (1.0, 7.0, 40.0, 300.0):
        z = 2j * np.pi * f
        H = V[:k] @ (B / (z - lam)[:, None])
        H_dense = V_dense[:k] @ (B_dense / (z - s_dense)[:, None])
        assert np.abs(H - H_dense).max() <= tol * np.abs(H_dense).max(), (f, np.abs(H - H_dense).max())
    return lam


#: Kelvin–Voigt damping (ζ 0.2–2 % over the first modes) with viscous damping or alone, without axial load: the
#: springs' stiffness and the masses' inertia are what ``C = α M + β K`` leaves out, on 1–4 unknowns (an elastic
#: end's springs are not: they enter ``K`` and the Kelvin–Voigt term through the same ghost rows)
KELVIN_VOIGT = {
    "a mass": dict(masses=[(0.3, 0.08)]),
    "a spring, no viscous damping": dict(masses=[], springs=[(0.45, 300.0)], c=0.0),
    "a spring to ground": dict(masses=[], springs=[(0.45, 300.0)]),
    "a shaker's mass and spring": dict(masses=[(0.77, 0.1)], springs=[(0.77, 400.0)]),
}


@pytest.mark.parametrize("name", sorted(KELVIN_VOIGT))
def test_kelvin_voigt_damping_with_attachments_is_low_rank(name):
    """Without axial load ``ψ̃ᵀC̃ψ̃`` is the grid's own ``ω̃²`` less the springs' part: a Kelvin–Voigt term with masses
    and springs takes the structured route, and its modal damping, poles and transfer function are the dense
    ones (budgets of :func:`test_low_rank_route_equals_the_dense_eigenproblem`)."""
    cfg = beam(**({"N": 0.0, "eta": 1e-4} | KELVIN_VOIGT[name]))
    mm = modal_matrices(cfg, cfg.parameter_values())
    assert mm.damping is None and mm.low_rank is not None and 1 <= mm.low_rank.rank <= 4
    lam = _equals_the_dense_route(cfg, mm)
    assert np.count_nonzero(lam.imag == 0) >= 2        # the stiffest modes overdamped: both real roots found
    # and the realisation simulates the Van Loan exponential's outputs (budget of the simulation test below)
    u = band_limited_input(1500, 5e-4, 2.0, 150.0, seed=9)
    p = cfg.parameter_values()
    y_modal = em.simulate(exact_modal(cfg, p), u).outputs
    y_dense = em.simulate(exact_statespace(cfg, p), u).outputs
    err = np.abs(y_dense - y_modal).max(axis=0) / np.abs(y_modal).max(axis=0)
    V = cmod.coupled_modes(mm.frequencies2, mm.low_rank, mm.Fm)[1]
    assert np.all(err < max(10 * np.finfo(float).eps * basis_condition(V), 1e-12)), err


@pytest.mark.parametrize("what", ["a weak segment", "a mass without viscous damping", "an elastic end"])
def test_kelvin_voigt_damping_without_what_it_leaves_out_is_decoupled(what):
    """A weak segment lowers ``EI`` and the Kelvin–Voigt term alike (``C̃ = K̃``), so do an elastic end's springs
    (the same ghost rows); a point mass is not in a damping without a viscous term (``C = η K``): the modes stay
    decoupled, each with ``d_i = c/ρA + η ω_i²`` on the grid's own ``ω²`` — the dense ``ΨᵀCΨ``'s diagonal to its
    round-off, its off-diagonal round-off only."""
    if what == "a weak segment":
        cfg = em.config_from_dict(beam([], N=0.0, eta=1e-4).to_dict() | {
            "weak_segments": [{"name": "w", "x": 0.4, "length": 0.1, "factor": 0.6}]})
    elif what == "an elastic end":
        cfg = beam([], N=0.0, eta=1e-4, left="elastic", left_springs=(1e4, 50.0))
    else:
        cfg = beam([(0.3, 0.08)], N=0.0, eta=1e-4, c=0.0)
    mm = modal_matrices(cfg, cfg.parameter_values())
    assert mm.damping is not None and mm.low_rank is None
    dense_Cm = mm.shapes.T @ discretised_C(cfg) @ mm.shapes
    np.testing.assert_allclose(mm.damping, np.diag(dense_Cm), rtol=1e-10)
    assert np.abs(dense_Cm - np.diag(np.diag(dense_Cm))).max() <= 1e-10 * np.abs(dense_Cm).max()


def discretised_C(cfg: em.BeamConfig) -> np.ndarray:
    """The damping matrix on the grid the modes' shapes live on (the refined one of the Richardson pair)."""
    from ebb_model.space.discretisation import discretise
    from ebb_model.space.richardson_pair import refined_config
    return discretise(refined_config(cfg), cfg.parameter_values()).C


def test_low_rank_simulation_equals_the_matrix_exponential():
    """The exact realisation through the structured route simulates the same outputs as the Van Loan matrix
    exponential of the same modal system (no eigenvectors): displacement, velocity and acceleration sensors.

    Budget as in ``test_exact_scheme``: ``eps · cond(V)`` relative, times 10 for the sum over the states of a
    sample and the recursion."""
    cfg = beam(MASSES["two masses"])
    p = cfg.parameter_values()
    cm = continuous_modes(cfg, p)
    u = band_limited_input(1500, 5e-4, 2.0, 150.0, seed=5)
    y_modal = em.simulate(exact_modal(cfg, p), u).outputs
    y_dense = em.simulate(exact_statespace(cfg, p), u).outputs
    tol = max(10 * np.finfo(float).eps * basis_condition(cm.V), 1e-12)
    err = np.abs(y_dense - y_modal).max(axis=0) / np.abs(y_modal).max(axis=0)
    assert np.all(err < tol), (err, tol)


def test_lowest_poles_equal_every_pole():
    """``modal_poles`` with ``lowest`` (the modal pattern's comparison) equals the lowest of all poles, and the
    structured route equals the full-coupling Newton route it replaced (:func:`_coupled_poles`)."""
    import ebb_model.modal.modal_poles as mpoles

    cfg = beam(MASSES["two masses"])
    p = cfg.parameter_values()
    mm = modal_matrices(cfg, p)
    every = np.linalg.eigvals(modal_state_matrix(mm.frequencies2, mm.Cm))
    every = every[every.imag > 0]
    every = every[np.argsort(every.imag)]
    low = modal_poles(cfg, p, 5)
    low = low[low.imag > 0]
    low = low[np.argsort(low.imag)]
    np.testing.assert_allclose(low, every[:5], rtol=1e-12)
    full = mpoles._coupled_poles(mm.frequencies2, mm.Cm, 5)
    np.testing.assert_allclose(full[np.argsort(full.imag)], low, rtol=1e-12)


@pytest.mark.parametrize("kind", ["kelvin-voigt", "rotary inertia"])
def test_other_damping_is_not_low_rank(kind):
    """A Kelvin–Voigt term or rotary inertia makes ``C − α M`` non-zero on every unknown: the dense route
    decides, and the realisation still simulates (same outputs as the matrix exponential)."""
    cfg = beam(MASSES["one mass between nodes"], **({"eta": 2e-4} if kind == "kelvin-voigt" else {"rhoI": 1e-4}))
    mm = modal_matrices(cfg, cfg.parameter_values())
    assert mm.damping is None and mm.low_rank is None
    u = band_limited_input(600, 5e-4, 2.0, 150.0, seed=6)
    y_modal = em.simulate(em.fast_model(cfg), u).outputs
    y_dense = em.simulate(exact_statespace(cfg, cfg.parameter_values()), u).outputs
    assert np.abs(y_dense - y_modal).max() <= 1e-9 * np.abs(y_dense).max()


def test_unconverged_newton_falls_back_to_the_dense_route(monkeypatch):
    """When Newton's iteration does not converge the dense eigenproblem gives the modes: the same outputs."""
    cfg = beam(MASSES["two masses"])
    p = cfg.parameter_values()
    u = band_limited_input(600, 5e-4, 2.0, 150.0, seed=7)
    y = em.simulate(exact_modal(cfg, p), u).outputs
    mm = modal_matrices(cfg, p)
    monkeypatch.setattr(cmod, "NEWTON_STEPS", 1)
    assert cmod.coupled_modes(mm.frequencies2, mm.low_rank, mm.Fm) is None
    y_dense_route = em.simulate(exact_modal(cfg, p), u).outputs
    np.testing.assert_allclose(y_dense_route, y, rtol=0, atol=1e-10 * np.abs(y).max())


def test_mass_proportional_damping_near_buckling_is_decoupled():
    """``C = α M`` is decoupled however far the computed modes are from M-orthogonal: on a pinned–pinned beam
    half-way to buckling ``Ψᵀ C Ψ`` has off-diagonal round-off above ``is_proportional``'s 1e-10 (the
    eigenvectors of the nearly singular ``K``), which sent every evaluation of the rig family's compressed bench
    through the dense eigenproblem.  Decoupled, it simulates the outputs of the matrix exponential."""
    from ebb_model.space.discretisation import discretise
    from ebb_model.space.richardson_pair import refined_config
    from ebb_model.theta.modal_form import is_proportional

    cfg = make_config("pinned", "pinned", nodes=60, dt=5e-4, EI=11.2, rhoA=0.9, c=2.3, N=-43.0,
                      actuators=[("F1", 0.45)], sensors=[("v1", 0.3, "velocity"), ("v2", 0.7, "velocity")])
    p = cfg.parameter_values()
    mm = modal_matrices(cfg, p)
    assert not is_proportional(mm.shapes, discretise(refined_config(cfg), p).C)[0]   # the round-off is there
    assert mm.damping is not None and mm.low_rank is None                           # and taken for what it is
    np.testing.assert_allclose(mm.damping, 2.3 / 0.9, rtol=1e-9)
    u = band_limited_input(1500, 5e-4, 2.0, 100.0, seed=8)
    y_modal = em.simulate(exact_modal(cfg, p), u).outputs
    y_dense = em.simulate(exact_statespace(cfg, p), u).outputs
    # budget: the dense route's eigen-free exponential against closed-form poles; the coupling left out is the
    # orthogonality round-off, ~1e-9 of the damping, itself ~1e-2 of the response: far below 1e-9
    assert np.abs(y_dense - y_modal).max() <= 1e-9 * np.abs(y_modal).max()
