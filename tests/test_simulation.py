"""Simulation: fast path vs scipy.signal.dlsim, batch, physics properties of the responses."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.signal as ss

from ebb_model import (
    ConfigError,
    DataError,
    DiscreteStateSpace,
    assemble,
    fast_model,
    frequency_response,
    simulate,
    simulate_batch,
    simulate_config,
)
from ebb_model.config import config_from_dict, load_config
from ebb_model.space.discretisation import discretise
from ebb_model.theta.modal_form import modal_from_statespace

from conftest import foh_reference, make_config

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

KIND_SETS = [("displacement", "displacement"), ("velocity", "acceleration"), ("acceleration", "displacement")]

SYSTEMS = [
    dict(left="clamped", right="clamped"),                              # the seed, undamped
    dict(left="clamped", right="free", c=0.3, substeps=3),               # viscous, sub-steps
    dict(left="pinned", right="clamped", N=50.0, eta=1e-4),              # non-proportional
    dict(left="elastic", right="free", left_springs=(5e3, 80.0), eta=2e-5, c=0.1,
         masses=[("m", 0.9, 0.05)]),
    dict(left="clamped", right="pinned", N=-30.0, theta=0.3),
]


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("kinds", KIND_SETS, ids=["disp", "vel-acc", "acc-disp"])
@pytest.mark.parametrize("spec", SYSTEMS, ids=["seed", "cantilever-substeps", "nonprop", "elastic-mass", "compr"])
def test_fast_path_equals_dlsim(spec, kinds):
    cfg = make_config(nodes=30, sensors=[("y1", 0.5, kinds[0]), ("y2", 0.83, kinds[1])],
                      actuators=[("F1", 0.31), ("F2", 0.77)], **spec)
    sys = assemble(cfg)
    u = np.random.default_rng(1).standard_normal((3000, 2))
    # at rest: ξ[0] = −Γ₁ u[0] in the first-order-hold realisation (sub-steps)
    x0 = -(sys.hold @ u[0]) if sys.hold is not None else None
    _, y_ref, _ = ss.dlsim((sys.A, sys.B, sys.C, sys.D, sys.dt), u, x0=x0)
    y_fast = simulate(fast_model(cfg), u).outputs
    y_dense = simulate(sys, u).outputs
    # Error budget of the modal route: it is the same scheme in other coordinates, so the two differ by
    # round-off in the lowest modes, whose eigenvalues carry a relative error of order eps·κ in either
    # float64 route, κ = ω²_max/ω²_min (absolute error eps·‖K‖ against the smallest ω²).  Displacement outputs,
    # dominated by those modes, differ by (0.1–0.7)·eps·κ in every case here (measured with numpy 2.4 / scipy 1.17:
    # 1.3e-10 for the elastic end with a point mass, κ = 1.9e6); other outputs by < 2e-12.
    beam = discretise(cfg, cfg.parameter_values())
    w2 = sla.eigvalsh(beam.K, beam.M)
    budget = 2 * np.finfo(float).eps * w2.max() / w2.min()
    assert rel(y_fast, y_ref) < max(budget, 1e-11)
    # the dense kernel iterates the very matrices dlsim does: summation order only (measured < 1e-12)
    assert rel(y_dense, y_ref) < 1e-11


def test_general_modal_route_equals_dense():
    """The eigen-decomposition route of a general (θ-scheme, non-proportionally damped) dense system."""
    cfg = make_config(N=80.0, eta=1e-4, nodes=25, sensors=[("a", 0.4, "acceleration")], scheme="theta")
    sys = assemble(cfg)
    u = np.random.default_rng(2).standard_normal((2000, 1))
    y1 = simulate(modal_from_statespace(sys), u).outputs
    y2 = simulate(sys, u).outputs
    assert rel(y1, y2) < 1e-10


def test_batch_equals_individual_runs():
    cfg = make_config(right="free", c=0.2, nodes=20)
    u = np.random.default_rng(3).standard_normal((1500, 1))
    P = np.array([[10.0, 0.0], [12.0, 5.0], [8.0, -3.0]])
    Y = simulate_batch(cfg, P, u, names=["EI", "N"])
    for row, y in zip(P, Y):
        ref = simulate_config(cfg, u, {"EI": row[0], "N": row[1]}).outputs
        np.testing.assert_array_equal(y, ref)


def test_static_tip_deflection_of_cantilever():
    """A step force at the tip of a damped cantilever settles at P L³ / (3 EI) (beam theory)."""
    EI, L, P = 10.0, 1.0, 2.0
    cfg = make_config("clamped", "free", nodes=80, EI=EI, c=8.0, dt=2e-4, actuators=[("F", L)],
                      sensors=[("tip", L, "displacement"), ("mid", 0.5, "displacement")])
    y = simulate_config(cfg, np.full((60000, 1), P)).outputs
    tip, mid = y[-1]
    assert tip == pytest.approx(P * L ** 3 / (3 * EI), rel=2e-3)
    x = 0.5  # w(x) = P x² (3L - x) / (6 EI)
    assert mid == pytest.approx(P * x ** 2 * (3 * L - x) / (6 * EI), rel=2e-3)


def test_reciprocity_of_collocated_pairs():
    """Maxwell–Betti: the response at b to a force at a equals the response at a to a force at b."""
    a, b = 0.23, 0.68
    kw = dict(left="elastic", right="free", left_springs=(4e3, 60.0), c=0.2, nodes=40)
    c1 = make_config(actuators=[("F", a)], sensors=[("y", b, "displacement")], **kw)
    c2 = make_config(actuators=[("F", b)], sensors=[("y", a, "displacement")], **kw)
    u = np.random.default_rng(4).standard_normal((3000, 1))
    y1 = simulate_config(c1, u).outputs
    y2 = simulate_config(c2, u).outputs
    assert rel(y1, y2) < 1e-10


def test_frequency_response_matches_steady_state_simulation():
    cfg = make_config(c=6.0, nodes=30, sensors=[("y", 0.5, "displacement")])
    fm = fast_model(cfg)
    f0 = 47.0
    n = 40000
    t = np.arange(n) * cfg.time.dt
    u = np.cos(2 * np.pi * f0 * t)[:, None]
    y = simulate(fm, u).outputs[:, 0]
    H = frequency_response(fm, [f0]).H[0, 0, 0]
    H_dense = frequency_response(assemble(cfg), [f0]).H[0, 0, 0]
    assert abs(H - H_dense) < 1e-9 * abs(H)
    tail = slice(n - 10000, n)  # transients decayed: envelope exp(-c t / 2 rhoA) = exp(-9) at 3 s
    y_ss = np.real(H * np.exp(2j * np.pi * f0 * t[tail]))
    assert rel(y[tail], y_ss) < 1e-3


def test_the_dense_frequency_response_is_the_solve_at_every_frequency():
    """A dense model's response (Hessenberg form once, then O(n²) per frequency) against a plain dense solve per
    frequency — a random non-normal system with three inputs and two outputs, whose elimination must exchange rows
    — and, on the lightly damped 400-state seed model, against its modal form (2×2 blocks: another route)."""
    rng = np.random.default_rng(5)
    n = 40
    dense = 0.9 * rng.standard_normal((n, n)) / np.sqrt(n)      # spectral radius 0.93: well conditioned
    # already Hessenberg with a unit diagonal: at f = 0 (z = 1) the elimination without row exchanges divides by 0
    hessenberg = np.triu(rng.standard_normal((n, n)), -1)
    np.fill_diagonal(hessenberg, 1.0)
    for A in (dense, hessenberg):
        system = DiscreteStateSpace(A, rng.standard_normal((n, 3)), rng.standard_normal((2, n)),
                                    rng.standard_normal((2, 3)), 1e-3, ("a", "b", "c"), ("y", "z"))
        f = np.linspace(0.0, 500.0, 37)
        H = frequency_response(system, f).H
        ref = np.array([system.C @ np.linalg.solve(zi * np.eye(n) - A, system.B) + system.D
                        for zi in np.exp(2j * np.pi * f * 1e-3)])
        assert np.max(np.abs(H - ref)) < 1e-12 * np.max(np.abs(ref))   # measured 1.8e-15, 1.6e-15
    # a frequency at a pole (z = 1 is an eigenvalue): the singular system is an error, as a dense solve's
    at_pole = DiscreteStateSpace(np.diag([1.0, 0.5]), np.ones((2, 1)), np.ones((1, 2)), np.zeros((1, 1)), 1e-3)
    with pytest.raises(np.linalg.LinAlgError, match="pole"):
        frequency_response(at_pole, [0.0])
    cfg = load_config(EXAMPLES / "seed_two_sensors.toml")      # 200 nodes, θ-scheme, ζ ≈ 0.1 %
    f = np.linspace(1.0, 2000.0, 60)
    dense, modal = frequency_response(assemble(cfg), f).H, frequency_response(fast_model(cfg), f).H
    # both carry round-off amplified by the resonances' conditioning: measured 6.5e-8 of the peak (a dense
    # solve per frequency: 3.2e-7)
    assert np.max(np.abs(dense - modal)) < 1e-6 * np.max(np.abs(modal))


def test_natural_frequency_in_free_vibration():
    """The free-vibration spectrum peaks at the analytic first mode (clamped–clamped, U = 0)."""
    cfg = make_config(nodes=60, dt=2e-4, sensors=[("y", 0.5, "displacement")])
    u = np.zeros((2 ** 16, 1))
    u[0] = 1.0
    y = simulate_config(cfg, u).outputs[:, 0]
    spec = np.abs(np.fft.rfft(y * np.hanning(y.size)))
    f = np.fft.rfftfreq(y.size, cfg.time.dt)
    f1 = 22.3733 / (2 * math.pi) * math.sqrt(10.0)
    peak = f[np.argmax(spec)]
    assert peak == pytest.approx(f1, abs=2 * (f[1] - f[0]) + 2e-3 * f1)


def test_bad_inputs_to_simulate():
    cfg = make_config()
    fm = fast_model(cfg)
    with pytest.raises(DataError, match="non-finite"):
        simulate(fm, np.array([[0.0], [np.nan]]))
    with pytest.raises(DataError, match="shape"):
        simulate(fm, np.zeros((10, 3)))


@pytest.mark.parametrize("spec", [dict(right="free", c=0.3, substeps=4), dict(N=60.0, eta=1e-4)],
                         ids=["proportional", "general"])
def test_modal_realisation_equals_nodal_including_field(spec):
    from ebb_model import assemble_modal

    # the θ-scheme: the nodal realisation and its non-causal reference recursion are that scheme's
    cfg = make_config(nodes=24, sensors=[("a", 0.8, "acceleration"), ("v", 0.4, "velocity")], scheme="theta",
                      **spec)
    u = np.random.default_rng(6).standard_normal((2000, 1))
    nodal = assemble(cfg)
    modal = assemble_modal(cfg, field=True)
    assert modal.output_names[:2] == ("a", "v") and modal.output_names[2] == "w[0]"
    y_modal = simulate(modal, u).outputs
    y_nodal = simulate(nodal, u).outputs
    # the physical state (q, v) by the non-causal first-order-hold recursion: the field is P q
    y_ref, w_ref = foh_reference(cfg, u)
    assert rel(y_modal[:, :2], y_nodal) < 1e-9
    assert rel(y_nodal, y_ref) < 1e-9
    assert rel(y_modal[:, 2:], w_ref) < 1e-9


def test_input_hold_option():
    """``time.input = "zoh"`` holds the sample over the sub-steps; "foh" (default) draws the straight line.

    A constant force is the same under both holds (equal outputs), a varying one
    is not; the zero-order-hold system has no hold matrix and equals the
    sub-stepped recursion with the sample held.
    """
    d = make_config(right="free", c=0.3, substeps=4, nodes=20, scheme="theta").to_dict()
    foh = config_from_dict(d)
    d["time"]["input"] = "zoh"
    zoh = config_from_dict(d)
    assert foh.time.input_hold == "foh" and zoh.time.input_hold == "zoh"
    assert assemble(zoh).hold is None and assemble(foh).hold is not None
    const = np.ones((500, 1))
    assert rel(simulate(fast_model(foh), const).outputs, simulate(fast_model(zoh), const).outputs) < 1e-10
    u = np.random.default_rng(4).standard_normal((500, 1))
    assert rel(simulate(fast_model(foh), u).outputs, simulate(fast_model(zoh), u).outputs) > 1e-3
    d["time"]["input"] = "cubic"
    with pytest.raises(ConfigError, match='time.input: "cubic" needs scheme = "exact"'):
        config_from_dict(d)


@pytest.mark.parametrize("n_inputs", [1, 2, 3])
def test_the_modal_kernel_reads_the_cubics_past_samples_as_the_dense_delay_states_do(n_inputs):
    """The cubic input reads ``u[k−2] … u[k+1]``; the modal kernel gathers the past samples from ``u`` itself
    (``u[−j] = u[0]`` before the record), the dense exact system keeps them as delay states.  Both from rest,
    on records of 1, 2, 3 and 600 samples (the start is where the two differ if the gathering is wrong).

    Budget: the two realisations' round-off over the recursion (the modal basis' ``eps · cond(V)`` and the
    matrix exponential's, summed over 600 samples): measured <= 1.3e-13 of the outputs' peak, 1e-12 allowed.
    Reading ``u[−j]`` as zero instead moves the outputs by 6e-7 to 2e-2 of their peak (measured): the check fails."""
    from ebb_model.exact.exact_modal import exact_modal, exact_statespace

    actuators = [(f"F{i + 1}", x) for i, x in enumerate((0.3, 0.55, 0.8)[:n_inputs])]
    cfg = make_config("clamped", "pinned", nodes=25, dt=5e-4, EI=10.0, rhoA=1.0, c=2.0, N=10.0, actuators=actuators,
                      sensors=[("y1", 0.5, "displacement"), ("v1", 0.77, "velocity"), ("a1", 0.6, "acceleration")])
    assert cfg.time.input_hold == "cubic"
    p = cfg.parameter_values()
    modal, dense = exact_modal(cfg, p), exact_statespace(cfg, p)
    assert modal.delays == 2
    u = np.random.default_rng(n_inputs).standard_normal((600, n_inputs))
    scale = np.abs(simulate(dense, u).outputs).max(axis=0)     # (the first samples' outputs are near zero)
    for n in (1, 2, 3, 600):
        y_modal, y_dense = simulate(modal, u[:n]).outputs, simulate(dense, u[:n]).outputs
        err = np.abs(y_modal - y_dense).max(axis=0) / scale
        assert np.all(err < 1e-12), (n, err)
