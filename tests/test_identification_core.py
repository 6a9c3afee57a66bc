"""Identification building blocks: unknowns, objectives, penalties, Fisher information, GA checkpoints."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import ebb_model as em
from ebb_model import ConfigError
from identification.fisher import fisher_information
from identification.noise import records_noise_std
from identification.native import NativeEvaluator, experiments_from_arrays
from identification.objectives import PENALTY, measured_spread, nrmse, objective_names, output_errors
from identification.optimise import knee_index, optimise
from identification.parameters import parameter_space
from identification.problem import IdentificationProblem
from identification.runners import SerialRunner

from conftest import make_config, make_identification_config


def seed_like(**kw):
    return make_identification_config(nodes=20, N=50.0, **kw)


def synthetic(cfg, n=1500, noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 1))
    y = em.simulate_config(cfg, u).outputs
    return u, y + noise * y.std(axis=0) * rng.standard_normal(y.shape)


def test_config_pickles():
    cfg = seed_like()
    back = pickle.loads(pickle.dumps(cfg))
    assert back == cfg and back.to_dict() == cfg.to_dict()
    assert type(back.parameters) is type(cfg.parameters)          # read-only again after the round trip
    with pytest.raises(TypeError):
        back.parameters["EI"] = None
    # checkpoints written before the config pickled itself hold "call _rebuild_config(dict form, extra)"
    from ebb_model.config.validation import _rebuild_config

    class OldPickle:
        def __reduce__(self):
            return (_rebuild_config, (cfg.to_dict(), ()))

    assert pickle.loads(pickle.dumps(OldPickle())) == cfg


def test_nrmse_definition():
    y = np.sin(np.linspace(0, 10, 200))[:, None]
    assert nrmse(y, y)[0] == 0.0
    assert nrmse(np.full_like(y, y.mean()), y)[0] == pytest.approx(1.0)


@pytest.mark.parametrize("per", ["sensor", "experiment"])
def test_output_errors_with_the_measured_spread_kept_are_the_same_numbers(per):
    # the evaluators keep the measured records' spread (it is every candidate's); the objectives must not move
    rng = np.random.default_rng(3)
    meas = [rng.standard_normal((300, 2)) + 1.0, rng.standard_normal((200, 2)) - 2.0]
    sims = [m + 0.1 * rng.standard_normal(m.shape) for m in meas]
    kept = output_errors(sims, meas, per=per, spread=measured_spread(meas))
    assert np.array_equal(kept, output_errors(sims, meas, per=per))
    # and the definition: per sensor, RSS over the measured spread about the mean, pooled over the experiments
    if per == "sensor":
        rss = sum(np.sum((s - m) ** 2, axis=0) for s, m in zip(sims, meas))
        spread = sum(np.sum((m - m.mean(axis=0)) ** 2, axis=0) for m in meas)
        np.testing.assert_allclose(kept, np.sqrt(rss / spread), rtol=1e-14)


def test_unstable_candidates_get_finite_penalties():
    cfg = seed_like(right="free", c=0.1)
    u, y = synthetic(cfg)
    d = cfg.to_dict()
    d["parameters"]["N"]["bounds"] = [-100.0, 100.0]
    cfg = em.config_from_dict(d)
    sp = parameter_space(cfg)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    F = ev.evaluate(np.array([[10.0, 50.0], [10.0, -90.0]]))  # cantilever buckles at N = -pi^2/4 EI
    assert np.all(np.isfinite(F))
    assert F[0, 0] < 0.05 and F[1, 0] > PENALTY
    assert objective_names(cfg.output_names, ["e"]) == ("nrmse_y1", "nrmse_y2", "growth_factor")


def test_fisher_full_rank_and_cramer_rao_matches_scatter_of_estimates():
    cfg = seed_like(c=0.5)
    sp = parameter_space(cfg)
    u, y = synthetic(cfg, noise=0.0)
    sigma = 1e-3 * y.std(axis=0)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    rep = fisher_information(ev, sp.nominal, noise_std=sigma)
    assert rep.rank == 2 and not rep.singular
    assert np.all(rep.cramer_rao_std > 0) and np.all(np.isfinite(rep.cramer_rao_std))
    # Monte Carlo: full nonlinear refits of the model (scipy least squares on the simulated outputs, not the
    # Fisher module's sensitivities) over 300 noise realisations scatter as the Cramér–Rao bound says.
    # Budget: the sample std of 300 draws has a relative standard error of 1/sqrt(2·299) = 4.1 %; 15 % is 3.6 of
    # them (the refits' nonlinearity at 0.1 % noise is far smaller).
    from scipy.optimize import least_squares

    truth = np.asarray(sp.nominal, dtype=float)
    model_y = lambda x: em.simulate_config(cfg, u, dict(zip(sp.names, x))).outputs   # noqa: E731
    rng = np.random.default_rng(5)
    est = []
    for _ in range(300):
        y_noisy = y + sigma * rng.standard_normal(y.shape)
        fit = least_squares(lambda x: ((model_y(x) - y_noisy) / sigma).ravel(), truth, x_scale=truth,
                            method="lm", xtol=1e-12, ftol=1e-12)
        est.append(fit.x)
    np.testing.assert_allclose(np.std(est, axis=0, ddof=1), rep.cramer_rao_std, rtol=0.15)
    assert np.all(np.abs(np.mean(est, axis=0) - truth) < 4 * rep.cramer_rao_std / np.sqrt(300))   # unbiased


def test_fisher_names_the_unidentifiable_direction():
    """Sensor and force at mid-span of a symmetric beam: only symmetric modes respond, so the
    sensor position has zero sensitivity — the matrix is singular and the report says which unknown."""
    d = seed_like().to_dict()
    d["actuators"] = [{"name": "F1", "x": 0.5}]
    d["sensors"] = [{"name": "y1", "x": 0.5}]
    d["identification"] = {"positions": {"y1": [0.4, 0.6]}}
    cfg = em.config_from_dict(d, extra_sections=("identification",))
    sp = parameter_space(cfg)
    assert sp.names == ("EI", "N", "x_y1")
    u, y = synthetic(cfg)
    rep = fisher_information(NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)])), sp.nominal)
    assert rep.singular
    assert any("x_y1" in m for m in rep.messages)


def test_noise_estimate_is_the_floor_above_the_excited_band():
    """Signal up to fs/13 (a lightly damped accelerometer record's band): the floor above it is the noise."""
    from ebb_model.reference.excitation import band_limited_input

    dt = 5e-4
    u = band_limited_input(6000, dt, 2.0, 150.0, seed=1)
    rng = np.random.default_rng(1)
    y = np.column_stack([u[:, 0], np.gradient(u[:, 0], dt)])   # signal whose power sits at the band's top
    sigma = 0.01 * y.std(axis=0)
    est = records_noise_std([u], [y + sigma * rng.standard_normal(y.shape)], dt)
    print(f"\nestimate / true noise std: {est / sigma}")
    assert est == pytest.approx(sigma, rel=0.1)   # 0.1: the floor of ~6000 samples in ~16 Welch segments


def test_bad_position_bounds():
    d = seed_like().to_dict()
    d["identification"] = {"positions": {"y1": [0.6, 0.4], "nope": [0.1, 0.2]}}
    with pytest.raises(ConfigError) as ei:
        parameter_space(em.config_from_dict(d, extra_sections=("identification",)))
    assert "identification.positions.y1" in str(ei.value) and "identification.positions.nope" in str(ei.value)


class _Interrupting(SerialRunner):
    """Dies (like a killed run) when asked for the given evaluation call."""

    def __init__(self, die_at_call: int):
        self.calls = 0
        self.die_at_call = die_at_call

    def __call__(self, evaluator, X):
        self.calls += 1
        if self.calls == self.die_at_call:
            raise KeyboardInterrupt
        return super().__call__(evaluator, X)


def test_stability_is_the_optimiser_constraint():
    """An unstable candidate is infeasible for pymoo (``G > 0``), not only a poor fit: a GA whose box lies half
    beyond the cantilever's buckling load (N = −π²EI/4 ≈ −24.7 N at EI = 10) returns stable points only, and
    its knee is one of them."""
    cfg = seed_like(right="free", c=0.1)
    u, y = synthetic(cfg, n=400)
    d = cfg.to_dict()
    d["parameters"]["N"]["bounds"] = [-100.0, 100.0]
    cfg = em.config_from_dict(d)
    sp = parameter_space(cfg)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    FG = ev.evaluate_constrained(np.array([[10.0, 50.0], [10.0, -90.0]]))
    assert FG.shape == (2, ev.n_obj + 1)
    np.testing.assert_array_equal(FG[:, :-1], ev.evaluate(np.array([[10.0, 50.0], [10.0, -90.0]])))
    assert FG[0, -1] <= 0.0 < FG[1, -1]                     # ρ(Φ) − 1: feasible, infeasible
    problem = IdentificationProblem(ev, objective_names(cfg.output_names, ["e"]))
    assert problem.n_ieq_constr == 1
    front = optimise(problem, pop=12, generations=4, seed=3, progress=False)
    assert np.all(front.X[:, 1] > -np.pi ** 2 * front.X[:, 0] / 4)   # above each point's own buckling load
    assert np.all(front.F[:, :2] < PENALTY)
    assert ev.simulate(front.X[front.knee]).stable


def test_checkpoint_resume_gives_identical_front(tmp_path):
    cfg = seed_like(c=0.3)
    u, y = synthetic(cfg, n=400)
    sp = parameter_space(cfg)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    names = objective_names(cfg.output_names, ["e"])
    kw = dict(pop=8, generations=5, seed=7, progress=False)
    (tmp_path / "a").mkdir()
    full = optimise(IdentificationProblem(ev, names), out_dir=tmp_path / "a", **kw)
    (tmp_path / "b").mkdir()
    with pytest.raises(KeyboardInterrupt):
        optimise(IdentificationProblem(ev, names), out_dir=tmp_path / "b", runner=_Interrupting(3), **kw)
    assert (tmp_path / "b" / "checkpoint.pkl").exists()
    resumed = optimise(IdentificationProblem(ev, names), out_dir=tmp_path / "b", resume=True, **kw)
    np.testing.assert_array_equal(full.X, resumed.X)
    np.testing.assert_array_equal(full.F, resumed.F)
    assert resumed.generations == 5
    assert knee_index(full.F, full.objective_names) == full.knee
    # the convergence history rides in the checkpoint: the resumed run's is the uninterrupted run's
    np.testing.assert_array_equal(full.history, resumed.history)
    assert full.history.shape == (5, 1 + len(names))
    assert np.all(np.diff(full.history[:, 0]) > 0)                        # evaluations so far
    np.testing.assert_array_equal(full.history[-1, 1:], full.F.min(axis=0))   # the last generation's set


def test_knee_is_a_compromise_of_the_fit_among_strictly_stable_points():
    """The stabilising objective is a constraint, not a term of the compromise: on a front where the growth
    factor barely varies it used to pull the knee to the worse-fitting, more damped end."""
    from identification.optimise import knee_order

    names = ("nrmse_y1", "nrmse_y2", "growth_factor")
    F = np.array([[0.02, 0.01, 1.0 + 1e-6],      # best fit, but unstable: never the knee
                  [0.10, 0.10, 0.99999],
                  [0.50, 0.50, 0.99990],
                  [1.00, 1.00, 0.99980]])
    assert knee_index(F) == 2                     # all three objectives normalised: the growth factor decides
    assert knee_index(F, names) == 1              # the fit's compromise among the strictly stable points
    assert list(knee_order(F, names)) == [1, 2, 3, 0]
    assert knee_index(F[:, :2], names[:2]) == 0   # without the stabilising objective: plain knee


def test_statespace_export_roundtrip_and_balanced_truncation_bound(tmp_path):
    from identification.export_statespace import balanced_truncation, load_statespace, save_statespace

    cfg = make_config(nodes=20, c=2.0, dt=1e-3)
    sys = em.assemble(cfg)
    cs = load_statespace(save_statespace(sys, tmp_path / "m.npz"))
    assert cs.dt == sys.dt and list(cs.input_labels) == ["F1"] and list(cs.output_labels) == ["y1", "y2"]
    np.testing.assert_array_equal(cs.A, sys.A)
    bm = balanced_truncation(sys, 8)
    f = np.linspace(0.0, 0.5 / sys.dt, 2001)
    err = np.abs(em.frequency_response(sys, f).H - em.frequency_response(bm.system, f).H).max()
    assert err <= bm.error_bound
    assert np.all(np.diff(bm.hankel_singular_values) <= 1e-15)
    with pytest.raises(em.StabilityError, match="asymptotically stable"):
        balanced_truncation(em.assemble(make_config(nodes=10)), 4)


def test_polish_converges_from_a_nearby_start():
    from identification.polish import polish

    cfg = seed_like(c=0.4)
    u, y = synthetic(cfg, n=800, noise=0.0)
    sp = parameter_space(cfg)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    res = polish(ev, np.array([11.0, 45.0]))
    np.testing.assert_allclose(res.x, sp.nominal, rtol=1e-6)
    assert 0 < res.n_evaluations <= 400 and res.cost < 1e-12


def test_predicted_chi2_decrease_is_the_exact_drop_of_a_linear_fit():
    """For a linear model the Gauss-Newton prediction is exact: compare with the fitted χ² drop."""
    from identification.least_squares import predicted_chi2_decrease

    rng = np.random.default_rng(3)
    J = rng.normal(size=(200, 3))
    r = rng.normal(size=200)
    s = np.full(3, 0.5)
    beta, *_ = np.linalg.lstsq(J, -r, rcond=None)
    drop = r @ r - (r + J @ beta) @ (r + J @ beta)
    var = (r @ r) / (200 - 3)
    assert predicted_chi2_decrease(J, r, s) == pytest.approx(drop / var, rel=1e-12)
    # an unknown on its bound that the gradient pushes outwards is held; the drop is that of the others
    g = J.T @ r
    s_held = s.copy()
    s_held[0] = 0.0 if g[0] > 0 else 1.0
    beta2, *_ = np.linalg.lstsq(J[:, 1:], -r, rcond=None)
    drop2 = r @ r - (r + J[:, 1:] @ beta2) @ (r + J[:, 1:] @ beta2)
    assert predicted_chi2_decrease(J, r, s_held) == pytest.approx(drop2 / var, rel=1e-12)
    assert predicted_chi2_decrease(J, np.zeros(200), s) == 0.0


def test_polish_stops_once_the_data_cannot_tell_the_remaining_step_apart():
    """On noisy data the polish ends within the stated χ² resolution of the optimum, not at round-off."""
    from identification.polish import CHI2_RESOLUTION, ResidualEvaluator, polish

    cfg = seed_like(c=0.4)
    u, y = synthetic(cfg, n=800, noise=0.0)
    y = y + np.random.default_rng(5).normal(scale=0.02 * np.std(y, axis=0), size=y.shape)
    sp = parameter_space(cfg)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    res = polish(ev, np.array([11.0, 45.0]))
    full = polish(ev, np.array([11.0, 45.0]), chi2_resolution=0.0)  # on to least_squares' round-off tests
    assert res.success and res.message.startswith("converged")
    assert not full.message.startswith("converged")
    r = ResidualEvaluator(ev).residuals(res.x)
    var = (r @ r) / (r.size - sp.dim)
    chi2_left = (res.cost - full.cost) / var  # what the early stop left on the table, in χ² units
    print(f"\nstop after {res.n_evaluations} evaluations (vs {full.n_evaluations}); chi2 left {chi2_left:.2e}")
    assert -1e-9 <= chi2_left < CHI2_RESOLUTION
    assert res.n_evaluations < full.n_evaluations


def test_a_buckled_guess_is_checked_with_its_load_relaxed():
    """A newcomer's guesses of EI and a compressive N can be a buckled beam (clamped–clamped, EI 10: buckling at
    4π² EI/L² ≈ 395 N; the guess N −480): the identifiability check before the search is made with the load
    relaxed towards zero inside its bounds and says so, where it ended in a ``StabilityError`` before any search."""
    from ebb_model.errors import StabilityError
    from identification.fisher import nominal_fisher

    truth = make_config(nodes=20, N=-200.0, c=0.5)
    d = truth.to_dict()
    d["parameters"]["EI"].update(bounds=[5.0, 20.0], identify=True)
    d["parameters"]["N"].update(value=-480.0, bounds=[-600.0, 100.0], identify=True)
    cfg = em.config_from_dict(d, extra_sections=("identification",))
    sp = parameter_space(cfg)
    u, y = synthetic(truth)
    ev = NativeEvaluator(cfg, sp, experiments_from_arrays([("e", u, y)]))
    assert not ev.simulate(np.asarray(sp.nominal)).stable          # the guess is buckled
    with pytest.raises(StabilityError):
        fisher_information(ev, sp.nominal)
    rep = nominal_fisher(ev)
    j = sp.names.index("N")
    assert rep.point[j] == pytest.approx(-240.0) and rep.point[0] == sp.nominal[0]
    assert not rep.singular and "N -480 buckles the nominal beam" in rep.messages[0], rep.messages
