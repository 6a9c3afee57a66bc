"""The FMU backend (fmpy) gives the native backend's objective values to 1e-9 relative."""
from __future__ import annotations

import numpy as np

import ebb_model as em
from fmu_build import build_fmu
from identification.native import experiments_from_arrays
from identification.fmu_backend import FmuEvaluator
from identification.native import NativeEvaluator
from identification.parameters import parameter_space

from conftest import make_identification_config


def test_fmu_and_native_objectives_agree(tmp_path):
    cfg = make_identification_config(nodes=16, c=0.3, N=40.0, sensors=[("y1", 0.5, "displacement"),
                                                                      ("a2", 0.8, "acceleration")])
    rng = np.random.default_rng(2)
    u = rng.standard_normal((400, 1))
    y = em.simulate_config(cfg, u).outputs
    y += 0.01 * y.std(0) * rng.standard_normal(y.shape)
    exps = experiments_from_arrays([("e", u, y)])
    space = parameter_space(cfg)
    fmu = build_fmu(cfg, tmp_path / "beam.fmu")
    native = NativeEvaluator(cfg, space, exps)
    fe = FmuEvaluator(str(fmu), cfg, space, exps)
    try:
        X = np.array([[10.0, 40.0], [12.5, 3.0], [7.0, 90.0]])
        F_native = native.evaluate(X)
        F_fmu = fe.evaluate(X)
        np.testing.assert_allclose(F_fmu, F_native, rtol=1e-9, atol=0)
        # invalid (EI = 0) and buckled (U = -40 < -4 pi^2) candidates: finite penalties on both backends,
        # the same stabilising objective
        Xbad = np.array([[0.0, 40.0], [10.0, -400.0]])
        bad_fmu, bad_native = fe.evaluate(Xbad), native.evaluate(Xbad)
        assert np.all(np.isfinite(bad_fmu)) and np.all(bad_fmu[:, :2] > 1e3) and np.all(bad_native[:, :2] > 1e3)
        np.testing.assert_array_equal(bad_fmu[:, 2], bad_native[:, 2])
        # and the reused instance still gives the right answer afterwards
        np.testing.assert_allclose(fe.evaluate(X[:1]), F_native[:1], rtol=1e-9, atol=0)
    finally:
        fe.close()
