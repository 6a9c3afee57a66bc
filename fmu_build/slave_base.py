"""What the beam's pythonfmu slaves share, FMI 2.0's (``slave_template``) and FMI 3.0's (``slave_template_fmi3``).

The slaves hold no physics.  At the end of initialisation they ask the core for the discrete system of the
current parameter values, ``x[k+1] = A x[k] + B u[k]``, ``y[k] = C x[k] + D u[k]``, ``t_k = t_0 + k dt``
(``ebb_model.assemble_modal``; with ``field=True`` displacement outputs at every grid node are appended), and then
only iterate it.  Co-simulation semantics, zero-order hold: at ``t_k`` the master sets ``u_k``; reading the
outputs returns ``y_k = C x_k + D u_k`` (an input just set shows at once in velocity and acceleration sensors:
direct feedthrough, declared in ModelStructure); a step ``(t_k, h)`` with ``h = n dt`` (``n`` a positive
integer) applies the recursion ``n`` times with ``u`` held; any other ``h`` is refused.

:class:`BeamModel` is everything but the standard's calls: the variables (made by the version's variable
classes, :meth:`BeamModel._real_variable`, :meth:`BeamModel._constant_variable`), the assembly, the step, reading
and writing values.  Errors never escape as Python exceptions, which pythonfmu reports as fatal: they are logged
with status error and the FMU's C loader returns an error status for that call (``loader.c``, ``loader3.c``).

This module is a template like the slaves: the builder copies it into the FMU's resources as
``<modelIdentifier>_base.py`` with :data:`CORE_PACKAGE` pointing at the FMU's private copy of ``ebb_model``
(:mod:`fmu_build.bundle`), and the slave's import of it renamed to match.  The per-step path is kept lean (see
:class:`StepPlan`): everything is precomputed at assembly, a step is one matrix-vector product into a
preallocated buffer (which also yields ``C x`` of the new state) and one copy, and outputs are converted to
Python floats only when read after a change.
"""
from __future__ import annotations

import importlib
import importlib.util
import json
import math
import operator
import os
import sys
from typing import TYPE_CHECKING, Any, Sequence, cast

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

__all__ = ["BeamModel", "StepPlan", "CORE_PACKAGE", "CORE_MODULES", "SPEC_FILE", "STEP_TOLERANCE", "FIELD_NAME",
           "MODEL_FILE", "REQUIRED_PACKAGES", "INPUT", "PARAMETER"]

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

#: Name of the deflection outputs (``field=True``): ``w[0] ... w[nodes+1]`` in FMI 2.0, one array ``w`` in FMI 3.0.
FIELD_NAME = "w"

#: Roles of a settable value: (INPUT, actuator index) or (PARAMETER, parameter name).
INPUT, PARAMETER = 0, 1

_core, _beam = (importlib.import_module(CORE_PACKAGE + m) for m in CORE_MODULES)


class BeamModel:
    """The beam slave's state and behaviour, independent of the FMI version.

    Values are kept in one flat list ``_reals`` of *elements* (a scalar variable is one element, an array as many
    as it has): ``_first[vr]`` is the first element of value reference ``vr``, ``_count[vr]`` how many it has.
    Without arrays (FMI 2.0) an element's index is its value reference.

    Notes
    -----
    Value references follow registration order: the parameters ``EI, rhoA, c, eta, N, rhoI, kf`` (tunable,
    ``PARAMETER_NAMES``), one input per actuator [N], one output per sensor [m, m/s, m/s2], the field outputs when
    built with ``field=True``, then the fixed set-up as calculated parameters (``beam.length``, ``beam.nodes``,
    ``time.dt``, positions, ...).  Parameter values are read when initialisation ends; a change in step mode takes
    effect at the next step (the state is kept).
    """

    #: Prefix of the standard's function names in messages (``fmi2``, ``fmi3``).
    FMI = "fmi2"
    #: The version's status value of an error, for ``log``.
    ERROR_STATUS: Any = 3

    if TYPE_CHECKING:   # provided by the pythonfmu slave class the concrete slave also derives from
        vars: dict[int, Any]
        modelName: str | None
        description: str | None

        def register_variable(self, var: Any, nested: bool = True) -> None: ...

        def log(self, msg: str, status: Any = ..., category: str | None = None, debug: bool = False) -> None: ...

    # ----------------------------------------------------------- the version's variables
    def _real_variable(self, name: str, getter: Any, *, causality: str, variability: str | None, description: str,
                       unit: str | None, size: int) -> Any:
        """The version's Real (Float64) variable; ``size`` > 1: an array of that many elements."""
        raise NotImplementedError

    def _constant_variable(self, name: str, value: float | int | str, description: str, unit: str | None) -> Any:
        """The version's calculated parameter (fixed) holding ``value`` (its type chooses the variable's)."""
        raise NotImplementedError

    def _add_field(self, xs: Sequence[float]) -> None:
        """Register the deflection outputs at the grid nodes ``xs`` (scalars or one array)."""
        raise NotImplementedError

    # ----------------------------------------------------------- set-up
    def _init_model(self, resources: str | None) -> None:
        """Read the FMU's spec in ``resources`` (this module's folder when None), register the variables and set
        the state at rest."""
        resources = resources or os.path.dirname(os.path.abspath(__file__))
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
        self.modelName = spec.get("model_name", self.modelName)
        self.description = spec.get("description")

        #: unit of each Real variable by name (read by the builder for modelDescription.xml)
        self.variable_units: dict[str, str] = {}
        self._reals: list[float | None] = []
        self._roles: list[tuple[int, Any] | None] = []  # per element: (kind, key) if settable
        self._first: list[int] = []    # per value reference: its first element
        self._count: list[int] = []    # per value reference: its number of elements
        self._params: dict[str, float] = dict(self._cfg.parameter_values())
        self._register_variables()

        self._model_stale = True  # parameters changed since the last assembly
        self._outputs_stale = True  # state, input or model changed since the outputs were stored
        self._problem = ""  # why the model or the outputs are unavailable
        self._u: list[float] = [0.0] * len(self._inputs)
        self._plan: StepPlan | None = None
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

    def _add_real(self, name: str, value: float, unit: str | None, role: tuple[int, Any] | None, *,
                  causality: str, variability: str | None = None, description: str = "", size: int = 1) -> None:
        reals, first = self._reals, len(self._reals)
        # a getter on the values list, not on self: no reference cycle through pythonfmu's variables
        getter = (lambda: reals[first]) if size == 1 else (lambda: reals[first:first + size])
        self.register_variable(self._real_variable(name, getter, causality=causality, variability=variability,
                                                   description=description, unit=unit, size=size), nested=False)
        reals.extend([value] * size)
        self._roles.extend([role] * size)
        self._first.append(first)
        self._count.append(size)
        if unit:
            self.variable_units[name] = unit

    def _add_constant(self, name: str, value: Any, description: str, unit: str | None = None) -> None:
        self.register_variable(self._constant_variable(name, value, description, unit), nested=False)
        self._first.append(len(self._reals))
        self._count.append(1)
        self._reals.append(value if type(value) is float else None)
        self._roles.append(None)
        if unit:
            self.variable_units[name] = unit

    def _register_variables(self) -> None:
        cfg = self._cfg
        for name in _beam.PARAMETER_NAMES:
            self._add_real(name, self._params[name], _beam.PARAMETER_UNITS[name], (PARAMETER, name),
                           causality="parameter", variability="tunable",
                           description=_beam.PARAMETER_DESCRIPTIONS[name])
        self._inputs = range(len(self._reals), len(self._reals) + len(cfg.actuators))
        for j, a in enumerate(cfg.actuators):
            self._add_real(a.name, 0.0, "N", (INPUT, j), causality="input", description=f"point force at x = {a.x:g} m")
        first_output = len(self._reals)
        for s in cfg.sensors:
            through = "" if getattr(s, "antialias", None) is None else f", through its {s.antialias.describe()}"
            self._add_real(s.name, math.nan, s.unit, None, causality="output",
                           description=f"{s.kind} at x = {s.x:g} m{through}")
        if self._field:
            self._add_field(_core.field_matrix(cfg)[0])
        self._outputs = (first_output, len(self._reals))
        self._register_setup()

    def _register_setup(self) -> None:
        """The fixed set-up as calculated parameters."""
        cfg = self._cfg
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

    def array_sizes(self) -> dict[int, int]:
        """Value reference -> number of elements, of every array variable (none in FMI 2.0)."""
        return {vr: n for vr, n in enumerate(self._count) if n > 1}

    # ----------------------------------------------------------- model
    def _error(self, function: str, message: str) -> None:
        """Log ``message`` with status error: the loader turns the call's status into an error."""
        self.log(f"{self.FMI}{function}: {message}", self.ERROR_STATUS)

    def _assemble(self) -> bool:
        """(Re)build the step plan from the current parameters, keeping the state; False, with the reason in
        ``self._problem``, when the core rejects the parameters (ParameterError, StabilityError) or fails."""
        try:
            # the modal realisation: cheaper to rebuild for new parameters than the nodal one, and
            # better conditioned (field outputs are appended as displacement outputs at the grid nodes)
            if self._carried is not None and self._carried[0] == self._params:
                plan = StepPlan(*self._carried[1])       # the model the FMU carries for these values
            else:
                system = _core.assemble_modal(self._cfg, dict(self._params), field=self._field)
                plan = StepPlan(system.A, system.B, system.C, system.D, system.hold)
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
        """Store ``y = C x + D u`` of the current state and inputs among the Real values; False, with the reason
        in ``self._problem``, when there is no valid model or the outputs are not finite."""
        if self._model_stale and not self._assemble():
            return False
        plan = cast(StepPlan, self._plan)  # not stale: an assembly has set it
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

    def _exit_initialization(self) -> None:
        try:
            if (self._model_stale or self._plan is None) and not self._assemble():
                self._error("ExitInitializationMode", self._problem)
        except Exception as exc:
            self._error("ExitInitializationMode", f"{type(exc).__name__}: {exc}")

    def _advance(self, step_size: float) -> bool:
        """One communication step of ``step_size``; False (the reason logged) when it is refused."""
        try:
            if step_size == self._dt and not self._model_stale and not self._at_start:  # the hot path
                self._W.dot(self._z, out=self._buf)
                self._x[...] = self._next_x
                self._cx_valid = True
                self._outputs_stale = True
                return True
            return self._do_steps(step_size)
        except Exception as exc:
            self._error("DoStep", f"{type(exc).__name__}: {exc}")
            return False

    def _do_steps(self, step_size: float) -> bool:
        ratio = step_size / self._dt
        if math.isfinite(ratio) and 0.0 < ratio <= STEP_TOLERANCE:
            # a master's rounding remainder (time accumulated in floating point: 2000 steps of 1e-4 s fall
            # 5.7e-15 s short of 0.2 s, and the master steps the rest): no sample to take
            return True
        n = round(ratio) if math.isfinite(ratio) else 0
        if n < 1 or abs(ratio - n) > STEP_TOLERANCE:
            self._error("DoStep", f"communication step size {step_size!r} s is not a positive "
                                  f"integer multiple of the sample time dt = {self._dt!r} s")
            return False
        if self._model_stale and not self._assemble():
            self._error("DoStep", self._problem)
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

    # ----------------------------------------------------------- values
    def _read(self, function: str, vrs: Sequence[int], elements: bool = False) -> list[float]:
        """The Real values of ``vrs`` (with ``elements``: every element of each, in order; else one per reference,
        a reference being its element's index); NaNs and a logged error for what cannot be read."""
        try:
            if elements:
                first, count = self._first, self._count
                at = [i for vr in vrs for i in range(first[vr], first[vr] + count[vr])]
            else:
                at = list(vrs) if not isinstance(vrs, list) else vrs
            if self._outputs_stale and not self._refresh_outputs():
                o0, o1 = self._outputs
                if any(o0 <= i < o1 for i in at):
                    self._error(function, self._problem)
                    return [math.nan] * len(at)
            reals = self._reals
            values = [reals[i] for i in at]
            if None in values:
                raise TypeError("a requested variable is not of type Real")
            return cast("list[float]", values)  # no None among them (checked above)
        except Exception as exc:
            self._error(function, f"value references {list(vrs)}: {type(exc).__name__}: {exc}")
            n = sum(self._count[vr] if 0 <= vr < len(self._count) else 1 for vr in vrs) if elements else len(vrs)
            return [math.nan] * n

    def _write(self, function: str, vrs: Sequence[int], values: Sequence[float]) -> None:
        """Set the inputs and parameters ``vrs`` (scalars, one value each); a logged error for anything else."""
        try:
            roles, reals, first, count = self._roles, self._reals, self._first, self._count
            for vr, value in zip(vrs, values):
                try:
                    role = roles[first[vr]] if count[vr] == 1 else None
                except (IndexError, TypeError):  # no such value reference
                    role = None
                if role is None:  # or an output or a constant
                    self._error(function, f"variable {self._name(vr)} cannot be set")
                    continue
                kind, key = role
                if kind == INPUT:
                    if not math.isfinite(value):
                        self._error(function, f"input {self._name(vr)} = {value!r} is not a finite number")
                        continue
                    reals[first[vr]] = value
                    self._u[key] = value
                    if self._plan is not None:
                        self._z[self._plan.nx + key] = value  # C x stays valid; D u is added on reading
                else:  # parameter: used from the next assembly on
                    self._params[key] = value
                    reals[first[vr]] = value
                    self._model_stale = True
                self._outputs_stale = True
        except Exception as exc:
            self._error(function, f"{type(exc).__name__}: {exc}")

    def _refuse(self, function: str, vrs: Sequence[int]) -> None:
        self._error(function, f"variables {[self._name(vr) for vr in vrs]} cannot be set")

    def _name(self, vr: int) -> str:
        var = self.vars.get(vr)
        return f"{var.name!r} (value reference {vr})" if var is not None else f"with value reference {vr}"


class StepPlan:
    """One sample of ``x+ = A x + B u`` and the outputs ``C x+`` as one matrix-vector product.

    ``W = [[A, B], [C A, C B]]`` acts on ``z = (x, u)``: its first ``nx`` entries are the next state, the others
    ``C x+``, so that reading the outputs after a step costs no further product; ``D u`` of the inputs set after
    the step is added when the outputs are read.  ``W`` is column-major (a slightly faster ``dgemv`` here).

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
    """Keep one entry of ``resources`` on ``sys.path``: pythonfmu inserts the resources directory at
    ``sys.path[0]`` for every instance it creates (1,000 instantiations left 1,000 entries for every import)."""
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
