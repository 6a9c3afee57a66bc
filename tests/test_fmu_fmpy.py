"""The beam FMU through fmpy: equivalence with ebb_model.simulate, semantics, errors.

Reference: ``ebb_model.simulate`` of the same config — the same model through
another adapter, not independent physics (the model itself is checked against
independent truth in ``test_exact_scheme.py`` and ``test_accuracy.py``).  The
FMU is a thin adapter, so it must reproduce the core to rounding; for the field
outputs the core's ``field_matrix`` applied to a plain state recursion.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import pythonfmu  # noqa: F401 - a dependency: a broken install must fail, not skip
import fmpy  # noqa: F401
from fmpy import extract, read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import (FMU2Slave, defaultCallbacks, fmi2CallbackFunctions,  # noqa: E402
                       fmi2CallbackLoggerTYPE)

sys.path.insert(0, str(Path(__file__).resolve().parent / "fmu_hosts"))
from fmu_configs import SEED_TOML, mixed_config, substep_config  # noqa: E402
from fmu_loops import fmpy_outputs  # noqa: E402

from ebb_model import assemble, config_from_dict, field_matrix, load_config, simulate  # noqa: E402
from ebb_model.assemble import field_config  # noqa: E402
from fmu_build import build_fmu  # noqa: E402

from conftest import foh_reference  # noqa: E402

RTOL = 1e-10


def _rel_err(y: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Largest error of each column relative to the column's largest magnitude."""
    return np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmus")
    cfgs = {"seed": load_config(SEED_TOML), "mixed": config_from_dict(mixed_config()),
            "substep": config_from_dict(substep_config())}
    fmus = {name: build_fmu(cfg, d / f"{name}.fmu") for name, cfg in cfgs.items()}
    fmus["seed_field"] = build_fmu(cfgs["seed"], d / "seed_field.fmu", field=True)
    return cfgs, fmus


class Instance:
    """One fmpy FMU2Slave instance that records the FMU's log messages; freed by close()."""

    def __init__(self, fmu: Path):
        self.unzipdir = extract(str(fmu))
        self.md = read_model_description(self.unzipdir)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dt = float(self.md.defaultExperiment.stepSize)
        self.messages: list[tuple[int, str]] = []

        def log(env, name, status, category, message):
            self.messages.append((status, message.decode()))

        self._logger = fmi2CallbackLoggerTYPE(log)
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = self._logger
        callbacks.allocateMemory = defaultCallbacks.allocateMemory
        callbacks.freeMemory = defaultCallbacks.freeMemory
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="test")
        self.fmu.instantiate(callbacks=callbacks)

    def init(self, **params: float) -> None:
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in params.items():
            self.fmu.setReal([self.vr[name]], [value])
        self.fmu.exitInitializationMode()

    def set(self, **values: float) -> None:
        self.fmu.setReal([self.vr[n] for n in values], list(values.values()))

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[n] for n in names])

    def close(self) -> None:
        self.fmu.freeInstance()


@pytest.fixture
def instance(built):
    made: list[Instance] = []

    def make(name: str) -> Instance:
        made.append(Instance(built[1][name]))
        return made[-1]

    yield make
    for inst in made:
        inst.close()


@pytest.mark.parametrize("name", ["seed", "mixed", "substep"])
def test_outputs_equal_core_simulation(built, name):
    cfgs, fmus = built
    cfg = cfgs[name]
    u = np.random.default_rng(7).standard_normal((1500, len(cfg.actuators)))
    y = fmpy_outputs(fmus[name], u)
    ref = simulate(assemble(cfg), u).outputs
    err = _rel_err(y, ref)
    kinds = [s.kind for s in cfg.sensors]
    assert np.all(err < RTOL), dict(zip(kinds, err))


def test_all_sensor_kinds_are_covered(built):
    kinds = {s.kind for cfg in built[0].values() for s in cfg.sensors}
    assert kinds == {"displacement", "velocity", "acceleration"}


def test_field_outputs_are_the_core_field_matrix(built, tmp_path):
    """θ-scheme: the field is P q of the scheme's physical nodal state (its non-causal reference recursion)."""
    cfgs, fmus = built
    d = cfgs["seed"].to_dict()
    d["time"]["scheme"] = "theta"
    cfg = config_from_dict(d)
    fmus = {"seed_field": build_fmu(cfg, tmp_path / "seed_theta_field.fmu", field=True)}
    xs, Cf = field_matrix(cfg)
    u = np.random.default_rng(3).standard_normal((400, 1))
    names = [f"w[{i}]" for i in range(len(xs))]
    y = fmpy_outputs(fmus["seed_field"], u, outputs=names + ["y1"])
    sys_ = assemble(cfg)
    _, ref = foh_reference(cfg, u)  # P q of the physical state (non-causal first-order-hold recursion)
    assert np.max(np.abs(y[:, :-1] - ref)) <= RTOL * np.max(np.abs(ref))
    assert np.all(y[:, 0] == 0.0) and np.all(y[:, len(xs) - 1] == 0.0)  # clamped ends do not move
    assert np.max(np.abs(y[:, -1] - simulate(sys_, u).outputs[:, 0])) <= RTOL * np.max(np.abs(y[:, -1]))


def rest_feedthrough(cfg) -> np.ndarray:
    """Feedthrough of the first sample from rest: ``D − C Γ₁`` (the first-order hold starts at ``ξ₀ = −Γ₁ u₀``)."""
    sys_ = assemble(cfg)
    return sys_.D - sys_.C @ sys_.hold if sys_.hold is not None else sys_.D


def test_field_outputs_of_the_default_scheme_equal_the_core(built):
    cfg = built[0]["seed"]
    u = np.random.default_rng(3).standard_normal((400, 1))
    xs, _ = field_matrix(cfg)
    y = fmpy_outputs(built[1]["seed_field"], u, outputs=[f"w[{i}]" for i in range(len(xs))])
    ref = simulate(assemble(field_config(cfg)), u).outputs[:, len(cfg.sensors):]
    assert np.max(np.abs(y - ref)) <= RTOL * np.max(np.abs(ref))
    assert np.all(y[:, 0] == 0.0) and np.all(y[:, -1] == 0.0)  # clamped ends do not move


def test_input_shows_at_once_in_feedthrough_outputs(built, instance):
    cfg = built[0]["mixed"]
    D = rest_feedthrough(cfg)
    inst = instance("mixed")
    inst.init()
    assert inst.get("d1", "v1", "a1") == [0.0, 0.0, 0.0]
    inst.set(F1=2.0, F2=-1.0)
    y = np.array(inst.get("d1", "v1", "a1"))
    # exact scheme: from rest only the acceleration responds at once (F/m through the modes); displacement and
    # velocity stay zero (to the round-off of the causal hold's ±Γ₁u, ~1e-20 here)
    np.testing.assert_allclose(y[2], D[2] @ [2.0, -1.0], rtol=1e-13, atol=0)
    assert y[2] != 0.0 and np.all(np.abs(y[:2]) <= 1e-15 * abs(y[2]))


def test_step_of_several_samples_holds_the_input(built, instance):
    a, b = instance("mixed"), instance("mixed")
    a.init()
    b.init()
    for inst in (a, b):
        inst.set(F1=1.5, F2=0.25)
    a.fmu.doStep(0.0, 3 * a.dt)
    for k in range(3):
        b.fmu.doStep(k * b.dt, b.dt)
    np.testing.assert_allclose(a.get("d1", "v1", "a1"), b.get("d1", "v1", "a1"), rtol=1e-13, atol=0)


def test_reset_then_new_parameters_give_the_new_model(built, instance):
    cfg = built[0]["seed"]
    new = {"EI": 20.0, "N": 0.0, "c": 0.1}
    u = np.random.default_rng(5).standard_normal((300, 1))
    inst = instance("seed")
    outputs = {}
    for label, params in (("nominal", {}), ("new", new), ("nominal again", {})):
        inst.init(**params)
        y = np.empty((len(u), 2))
        for k in range(len(u)):
            inst.set(F1=float(u[k, 0]))
            y[k] = inst.get("y1", "y2")
            inst.fmu.doStep(k * inst.dt, inst.dt)
        outputs[label] = y
        inst.fmu.reset()
    ref_new = simulate(assemble(cfg, new), u).outputs
    ref_nominal = simulate(assemble(cfg), u).outputs
    assert np.all(_rel_err(outputs["new"], ref_new) < RTOL)
    assert np.all(_rel_err(outputs["nominal"], ref_nominal) < RTOL)
    assert np.all(_rel_err(outputs["nominal again"], ref_nominal) < RTOL)
    assert np.all(_rel_err(ref_new, ref_nominal) > 1e-2)


def test_rotary_inertia_and_foundation_are_tunable(built, instance):
    """rhoI and kf set at initialisation give the core's model with them (non-proportional damping)."""
    cfg = built[0]["mixed"]
    params = {"rhoI": 2e-3, "kf": 400.0}
    u = np.random.default_rng(9).standard_normal((300, 2))
    inst = instance("mixed")
    inst.init(**params)
    y = np.empty((len(u), 3))
    for k in range(len(u)):
        inst.set(F1=float(u[k, 0]), F2=float(u[k, 1]))
        y[k] = inst.get("d1", "v1", "a1")
        inst.fmu.doStep(k * inst.dt, inst.dt)
    ref = simulate(assemble(cfg, params), u).outputs
    assert np.all(_rel_err(y, ref) < RTOL)
    assert np.all(_rel_err(simulate(assemble(cfg), u).outputs, ref) > 1e-2)


def test_parameters_set_before_initialisation_are_used(built, instance):
    cfg = built[0]["mixed"]
    inst = instance("mixed")
    inst.fmu.setupExperiment(startTime=0.0)
    inst.set(rhoA=2.5)  # instantiated state, before enterInitializationMode
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    inst.set(F1=1.0, F2=0.0)
    np.testing.assert_allclose(inst.get("a1"), rest_feedthrough(cfg.with_parameters(rhoA=2.5))[2, 0], rtol=1e-13)


@pytest.mark.parametrize("step", [1.5, 0.5, 0.0, -1.0, math.nan, math.inf])
def test_bad_step_size_is_an_error_not_a_crash(instance, step):
    inst = instance("seed")
    inst.init()
    with pytest.raises(FMICallException) as exc:
        inst.fmu.doStep(0.0, step * inst.dt)
    assert exc.value.status == 3  # fmi2Error, never fmi2Fatal
    assert any(s == 3 and "multiple of the sample time" in m for s, m in inst.messages)
    inst.fmu.reset()
    inst.init()
    assert inst.fmu.doStep(0.0, inst.dt) is None


@pytest.mark.parametrize("name, value, message", [
    ("EI", -1.0, "EI"), ("EI", 0.0, "EI"), ("rhoA", 0.0, "rhoA"), ("EI", math.nan, "EI"),
    ("c", -1.0, "c"), ("N", -1e6, "N"), ("rhoI", -1e-3, "rhoI"), ("kf", -1.0, "kf"),
])
def test_bad_parameters_fail_at_exit_initialisation(instance, name, value, message):
    inst = instance("seed")
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.set(**{name: value})
    with pytest.raises(FMICallException) as exc:
        inst.fmu.exitInitializationMode()
    assert exc.value.status == 3
    errors = [m for s, m in inst.messages if s == 3]
    assert errors and errors[0].startswith("fmi2ExitInitializationMode") and message in errors[0]
    with pytest.raises(FMICallException) as exc:
        inst.fmu.doStep(0.0, inst.dt)
    assert exc.value.status == 3
    inst.fmu.reset()  # and the instance is usable again
    inst.init()
    inst.fmu.doStep(0.0, inst.dt)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_input_is_an_error(instance, value):
    inst = instance("seed")
    inst.init()
    with pytest.raises(FMICallException) as exc:
        inst.set(F1=value)
    assert exc.value.status == 3
    assert any("F1" in m and "finite" in m for s, m in inst.messages if s == 3)
    assert inst.get("y1") == [0.0]


def test_misuse_is_an_error_not_fatal(instance):
    inst = instance("seed")
    inst.init()
    for call in (lambda: inst.set(y1=1.0), lambda: inst.set(**{"beam.length": 2.0}),
                 lambda: inst.fmu.setReal([10_000], [1.0]), lambda: inst.fmu.getReal([10_000]),
                 lambda: inst.fmu.getReal([inst.vr["beam.nodes"]]),
                 lambda: inst.fmu.setInteger([inst.vr["beam.nodes"]], [3])):
        with pytest.raises(FMICallException) as exc:
            call()
        assert exc.value.status == 3
    assert inst.fmu.getInteger([inst.vr["beam.nodes"]]) == [50]
    assert inst.fmu.getString([inst.vr["beam.left"]]) == [b"clamped"]
    assert inst.get("beam.length", "time.dt") == [1.0, 1e-4]


def test_wrong_guid_is_refused(built):
    md = read_model_description(str(built[1]["seed"]))
    unzipdir = extract(str(built[1]["seed"]))
    fmu = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=unzipdir,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="wrong")
    with pytest.raises(Exception, match="instantiate"):
        fmu.instantiate()
    fmu.freeLibrary()


def test_simulate_fmu_high_level(built):
    cfg = built[0]["seed"]
    dt = cfg.time.dt
    n = 500
    u = np.random.default_rng(11).standard_normal(n)
    signal = np.zeros(n, dtype=[("time", float), ("F1", float)])
    signal["time"] = np.arange(n) * dt
    signal["F1"] = u
    res = simulate_fmu(str(built[1]["seed"]), start_time=0.0, stop_time=(n - 1) * dt, output_interval=dt,
                       input=signal, output=["y1", "y2"])
    sys_ = assemble(cfg)
    ref = simulate(sys_, u[:, None]).outputs
    # simulate_fmu records the outputs after each doStep, before the next input is set: y_k sees u_{k-1}
    # through the feedthrough (the first-order hold gives displacements one too)
    ref[1:] -= np.outer(u[1:] - u[:-1], sys_.D[:, 0])
    y = np.column_stack([res["y1"], res["y2"]])
    assert len(y) == n
    assert np.all(_rel_err(y, ref) < RTOL)
