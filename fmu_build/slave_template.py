"""The beam as a pythonfmu co-simulation slave: a thin adapter over ``ebb_model``.

The slave holds no physics.  At the end of initialisation it asks the core
for the discrete system of the current parameter values,

.. math::

    x_{k+1} = A x_k + B u_k, \\qquad y_k = C x_k + D u_k, \\qquad t_k = t_0 + k\\,dt,

(``ebb_model.assemble``; with ``field=True`` of ``ebb_model.field_config``,
which appends displacement outputs at every grid node) and then
only iterates it.  Co-simulation semantics, zero-order hold:

* at ``t_k`` the master sets ``u_k``; ``fmi2GetReal`` returns
  ``y_k = C x_k + D u_k`` -- an input just set shows at once in velocity and
  acceleration sensors (direct feedthrough, declared in ModelStructure);
* ``fmi2DoStep(t_k, h)`` with ``h = n dt`` (``n`` a positive integer) applies
  the recursion ``n`` times with ``u`` held; any other ``h`` is refused.

Errors never escape as Python exceptions, which pythonfmu would report as
``fmi2Fatal``: they are logged with status ``fmi2Error`` and the FMU's C
loader returns ``fmi2Error`` for that call (see ``loader.c``).

This module is a template.  :func:`fmu_build.builder.build_fmu` copies it into
the FMU's resources as ``<modelIdentifier>_slave.py`` with the class renamed
and :data:`CORE_PACKAGE` pointing at the FMU's private copy of ``ebb_model``,
so that FMUs built from different configs can run side by side in one
process (pythonfmu imports the slave module by name and Python caches it).

The per-step path is kept lean (see :class:`_StepPlan`): everything is
precomputed at assembly, a step is one matrix-vector product into a
preallocated buffer (which also yields ``C x`` of the new state) and one
copy, and outputs are converted to Python floats only when read after a
change.
"""
from __future__ import annotations

import importlib
import importlib.util
import json
import math
import operator
import os
import sys
from typing import Any, Sequence, cast

#: What the FMU's Python must provide (the bundled core imports them); the model description says so too.
REQUIRED_PACKAGES = ("numpy", "scipy", "numba")

#: JSON file in the FMU's resources describing the model (written by the builder).
SPEC_FILE = "ebb_fmu.json"


def _check_requirements() -> None:
    """Name every missing package and the interpreter the FMU was built with, instead of a bare import error."""
    missing = [p for p in REQUIRED_PACKAGES if importlib.util.find_spec(p) is None]
    if not missing:
        return
    built_with = "unknown"
    spec_file = os.path.join(os.path.dirname(os.path.abspath(__file__)), SPEC_FILE)
    try:
        with open(spec_file, encoding="utf-8") as fh:
            built_with = json.load(fh).get("build_python", built_with)
    except (OSError, ValueError):
        pass
    raise ImportError(f"this FMU needs Python with {', '.join(REQUIRED_PACKAGES)}; the Python running it "
                      f"({sys.executable}) lacks {', '.join(missing)}. It was built with {built_with}")


_check_requirements()

import numpy as np  # noqa: E402 - after the requirement check
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String  # noqa: E402
from pythonfmu.enums import Fmi2Status  # noqa: E402

__all__ = ["BeamSlave", "CORE_PACKAGE", "CORE_MODULES", "SPEC_FILE", "STEP_TOLERANCE", "FIELD_NAME",
           "REQUIRED_PACKAGES"]

#: Package that provides ``config_from_dict``, ``causal_config``, ``assemble_modal`` and ``field_matrix``.
#: The builder rewrites this line to the FMU's bundled copy.
CORE_PACKAGE = "ebb_model"

#: The core's modules the slave imports (``""``: the package itself); the FMU bundles them and what they import.
CORE_MODULES = ("", ".beam")

#: A step ``h`` is accepted when ``|h/dt - n| <= STEP_TOLERANCE`` for an integer ``n >= 1``; a positive step of at
#: most ``STEP_TOLERANCE * dt`` (a float-accumulating master's remainder) is accepted as no step (FMI 2.0 has no
#: step of 0).
STEP_TOLERANCE = 1e-6

#: The model at the FMU's own parameter values, in its resources (written by the builder: :mod:`fmu_build.kernels`).
MODEL_FILE = "ebb_model.npz"

#: Base name of the deflection outputs ``w[0] ... w[nodes+1]`` (``field=True``).
FIELD_NAME = "w"

_core, _beam = (importlib.import_module(CORE_PACKAGE + m) for m in CORE_MODULES)


class BeamSlave(Fmi2Slave):
    """pythonfmu slave iterating the beam's discrete state-space system.

    Parameters
    ----------
    **kwargs
        Passed by pythonfmu: ``instance_name``, ``resources`` (directory with
        :data:`SPEC_FILE`), ``visible``, ``logger``.

    Notes
    -----
    Value references follow registration order: the parameters
    ``EI, rhoA, c, eta, N, rhoI, kf`` (tunable, ``PARAMETER_NAMES``), one
    input per actuator [N], one output per sensor [m, m/s, m/s2], the field
    outputs when built with ``field=True``, then the fixed set-up as
    calculated parameters
    (``beam.length``, ``beam.nodes``, ``time.dt``, positions, ...).
    Parameter values are read when initialisation ends; a change in step mode
    takes effect at the next step (the state is kept).
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        resources = kwargs.get("resources") or os.path.dirname(os.path.abspath(__file__))
        _dedupe_sys_path(resources)
        with open(os.path.join(resources, SPEC_FILE), encoding="utf-8") as fh:
            spec = json.load(fh)
        # the config as written (its channels' fractional delays valid only under the band-limited force), then as a
        # host drives it: sample by sample, the force between samples causal
        self._cfg = _core.causal_config(_core.config_from_dict(spec["config"]))
        #: the model the FMU carries and the parameter values it is for (:func:`_carried_model`), or None
        self._carried = _carried_model(os.path.join(resources, MODEL_FILE))
        self._field = bool(spec.get("field", False))
        self._dt = float(spec["dt"])
        self.modelName: str | None = spec.get("model_name", self.modelName)
        self.description = spec.get("description")
        self.default_experiment = DefaultExperiment(start_time=0.0, step_size=self._dt)

        #: unit of each Real variable by name (read by the builder for modelDescription.xml)
        self.variable_units: dict[str, str] = {}
        self._reals: list[float | None] = []
        self._roles: list[tuple[int, Any] | None] = []  # per value reference: (kind, key) if settable
        self._params: dict[str, float] = dict(self._cfg.parameter_values())
        self._register_variables()

        self._model_stale = True  # parameters changed since the last assembly
        self._outputs_stale = True  # state, input or model changed since the outputs were stored
        self._problem = ""  # why the model or the outputs are unavailable
        self._u: list[float] = [0.0] * len(self._inputs)
        self._plan: _StepPlan | None = None
        # the hot path's references into the plan (see _assemble): np.ndarray once assembled, None before; typed
        # Any because they are read only after an assembly and the per-step path must stay free of narrowing
        self._z: Any = None  # (x, u)
        #: at the start time: with a first-order-hold realisation, "at rest" is x = −Γ₁ u(t0)
        self._at_start = True
        self._x: Any = None  # view z[:nx]
        self._W: Any = None
        self._buf: Any = None
        self._next_x: Any = None  # view buf[:nx]
        self._cx_valid = False  # plan.cx holds C x of the current state

    # ----------------------------------------------------------- variables
    def _add_real(self, name: str, value: float, unit: str | None, role: tuple[int, Any] | None,
                  **kw: Any) -> None:
        reals, vr = self._reals, len(self._reals)
        # a getter on the values list, not on self: no reference cycle through pythonfmu's variables
        self.register_variable(Real(name, getter=lambda: reals[vr], **kw), nested=False)
        reals.append(value)
        self._roles.append(role)
        if unit:
            self.variable_units[name] = unit

    def _add_constant(self, name: str, value: Any, description: str, unit: str | None = None) -> None:
        cls = {float: Real, int: Integer, str: String}[type(value)]
        self.register_variable(
            cls(name, causality=Fmi2Causality.calculatedParameter, variability=Fmi2Variability.fixed,
                description=description, getter=lambda: value),
            nested=False,
        )
        self._reals.append(value if cls is Real else None)
        self._roles.append(None)
        if unit:
            self.variable_units[name] = unit

    def _register_variables(self) -> None:
        cfg = self._cfg
        for name in _beam.PARAMETER_NAMES:
            self._add_real(name, self._params[name], _beam.PARAMETER_UNITS[name], (1, name),
                           causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable,
                           description=_beam.PARAMETER_DESCRIPTIONS[name])
        self._inputs = range(len(self._reals), len(self._reals) + len(cfg.actuators))
        for j, a in enumerate(cfg.actuators):
            self._add_real(a.name, 0.0, "N", (0, j), causality=Fmi2Causality.input,
                           description=f"point force at x = {a.x:g} m")
        first_output = len(self._reals)
        for s in cfg.sensors:
            through = "" if getattr(s, "antialias", None) is None else f", through its {s.antialias.describe()}"
            self._add_real(s.name, math.nan, s.unit, None, causality=Fmi2Causality.output,
                           description=f"{s.kind} at x = {s.x:g} m{through}")
        if self._field:
            xs, _ = _core.field_matrix(cfg)
            for i, x in enumerate(xs):
                self._add_real(f"{FIELD_NAME}[{i}]", math.nan, "m", None, causality=Fmi2Causality.output,
                               description=f"deflection at grid node x = {x:g} m")
        self._outputs = (first_output, len(self._reals))

        b = cfg.beam
        self._add_constant("beam.length", float(b.length), "beam length", "m")
        self._add_constant("beam.nodes", int(b.nodes), "number of interior grid points")
        for side, end in (("left", b.left), ("right", b.right)):
            self._add_constant(f"beam.{side}", str(end.kind), f"boundary condition at the {side} end")
            if end.kind == "elastic":
                self._add_constant(f"beam.{side}_kt", float(end.kt), f"translational spring at the {side} end",
                                   "N/m")
                self._add_constant(f"beam.{side}_kr", float(end.kr), f"rotational spring at the {side} end",
                                   "N.m/rad")
        t = cfg.time
        self._add_constant("time.dt", float(t.dt), "sample time (communication steps are multiples of it)", "s")
        self._add_constant("time.theta", float(t.theta), "theta of the three-level time-stepping scheme")
        self._add_constant("time.substeps", int(t.substeps), "sub-steps of the scheme per sample")
        self._add_constant("time.scheme", str(t.scheme),
                           "exact: Richardson FD modes integrated exactly in time; theta: the seed's theta-scheme")
        for a in cfg.actuators:
            self._add_constant(f"actuators.{a.name}.x", float(a.x), f"position of actuator {a.name}", "m")
            if getattr(a, "antialias", None) is not None:
                self._add_constant(f"actuators.{a.name}.antialias.order", int(a.antialias.order),
                                   f"order of the anti-alias filter on force {a.name}'s record (cancels the "
                                   "sensors' own)")
                self._add_constant(f"actuators.{a.name}.antialias.corner", float(a.antialias.corner),
                                   f"-3 dB corner of the anti-alias filter on force {a.name}'s record", "Hz")
        for s in cfg.sensors:
            self._add_constant(f"sensors.{s.name}.x", float(s.x), f"position of sensor {s.name}", "m")
            self._add_constant(f"sensors.{s.name}.kind", str(s.kind), f"quantity measured by sensor {s.name}")
            if getattr(s, "antialias", None) is not None:
                self._add_constant(f"sensors.{s.name}.antialias.order", int(s.antialias.order),
                                   f"order of sensor {s.name}'s anti-alias filter (Butterworth)")
                self._add_constant(f"sensors.{s.name}.antialias.corner", float(s.antialias.corner),
                                   f"-3 dB corner of sensor {s.name}'s anti-alias filter", "Hz")
        for m in getattr(cfg, "masses", ()):
            self._add_constant(f"masses.{m.name}.x", float(m.x), f"position of point mass {m.name}", "m")
            self._add_constant(f"masses.{m.name}.mass", float(m.mass), f"point mass {m.name}", "kg")
        for k in getattr(cfg, "springs", ()):
            self._add_constant(f"springs.{k.name}.x", float(k.x), f"position of spring to ground {k.name}", "m")
            self._add_constant(f"springs.{k.name}.k", float(k.k), f"spring to ground {k.name}", "N/m")
        for w in getattr(cfg, "weak_segments", ()):
            self._add_constant(f"weak_segments.{w.name}.x", float(w.x), f"centre of weak segment {w.name}", "m")
            self._add_constant(f"weak_segments.{w.name}.length", float(w.length), f"length of weak segment {w.name}",
                               "m")
            self._add_constant(f"weak_segments.{w.name}.factor", float(w.factor),
                               f"remaining fraction of EI in {w.name}")

    # ----------------------------------------------------------- model
    def _error(self, function: str, message: str) -> None:
        """Log ``message`` with status error: the loader turns the call's status into fmi2Error."""
        self.log(f"{function}: {message}", Fmi2Status.error)

    def _assemble(self) -> bool:
        """(Re)build the step plan from the current parameters, keeping the state.

        Returns False, with the reason in ``self._problem``, when the core
        rejects the parameters (ParameterError, StabilityError) or fails.
        """
        try:
            # the modal realisation: cheaper to rebuild for new parameters than the nodal one, and
            # better conditioned (field outputs are appended as displacement outputs at the grid nodes)
            if self._carried is not None and self._carried[0] == self._params:
                plan = _StepPlan(*self._carried[1])       # the model the FMU carries for these values
            else:
                system = _core.assemble_modal(self._cfg, dict(self._params), field=self._field)
                plan = _StepPlan(system.A, system.B, system.C, system.D, system.hold)
        except Exception as exc:
            self._model_stale = True
            self._problem = f"no valid model for these parameters: {type(exc).__name__}: {exc}"
            return False
        if self._z is None or self._z.size != plan.nx + plan.nu:
            self._z = np.zeros(plan.nx + plan.nu)
        self._z[plan.nx:] = self._u
        self._plan = plan
        self._x = self._z[:plan.nx]
        self._W = plan.W
        self._buf = plan.buf
        self._next_x = plan.next_x
        self._cx_valid = False
        self._model_stale = False
        self._outputs_stale = True
        return True

    def _refresh_outputs(self) -> bool:
        """Store ``y = C x + D u`` of the current state and inputs among the Real values.

        Returns False, with the reason in ``self._problem``, when there is no
        valid model or the outputs are not finite.
        """
        if self._model_stale and not self._assemble():
            return False
        plan = cast(_StepPlan, self._plan)  # not stale: an assembly has set it
        self._rest_start()
        if not self._cx_valid:
            plan.N.dot(self._z, out=plan.cx)
            self._cx_valid = True
        values = plan.cx.tolist()
        if plan.feedthrough:
            u = self._u
            for i, drow in plan.feedthrough:
                values[i] += sum(map(operator.mul, drow, u))
        if not math.isfinite(sum(values)):
            self._problem = "the outputs are not finite (numerical overflow)"
            return False
        o0, o1 = self._outputs
        self._reals[o0:o1] = values
        self._outputs_stale = False
        return True

    def _rest_start(self) -> None:
        """At the start time, put the state at rest for the current inputs (``x = −Γ₁ u``)."""
        if self._at_start and self._plan is not None and self._plan.hold is not None:
            self._x[...] = -(self._plan.hold @ np.asarray(self._u, dtype=float))
            self._cx_valid = False

    # ----------------------------------------------------------- FMI calls
    def setup_experiment(self, start_time: float = 0.0, *args: Any) -> None:
        pass

    def enter_initialization_mode(self) -> None:
        pass

    def exit_initialization_mode(self) -> None:
        try:
            if (self._model_stale or self._plan is None) and not self._assemble():
                self._error("fmi2ExitInitializationMode", self._problem)
        except Exception as exc:
            self._error("fmi2ExitInitializationMode", f"{type(exc).__name__}: {exc}")

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            if step_size == self._dt and not self._model_stale and not self._at_start:  # the hot path
                self._W.dot(self._z, out=self._buf)
                self._x[...] = self._next_x
                self._cx_valid = True
                self._outputs_stale = True
                return True
            return self._do_steps(step_size)
        except Exception as exc:
            self._error("fmi2DoStep", f"{type(exc).__name__}: {exc}")
            return False

    def _do_steps(self, step_size: float) -> bool:
        ratio = step_size / self._dt
        if math.isfinite(ratio) and 0.0 < ratio <= STEP_TOLERANCE:
            # a master's rounding remainder (time accumulated in floating point: 2000 steps of 1e-4 s fall
            # 5.7e-15 s short of 0.2 s, and the master steps the rest): no sample to take
            return True
        n = round(ratio) if math.isfinite(ratio) else 0
        if n < 1 or abs(ratio - n) > STEP_TOLERANCE:
            self._error("fmi2DoStep", f"communication step size {step_size!r} s is not a positive "
                                      f"integer multiple of the sample time dt = {self._dt!r} s")
            return False
        if self._model_stale and not self._assemble():
            self._error("fmi2DoStep", self._problem)
            return False
        self._rest_start()
        self._at_start = False
        W, z, buf, x, next_x = self._W, self._z, self._buf, self._x, self._next_x
        for _ in range(n):
            W.dot(z, out=buf)
            x[...] = next_x
        self._cx_valid = True
        self._outputs_stale = True
        return True

    def terminate(self) -> None:
        pass

    def get_real(self, vrs: Sequence[int]) -> list[float]:
        try:
            if self._outputs_stale and not self._refresh_outputs():
                o0, o1 = self._outputs
                if any(o0 <= vr < o1 for vr in vrs):
                    self._error("fmi2GetReal", self._problem)
                    return [math.nan] * len(vrs)
            reals = self._reals
            values = [reals[vr] for vr in vrs]
            if None in values:
                raise TypeError("a requested variable is not of type Real")
            return cast("list[float]", values)  # no None among them (checked above)
        except Exception as exc:
            self._error("fmi2GetReal", f"value references {list(vrs)}: {type(exc).__name__}: {exc}")
            return [math.nan] * len(vrs)

    def set_real(self, vrs: Sequence[int], values: Sequence[float]) -> None:
        try:
            roles, reals = self._roles, self._reals
            for vr, value in zip(vrs, values):
                try:
                    role = roles[vr]
                except (IndexError, TypeError):  # no such value reference
                    role = None
                if role is None:  # or an output or a constant
                    self._error("fmi2SetReal", f"variable {self._name(vr)} cannot be set")
                    continue
                kind, key = role
                if kind == 0:  # input
                    if not math.isfinite(value):
                        self._error("fmi2SetReal", f"input {self._name(vr)} = {value!r} is not a finite number")
                        continue
                    reals[vr] = value
                    self._u[key] = value
                    if self._plan is not None:
                        self._z[self._plan.nx + key] = value  # C x stays valid; D u is added on reading
                else:  # parameter: used from the next assembly on
                    self._params[key] = value
                    reals[vr] = value
                    self._model_stale = True
                self._outputs_stale = True
        except Exception as exc:
            self._error("fmi2SetReal", f"{type(exc).__name__}: {exc}")

    def get_integer(self, vrs: Sequence[int]) -> list[int]:
        try:
            return super().get_integer(vrs)
        except Exception as exc:
            self._error("fmi2GetInteger", f"{type(exc).__name__}: {exc}")
            return [0] * len(vrs)

    def get_boolean(self, vrs: Sequence[int]) -> list[bool]:
        self._error("fmi2GetBoolean", "this FMU has no Boolean variables")
        return [False] * len(vrs)

    def get_string(self, vrs: Sequence[int]) -> list[str]:
        try:
            return super().get_string(vrs)
        except Exception as exc:
            self._error("fmi2GetString", f"{type(exc).__name__}: {exc}")
            return [""] * len(vrs)

    def set_integer(self, vrs: Sequence[int], values: Sequence[int]) -> None:
        self._error("fmi2SetInteger", f"variables {[self._name(vr) for vr in vrs]} cannot be set")

    def set_boolean(self, vrs: Sequence[int], values: Sequence[bool]) -> None:
        self._error("fmi2SetBoolean", f"variables {[self._name(vr) for vr in vrs]} cannot be set")

    def set_string(self, vrs: Sequence[int], values: Sequence[str]) -> None:
        self._error("fmi2SetString", f"variables {[self._name(vr) for vr in vrs]} cannot be set")

    def _name(self, vr: int) -> str:
        var = self.vars.get(vr)
        return f"{var.name!r} (value reference {vr})" if var is not None else f"with value reference {vr}"


class _StepPlan:
    """One sample of ``x+ = A x + B u`` and the outputs ``C x+`` as one matrix-vector product.

    ``W = [[A, B], [C A, C B]]`` acts on ``z = (x, u)``: its first ``nx``
    entries are the next state, the others ``C x+``, so that reading the
    outputs after a step costs no further product; ``D u`` of the inputs set
    after the step is added when the outputs are read.  ``W`` is stored in
    column-major order (a slightly faster ``dgemv`` for these sizes).

    Parameters
    ----------
    A, B, C, D
        The discrete system (``C``, ``D`` include the field rows, if any).
    hold
        ``Γ₁`` of a first-order-hold realisation, or ``None``.
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
                 hold: np.ndarray | None = None) -> None:
        A, B, C, D = (np.asarray(m, dtype=float) for m in (A, B, C, D))
        #: first-order-hold matrix Γ₁ (state at rest is −Γ₁ u), or None
        self.hold = None if hold is None else np.asarray(hold, dtype=float)
        nx, nu = B.shape
        self.nx, self.nu = nx, nu
        self.W = np.asfortranarray(np.vstack([np.hstack([A, B]), np.hstack([C @ A, C @ B])]))
        #: ``[C 0]``: the outputs' state part of the current ``z`` (when no step has computed it)
        self.N = np.ascontiguousarray(np.hstack([C, np.zeros_like(D)]))
        self.buf = np.empty(self.W.shape[0])
        self.next_x = self.buf[:nx]
        self.cx = self.buf[nx:]
        #: (output row, row of D as a list) for every output with direct feedthrough
        self.feedthrough: list[tuple[int, list[float]]] = [
            (i, D[i].tolist()) for i in range(D.shape[0]) if D[i].any()
        ]


def _carried_model(path: str) -> tuple[dict[str, float], tuple[Any, ...]] | None:
    """The parameter values and the model ``(A, B, C, D, hold)`` the FMU carries (:data:`MODEL_FILE`), or None.
    An acceleration only: a missing or unreadable file leaves every assembly to the core."""
    try:
        with np.load(path, allow_pickle=False) as z:
            values = {str(n): float(v) for n, v in zip(z["names"], z["values"])}
            hold = z["hold"] if bool(z["has_hold"]) else None
            return values, (z["A"], z["B"], z["C"], z["D"], hold)
    except Exception:   # noqa: BLE001 - see the docstring
        return None


def _dedupe_sys_path(resources: str) -> None:
    """Keep one entry of ``resources`` on ``sys.path``.

    pythonfmu inserts the resources directory at ``sys.path[0]`` for every
    instance it creates; without this, 1,000 instantiations leave 1,000
    entries that every later import would scan.
    """
    seen = False
    kept = []
    for p in sys.path:
        if p == resources:
            if seen:
                continue
            seen = True
        kept.append(p)
    if len(kept) != len(sys.path):
        sys.path[:] = kept
