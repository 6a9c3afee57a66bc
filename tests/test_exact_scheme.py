"""The accurate realisation (``[time] scheme = "exact"``) against independent, converged truth.

Truth: cubic Hermite finite elements integrated exactly in time (:mod:`ebb_model.reference.exact_fe`:
matrix exponential per sub-step, force a cubic spline through the samples), shown converged here in mesh
and sub-grid.  Records as the model-accuracy issue describes them: lightly damped, accelerometers and
displacement sensors, 1 % noise, excitation band up to fs/13.  Residuals are mean squared errors at the
true parameters in units of the noise variance (1 = the noise floor).

Also against closed forms: clamped–clamped ``Ω = 22.3733, 61.6728, 120.9034`` and the pinned–pinned
``Ω_n = nπ√(n²π² + U)`` under tension, where the Richardson modes converge at fourth order.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ebb_model as em
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.exact_fe import exact_fe_response
from ebb_model.reference.hermite_fe import hermite_beam

INF = math.inf
ENDS = {"clamped": (INF, INF), "pinned": (INF, 0.0), "free": (0.0, 0.0)}

# steel strip 40 x 4 mm
EI_STEEL = 210e9 * 0.04 * 0.004 ** 3 / 12
RHOA_STEEL = 7850 * 0.04 * 0.004

CASES = {
    # clamped–pinned, 0.8 m, 300 N tension, viscous + Kelvin–Voigt damping (ζ 0.4–1.6 % in band), 4 kHz,
    # 5–300 Hz (modes 1–4), two accelerometers
    "clamped-pinned-accelerometers": dict(
        length=0.8, left="clamped", right="pinned", params=dict(EI=EI_STEEL, rhoA=RHOA_STEEL, c=4.0, eta=5e-6,
                                                                 N=300.0),
        dt=1 / 4000, band=(5.0, 300.0), actuator=0.44, sensors=((0.24, "acceleration"), (0.6, "acceleration"))),
    # cantilever, 0.75 m, no axial load, light viscous damping (ζ 0.2–2 %), 3.2 kHz, 2–240 Hz,
    # a displacement sensor and an accelerometer
    "cantilever-mixed": dict(
        length=0.75, left="clamped", right="free", params=dict(EI=EI_STEEL, rhoA=RHOA_STEEL, c=1.5, eta=2e-6,
                                                                N=0.0),
        dt=1 / 3200, band=(2.0, 240.0), actuator=0.7, sensors=((0.5, "displacement"), (0.74, "acceleration"))),
    # clamped–pinned under tension, lightest damping at the top of the band (ζ 2.1 % at mode 1 down to 0.2 % at
    # mode 5, 137 Hz), 2 kHz, 2–150 Hz (fs/13), two accelerometers, 1.5 s: where the input reconstruction shows
    "clamped-pinned-light": dict(
        length=1.0, left="clamped", right="pinned", params=dict(EI=10.0, rhoA=1.0, c=2.0, eta=2e-6, N=20.0),
        dt=5e-4, band=(2.0, 150.0), actuator=0.55, sensors=((0.35, "acceleration"), (0.8, "acceleration"))),
}
SAMPLES_PER_CASE = {"clamped-pinned-accelerometers": 4000, "cantilever-mixed": 3200,   # 1 s records
                    "clamped-pinned-light": 3000}


def config(case: dict, nodes: int, scheme: str) -> em.BeamConfig:
    return em.config_from_dict({
        "beam": {"length": case["length"], "nodes": nodes, "left": case["left"], "right": case["right"]},
        "time": {"dt": case["dt"], "scheme": scheme},
        "parameters": {k: {"value": v} for k, v in case["params"].items()},
        "actuators": [{"name": "F1", "x": case["actuator"]}],
        "sensors": [{"name": f"s{i}", "x": x, "kind": k} for i, (x, k) in enumerate(case["sensors"])],
    })


def truth(case: dict, u: np.ndarray, n_elements: int) -> np.ndarray:
    b = hermite_beam(case["length"], n_elements, left=ENDS[case["left"]], right=ENDS[case["right"]],
                     **case["params"])
    return exact_fe_response(b, u, case["dt"], [case["actuator"]], case["sensors"])


@pytest.fixture(scope="module", params=sorted(CASES))
def record(request):
    case = CASES[request.param]
    n = SAMPLES_PER_CASE[request.param]
    u = band_limited_input(n, case["dt"], *case["band"], seed=4)
    y = truth(case, u, 96)
    noise_var = (0.01 * y.std(axis=0)) ** 2
    return request.param, case, u, y, noise_var


def residual(y: np.ndarray, truth_y: np.ndarray, noise_var: np.ndarray) -> np.ndarray:
    """Mean squared error per sensor in noise variances."""
    return np.mean((y - truth_y) ** 2, axis=0) / noise_var


def test_truth_is_converged_far_below_the_noise(record):
    """Mesh 96 → 128 elements changes the truth by far less than the residuals tested against it, so residuals
    of the model at the noise floor are the model's, not the truth's.  (In time the truth is exact for the
    spline force: see test_truth_integrator_is_exact_for_the_spline_force.)

    Error budget, measured: ≤ 1.3e-4 noise variances on an Intel machine; on an AMD EPYC machine (same lock)
    2.0e-3 on cantilever-mixed's displacement sensor, where the change *grows* with refinement (64 → 96:
    7.4e-4, 96 → 128: 2.0e-3, 128 → 160: 3.1e-2) — the integrator's round-off on the finer meshes, not their
    discretisation error, and it varies from run to run at the 20 % level.  What is tested against this truth:
    at most 1.5 noise variances (below), figures down to 0.008 (benchmarks).  The bound 5e-3 keeps the truth's
    uncertainty 300× below the assertions and ≥ 1.6× below the smallest quoted figure; the round-off's growth
    with the mesh is recorded in the closing note of the session that measured it.
    """
    name, case, u, y, noise_var = record
    finer = truth(case, u, 128)
    assert np.all(residual(y, finer, noise_var) < 5e-3), (name, residual(y, finer, noise_var))


def test_truth_integrator_is_exact_for_the_spline_force():
    """The truth's time integration against an adaptive 8th-order Runge–Kutta solve (rtol 1e-12) of the same
    finite-element ODE under the same cubic spline force, on a coarse mesh (the ODE solver's cost grows with
    the stiffness).  Budget: the solver's own error, measured 1e-9 relative; 1e-7 is 1e-10 noise variances."""
    from scipy.integrate import solve_ivp
    from scipy.interpolate import CubicSpline

    case = CASES["clamped-pinned-accelerometers"]
    n = 120
    u = band_limited_input(n, case["dt"], *case["band"], seed=5)
    b = hermite_beam(case["length"], 6, left=ENDS[case["left"]], right=ENDS[case["right"]], **case["params"])
    sensors = ((0.24, "displacement"), (0.6, "velocity"), (0.44, "acceleration"))
    y = exact_fe_response(b, u, case["dt"], [case["actuator"]], sensors)
    t = np.arange(n) * case["dt"]
    force = CubicSpline(t, u[:, 0])
    f_vec = b.load_vector(case["actuator"])
    M_inv = np.linalg.inv(b.M)
    nf = b.M.shape[0]

    def rhs(time, x):
        return np.concatenate([x[nf:], M_inv @ (f_vec * force(time) - b.C @ x[nf:] - b.K @ x[:nf])])

    sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(2 * nf), t_eval=t, method="DOP853", rtol=1e-12, atol=1e-16)
    rows = [b.displacement_row(x) for x, _ in sensors]
    acc = M_inv @ (np.outer(f_vec, u[:, 0]) - b.C @ sol.y[nf:] - b.K @ sol.y[:nf])
    ref = np.column_stack([rows[0] @ sol.y[:nf], rows[1] @ sol.y[nf:], rows[2] @ acc])
    err = np.abs(y - ref).max(axis=0) / np.abs(ref).max(axis=0)
    assert np.all(err < 1e-7), err


@pytest.mark.parametrize("nodes", [60, 120])
def test_exact_scheme_is_at_the_noise_floor_where_the_seed_scheme_is_not(record, nodes):
    """At the true parameters the exact scheme leaves <= 1.5 noise variances (the issue's target; the force
    taken as linear between samples accounts for most of what is left); the seed's FD + θ-scheme on the same
    grid leaves hundreds to thousands."""
    name, case, u, y, noise_var = record
    r_exact = residual(em.simulate(em.fast_model(config(case, nodes, "exact")), u).outputs, y, noise_var)
    r_theta = residual(em.simulate(em.fast_model(config(case, nodes, "theta")), u).outputs, y, noise_var)
    assert np.all(r_exact <= 1.5), (name, r_exact)
    assert np.all(r_theta > 100 * r_exact), (name, r_theta, r_exact)


@pytest.mark.parametrize("left,right,omegas", [
    ("clamped", "clamped", (22.3733, 61.6728, 120.9034)),
])
def test_richardson_modes_converge_at_fourth_order_to_the_closed_form(left, right, omegas):
    """Clamped–clamped, U = 0: Ω = ω L² √(ρA/EI) of the exact scheme's poles (no damping, so the poles are
    ±iω of the Richardson modes).  The tabulated Ω carry 6 digits (±2e-6 relative), so the order is
    checked on grids where the error is well above that: 21 and 43 nodes (measured errors 3e-5–4e-4 and
    3e-6–2.4e-5, orders 3.6–4.0; the seed's FD modes are 0.2–0.8 % off at 43 nodes)."""
    def errors(nodes):
        cfg = em.config_from_dict({"beam": {"length": 1.0, "nodes": nodes, "left": left, "right": right},
                                   "time": {"dt": 1e-4, "scheme": "exact"},
                                   "parameters": {"EI": {"value": 1.0}, "rhoA": {"value": 1.0}},
                                   "actuators": [{"name": "F1", "x": 0.3}],
                                   "sensors": [{"name": "y1", "x": 0.6}]})
        f, _ = em.discrete_frequencies(cfg)
        return np.abs(2 * np.pi * f[:3] / np.asarray(omegas) - 1)
    e21, e43 = errors(21), errors(43)
    order = np.log(e21 / e43) / np.log(44 / 22)
    assert np.all(e43 < 3e-5), e43
    assert np.all(order > 3.5), order


def test_pinned_pinned_under_tension_matches_the_closed_form_at_fourth_order():
    """Ω_n = nπ√(n²π² + U), U = N L²/EI = 30: modes 1–5 within 1e-6 at 100 nodes (measured 8.4e-7; the pair
    100/201 nodes) and the error falls as h⁴ from 60 nodes (measured 6.3e-6: ratio 7.5 = (101/61)⁴)."""
    U = 30.0

    def error(nodes):
        cfg = em.config_from_dict({"beam": {"length": 1.0, "nodes": nodes, "left": "pinned", "right": "pinned"},
                                   "time": {"dt": 1e-4, "scheme": "exact"},
                                   "parameters": {"EI": {"value": 1.0}, "rhoA": {"value": 1.0}, "N": {"value": U}},
                                   "actuators": [{"name": "F1", "x": 0.3}], "sensors": [{"name": "y1", "x": 0.6}]})
        f, _ = em.discrete_frequencies(cfg)
        n = np.arange(1, 6)
        return np.max(np.abs(2 * np.pi * f[:5] / (n * np.pi * np.sqrt(n ** 2 * np.pi ** 2 + U)) - 1))

    e60, e100 = error(60), error(100)
    assert e100 < 1e-6, e100
    assert np.log(e60 / e100) / np.log(101 / 61) > 3.8


def test_exact_scheme_is_the_same_through_every_route():
    """fast_model (simulate), assemble (dense) and the FMU's assemble_modal give the same outputs."""
    case = CASES["clamped-pinned-accelerometers"]
    cfg = config(case, 40, "exact")
    u = band_limited_input(800, case["dt"], *case["band"], seed=1)
    y_fast = em.simulate(em.fast_model(cfg), u).outputs
    y_dense = em.simulate(em.assemble(cfg), u).outputs      # starts at rest: ξ₀ = −Γ₁ u₀ (first-order hold)
    np.testing.assert_allclose(y_dense, y_fast, rtol=0, atol=1e-12 * np.abs(y_fast).max())


def test_config_scheme_is_validated_and_round_trips():
    case = CASES["cantilever-mixed"]
    cfg = config(case, 20, "exact")
    assert cfg.time.scheme == "exact"
    assert em.config_from_dict(cfg.to_dict()).time.scheme == "exact"
    d = cfg.to_dict()
    d["time"]["scheme"] = "newmark"
    with pytest.raises(em.ConfigError, match=r"time\.scheme: must be one of theta, exact, got 'newmark'"):
        em.config_from_dict(d)


def test_pole_integrals_equal_the_matrix_exponential():
    """Closed form and Taylor branch (|sT| < 1/2) against scipy's expm of the augmented 3×3 matrix."""
    import scipy.linalg as sla

    from ebb_model.exact.sample_integrals import pole_integrals

    rng = np.random.default_rng(0)
    mag = 10.0 ** rng.uniform(-3, 5, 300)
    s = mag * np.exp(1j * rng.uniform(np.pi / 2, 3 * np.pi / 2, 300))     # left half-plane: stable poles
    T = 2.5e-4
    E, phi0, phi1 = pole_integrals(s, T)
    A = np.zeros((s.size, 3, 3), dtype=complex)
    A[:, 0, 0], A[:, 0, 1], A[:, 1, 2] = s * T, T, 1.0
    X = sla.expm(A)
    np.testing.assert_allclose(E, X[:, 0, 0], rtol=1e-13, atol=1e-300)
    np.testing.assert_allclose(phi0, X[:, 0, 1], rtol=1e-12)
    np.testing.assert_allclose(phi1, X[:, 0, 2], rtol=1e-12)


def test_dense_exact_route_equals_the_modal_route():
    """exact_statespace (one Van Loan matrix exponential, no eigenvectors) = exact_modal (poles, closed form).

    Budget: the modal route carries the eigenvector basis' round-off, ``eps · cond(V)`` relative (cond of the
    column-scaled basis, computed here); the matrix exponential is backward stable.  Factor 10 for the sum over
    the states of a sample and the 800-sample recursion.
    """
    from ebb_model.exact.exact_modal import continuous_modes, exact_modal, exact_statespace
    from ebb_model.theta.modal_form import basis_condition

    for name, hold in (("clamped-pinned-accelerometers", "foh"), ("cantilever-mixed", "zoh"),
                       ("clamped-pinned-light", "cubic")):
        case = CASES[name]
        d = config(case, 40, "exact").to_dict()
        d["time"]["input"] = hold
        cfg = em.config_from_dict(d)
        p = cfg.parameter_values()
        u = band_limited_input(800, case["dt"], *case["band"], seed=2)
        y_modal = em.simulate(exact_modal(cfg, p), u).outputs
        y_dense = em.simulate(exact_statespace(cfg, p), u).outputs
        tol = max(10 * np.finfo(float).eps * basis_condition(continuous_modes(cfg, p).V), 1e-12)
        err = np.abs(y_dense - y_modal).max() / np.abs(y_modal).max()
        assert err < tol, (name, err, tol)


def test_exact_scheme_falls_back_to_the_dense_route(monkeypatch):
    """A basis above the condition limit gives the dense exact system, not an error: same outputs."""
    import ebb_model.exact.exact_modal as xm

    case = CASES["clamped-pinned-accelerometers"]                 # N and eta: non-proportional damping
    cfg = config(case, 30, "exact")
    u = band_limited_input(800, case["dt"], *case["band"], seed=3)
    y_modal = em.simulate(em.fast_model(cfg), u).outputs
    monkeypatch.setattr(xm, "MAX_BASIS_CONDITION", 1.0)            # every basis is now "ill-conditioned"
    with pytest.raises(np.linalg.LinAlgError, match="ill-conditioned"):
        xm.continuous_modes(cfg, cfg.parameter_values())
    model = em.fast_model(cfg)
    assert isinstance(model, em.DiscreteStateSpace)
    np.testing.assert_allclose(em.simulate(model, u).outputs, y_modal, rtol=0, atol=1e-10 * np.abs(y_modal).max())
    assert em.assemble(cfg).nstates == model.nstates
    f_fallback, _ = em.discrete_frequencies(cfg)                  # poles need no eigenvectors
    monkeypatch.undo()
    np.testing.assert_allclose(f_fallback, em.discrete_frequencies(cfg)[0], rtol=1e-12)


def test_theta_fast_path_never_raises_on_ill_conditioned_eigenvectors():
    """The model-accuracy issue's failure: 240 nodes, 32 sub-steps, non-proportional damping raised LinAlgError.

    The block form now comes from one sub-step's eigenvectors.  Its round-off budget is measured on the
    proportional twin (eta = 0), where the exactly diagonal route (modal_from_beam) is the reference: both the
    dense nodal system and the one-sub-step route stay within ``err_twin`` of it, so on the non-proportional
    case the two may differ by at most ``2 · err_twin`` (factor 3 kept for the different damping).
    """
    from ebb_model.space.discretisation import discretise
    from ebb_model.theta.modal_form import ModalStateSpace, modal_from_beam, modal_from_theta
    from ebb_model.theta.theta_scheme import discretise_time

    case = CASES["clamped-pinned-accelerometers"]
    u = band_limited_input(1000, case["dt"], *case["band"], seed=4)

    def setup(eta: float):
        d = config(case, 240, "theta").to_dict()
        d["time"]["substeps"] = 32
        d["parameters"]["eta"] = {"value": eta}
        cfg = em.config_from_dict(d)
        return cfg, discretise(cfg)

    def rel(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.abs(a - b).max() / np.abs(b).max())

    twin, beam = setup(0.0)
    y_ref = em.simulate(modal_from_beam(beam, case["dt"], 0.25, 32), u).outputs
    err_twin = max(rel(em.simulate(modal_from_theta(beam, case["dt"], 0.25, 32), u).outputs, y_ref),
                   rel(em.simulate(discretise_time(beam, case["dt"], 0.25, 32), u).outputs, y_ref))
    assert err_twin < 1e-6, err_twin
    cfg, beam = setup(case["params"]["eta"])
    model = em.fast_model(cfg)
    assert isinstance(model, ModalStateSpace)
    y_dense = em.simulate(discretise_time(beam, case["dt"], 0.25, 32), u).outputs
    assert rel(em.simulate(model, u).outputs, y_dense) < 3 * 2 * err_twin


def test_the_cubic_input_reaches_the_noise_floor_where_the_straight_line_does_not():
    """On the lightly damped record whose band reaches fs/13 the straight line between force samples is 2 % off
    in amplitude at the top of the band: the exact scheme with ``input = "foh"`` leaves more than 1.5 noise
    variances at the true parameters; with the default ``"cubic"`` (four samples) it is at the noise floor."""
    case = CASES["clamped-pinned-light"]
    u = band_limited_input(SAMPLES_PER_CASE["clamped-pinned-light"], case["dt"], *case["band"], seed=4)
    y = truth(case, u, 96)
    noise_var = (0.01 * y.std(axis=0)) ** 2
    cfg = config(case, 60, "exact")
    assert cfg.time.input_hold == "cubic"                  # the default of the exact scheme
    d = cfg.to_dict()
    d["time"]["input"] = "foh"
    r_cubic = residual(em.simulate(em.fast_model(cfg), u).outputs, y, noise_var)
    r_foh = residual(em.simulate(em.fast_model(em.config_from_dict(d)), u).outputs, y, noise_var)
    assert np.all(r_cubic <= 1.5) and np.max(r_foh) > 1.5 and np.all(r_foh > 3 * r_cubic), (r_cubic, r_foh)


def test_polynomial_integrals_equal_the_matrix_exponential():
    """``∫ e^{s(T−τ)} (τ/T)^p dτ``, p = 0…3 (recurrence and series branches), against scipy's expm of the
    5×5 matrix augmented with the chain of derivatives of ``σ³``."""
    import scipy.linalg as sla

    from ebb_model.exact.sample_integrals import polynomial_integrals

    rng = np.random.default_rng(1)
    mag = 10.0 ** rng.uniform(-3, 5, 300)
    s = mag * np.exp(1j * rng.uniform(np.pi / 2, 3 * np.pi / 2, 300))
    T = 2.5e-4
    E, I = polynomial_integrals(s, T, 3)
    A = np.zeros((s.size, 5, 5), dtype=complex)
    A[:, 0, 0], A[:, 0, 1] = s * T, T
    A[:, 1, 2], A[:, 2, 3], A[:, 3, 4] = 1.0, 1.0, 1.0      # chain f → f' → f'' → f''' in σ
    X = sla.expm(A)
    np.testing.assert_allclose(E, X[:, 0, 0], rtol=1e-13, atol=1e-300)
    for p in range(4):                                        # σ^p: p! times a unit start of the p-th derivative
        np.testing.assert_allclose(I[p], math.factorial(p) * X[:, 0, 1 + p], rtol=1e-11)


def test_the_series_branch_keeps_the_integrals_at_round_off():
    """Below ``|sT| = 1`` the integrals' series takes only the terms ``|sT|`` needs (at most 24): against the same
    series to 40 digits (mpmath), 200 poles of ``|sT|`` 1e-8 … 1 (complex and real), every degree 0 … 3."""
    import mpmath as mp

    from ebb_model.exact.sample_integrals import polynomial_integrals

    mp.mp.dps = 40
    rng = np.random.default_rng(6)
    s = 10.0 ** rng.uniform(-8, 0, 200) * np.exp(1j * rng.uniform(0, 2 * np.pi, 200))
    s[::7] = s[::7].real
    worst = 0.0
    for degree in range(4):
        _, I = polynomial_integrals(s, 1.0, degree)
        for j, sj in enumerate(s):
            z = mp.mpc(sj.real, sj.imag)
            for p in range(degree + 1):
                exact = complex(mp.nsum(lambda k: z ** k * mp.factorial(p) / mp.factorial(k + p + 1), [0, mp.inf]))
                worst = max(worst, abs(I[p, j] - exact) / abs(exact))
    # budget: Horner's rule on a series whose terms fall at least 2x per step, one rounding per step, each damped
    # by |z| ≤ 1: about one ulp.  Measured 1.0 eps with the terms truncated where what is left out falls below
    # eps/16, 0.92 eps with all 24; a truncation at 2^-40 would be ~1e-12 off
    assert worst <= 2.0 * np.finfo(float).eps, worst


@pytest.mark.parametrize("extra", [{"masses": [("m", 0.7, 0.1)]}, {"eta": 2e-4, "masses": [("m", 0.3, 0.4)]}])
def test_lowest_poles_of_damping_coupled_modes_equal_the_full_eigenproblem(cfg_factory, extra):
    # a point mass with viscous damping couples the modes through C_m: the lowest poles by Newton on
    # det(s²I + sC_m + Λ) must be the 2k × 2k eigenvalue problem's, and they must be found that way
    from ebb_model.exact.exact_modal import modal_matrices
    from ebb_model.modal.modal_poles import _coupled_poles

    cfg = cfg_factory("clamped", "pinned", nodes=40, c=3.0, scheme="exact", **extra)
    mm = modal_matrices(cfg, cfg.parameter_values())
    assert mm.damping is None                                   # the damping does couple the modes
    assert _coupled_poles(mm.frequencies2, mm.Cm, 5) is not None
    f_all, z_all = em.discrete_frequencies(cfg)
    f5, z5 = em.discrete_frequencies(cfg, None, 5)
    assert f5.shape == z5.shape == (5,)
    # measured: 5e-14 (frequencies) and 3e-11 (damping ratios, whose real parts are 1e-2–1e-3 of |s|) — the
    # eigenvalue solver's round-off on the balanced companion matrix; a neighbour's pole would be off by 1e0
    np.testing.assert_allclose(f5, f_all[:5], rtol=1e-12)
    np.testing.assert_allclose(z5, z_all[:5], rtol=1e-9)


@pytest.mark.parametrize("ends,extra", [(("clamped", "pinned"), {}), (("pinned", "pinned"), {"N": -40.0}),
                                        (("clamped", "free"), {"springs": [("k", 0.6, 400.0)]}),
                                        (("clamped", "clamped"), {"c": 0.0})])
def test_lowest_poles_of_mass_proportional_damping_need_no_mode_shapes(cfg_factory, ends, extra):
    # viscous damping per unit mass (C = c/ρA · M) leaves the modes decoupled: the lowest poles come from the
    # two grids' lowest eigenvalues alone (no shapes) and must equal the full route's
    from ebb_model.modal.modal_poles import _mass_proportional_poles

    kw = {"c": 3.0, **extra}
    cfg = cfg_factory(*ends, nodes=60, scheme="exact", **kw)
    assert _mass_proportional_poles(cfg, cfg.parameter_values(), 5) is not None     # the short route is taken
    f_all, z_all = em.discrete_frequencies(cfg)
    f5, z5 = em.discrete_frequencies(cfg, None, 5)
    # budget: two independent solvers of the inverted problem, each off the same matrices' 32-digit eigenvalues by
    # its own round-off (grows with κ(K)); measured on these grids (tests/test_few_modes.py for the method): the
    # short route's Lanczos ≤ 1.9e-10 in ω², LAPACK's dense solver for all of them ≤ 6.3e-10 (mode 1 of the
    # cantilever's 122-unknown grid) — their difference ≤ 8.2e-10 in ω², half of it in ω, and the extrapolation
    # ω²_f + (ω²_f − ω²_c)/3 weighs the fine grid's by 4/3: ≤ 5.5e-10 in frequency and damping ratio (d is one
    # rate for all modes, ζ = d/2ω).  Measured here: at most 2.9e-10 (the cantilever), 3.4e-11 (clamped–clamped).
    # A neighbour's mode is 1e-1 away.
    np.testing.assert_allclose(f5, f_all[:5], rtol=5.5e-10)
    np.testing.assert_allclose(z5, z_all[:5], rtol=5.5e-10, atol=0.0)


def test_damping_that_is_not_mass_proportional_takes_the_full_route(cfg_factory):
    from ebb_model.modal.modal_poles import _mass_proportional_poles

    for extra in ({"masses": [("m", 0.7, 0.1)]}, {"eta": 2e-4}):
        cfg = cfg_factory("clamped", "pinned", nodes=40, c=3.0, scheme="exact", **extra)
        assert _mass_proportional_poles(cfg, cfg.parameter_values(), 5) is None


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "5"])
def test_discrete_frequencies_rejects_an_impossible_number_of_modes(cfg_factory, bad):
    cfg = cfg_factory("clamped", "pinned", nodes=20, scheme="exact")
    with pytest.raises(em.ConfigError, match="n_modes"):
        em.discrete_frequencies(cfg, None, bad)
