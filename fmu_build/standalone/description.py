"""The standalone FMU's variables, and the two files generated from them: ``modelDescription.xml`` and
``ebb_config.h``.

One list (:func:`fmu_variables`) is the single source of both, so the XML cannot drift from the C code's
value references.  Value references are the list positions, one counter over all types (as the pythonfmu
FMU's): the parameters ``EI, rhoA, c, eta, N, rhoI, kf`` (tunable), one input per actuator [N], one output
per sensor [m, m/s, m/s2] (then the field outputs ``w[i]`` when asked for), the fixed set-up as calculated
parameters (names, causality and units as the pythonfmu FMU's, plus ``time.input``), and for model exchange
the continuous states ``modes.q[i]``, ``modes.qd[i]`` (``i = 1 … k``: the modal coordinates and velocities
of the ``k`` Richardson modes, mass-normalised; scheme ``theta``: ``nodes.q[i]``, ``nodes.qd[i]``, deflection
and velocity of the grid's ``k`` unknowns) and their derivatives ``der(...)``.

``ebb_config.h`` holds the **structure** only (grid, ends, positions, sensor kinds, point masses, springs, weak
segments, ``dt``, input reconstruction, start values, the variable table): the matrices are assembled in C from
the parameter values when the FMU initialises.  The channels' converter delays (after the force's channel) are
there as each delayed sensor's delay-line taps (:func:`ebb_model.acquisition.delay_line.delay_taps`: lags and
weights, the same float64 numbers as the Python model's); a delay line is past output samples, not a
continuous-time state, so an FMU with one offers co-simulation only (no ``ModelExchange`` element).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence, cast
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

import numpy as np

from ebb_model import PARAMETER_NAMES, BeamConfig
from ebb_model.acquisition.antialias import effective_filters
from ebb_model.acquisition.channel_delay import effective_delays
from ebb_model.acquisition.delay_line import delay_taps
from ebb_model.beam import PARAMETER_DESCRIPTIONS, PARAMETER_UNITS, SENSOR_KINDS, Sensor

from ..model_description import UNIT_DEFINITIONS, FmuIdentity

__all__ = ["Variable", "fmu_variables", "model_description_xml", "config_header", "build_description_xml",
           "n_modes", "delay_lines", "units_categories_experiment", "C_SOURCES", "C_HEADERS"]

#: The C sources compiled into the binary (in this package's ``csrc``) for FMI 2.0 and 3.0 (the instance is
#: common, ``ebb_fmi2.c`` or ``ebb_fmi3.c`` translates its standard's calls), and the headers they include
#: (FMI 3.0's types in ``ebb_fmi3.h``).
_COMMON = ("ebb_linalg.c", "ebb_fd.c", "ebb_model.c", "ebb_theta.c", "ebb_instance.c", "ebb_derivatives.c",
           "ebb_state.c", "ebb_delay.c")
C_SOURCES = {2: _COMMON + ("ebb_fmi2.c",), 3: _COMMON + ("ebb_fmi3.c",)}
C_HEADERS = {2: ("ebb_beam.h", "ebb_instance.h"), 3: ("ebb_beam.h", "ebb_instance.h", "ebb_fmi3.h")}
#: Roles and types as ``ebb_instance.h`` numbers them.
_ROLES = {"parameter": 0, "input": 1, "output": 2, "constant": 3, "state": 4, "derivative": 5, "time": 6}
_TYPES = {"Real": 0, "Integer": 1, "String": 2}
_HOLDS = {"zoh": "EBB_ZOH", "foh": "EBB_FOH", "cubic": "EBB_CUBIC"}


@dataclass(frozen=True)
class Variable:
    """One model variable: name, type (``Real``/``Integer``/``String``), role, index within its role, value.

    ``role`` is ``parameter``, ``input``, ``output``, ``constant`` (calculated parameter, fixed), ``state``,
    ``derivative`` or ``time`` (FMI 3.0's independent variable); ``value`` is the start value of parameters and
    the value of constants; ``size`` is the length of an array variable (FMI 3.0's ``w``), whose elements are
    the role's ``index``, ``index + 1``, ….
    """

    name: str
    type: str
    role: str
    index: int
    value: float | int | str | None = None
    unit: str | None = None
    description: str = ""
    size: int = 1


def n_modes(config: BeamConfig) -> int:
    """State pairs of model exchange: the unknowns of the config's grid (= the exact scheme's modes)."""
    b = config.beam
    return b.nodes + 2 - int(b.left.translation_fixed) - int(b.right.translation_fixed)


def n_filter_states(config: BeamConfig) -> int:
    """States of the sensors' anti-alias filters (:mod:`ebb_model.acquisition.antialias`), after the modal ones."""
    return sum(f.order for f in effective_filters(config) if f is not None)


def delay_lines(config: BeamConfig) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """``(sensor index, lags, weights)`` of each sensor whose effective delay is not 0
    (:func:`~ebb_model.acquisition.delay_line.delay_taps`), in sensor order; empty when none is delayed."""
    return [(i, *delay_taps(d)) for i, d in enumerate(effective_delays(config)) if d]


def fmu_variables(config: BeamConfig, field_sensors: Sequence[Sensor] = (), fmi: int = 2) -> list[Variable]:
    """All variables of the standalone FMU, in value-reference order (see the module docstring).

    With ``fmi=3`` the field outputs are one array variable ``w`` (the deflection at the grid nodes, in the
    order of ``field_sensors``) and ``time`` (the independent variable) comes last.
    """
    out: list[Variable] = []
    values = config.parameter_values()
    for i, name in enumerate(PARAMETER_NAMES):
        out.append(Variable(name, "Real", "parameter", i, float(values[name]), PARAMETER_UNITS[name],
                            PARAMETER_DESCRIPTIONS[name]))
    for j, a in enumerate(config.actuators):
        out.append(Variable(a.name, "Real", "input", j, 0.0, "N", f"point force at x = {a.x:g} m"))
    delays = effective_delays(config) or (0.0,) * len(config.sensors)
    for o, (s, d) in enumerate(zip(config.sensors, delays)):
        through = "" if s.antialias is None else f", through its {s.antialias.describe()}"
        late = f", {d:g} samples late (its converter's delay after the force's)" if d else ""
        out.append(Variable(s.name, "Real", "output", o, None, s.unit, f"{s.kind} at x = {s.x:g} m{through}{late}"))
    if fmi == 3 and field_sensors:
        out.append(Variable("w", "Real", "output", len(config.sensors), None, "m",
                            f"deflection at the {len(field_sensors)} grid nodes x = {field_sensors[0].x:g} … "
                            f"{field_sensors[-1].x:g} m, equally spaced", size=len(field_sensors)))
    else:
        for o, s in enumerate(field_sensors, start=len(config.sensors)):
            out.append(Variable(s.name, "Real", "output", o, None, "m", f"deflection at grid node x = {s.x:g} m"))

    def const(name: str, value: float | int | str, description: str, unit: str | None = None) -> None:
        kind = {float: "Real", int: "Integer", str: "String"}[type(value)]
        out.append(Variable(name, kind, "constant", 0, value, unit, description))

    b, t = config.beam, config.time
    const("beam.length", float(b.length), "beam length", "m")
    const("beam.nodes", int(b.nodes), "number of interior grid points")
    for side, end in (("left", b.left), ("right", b.right)):
        const(f"beam.{side}", str(end.kind), f"boundary condition at the {side} end")
        if end.kind == "elastic":
            const(f"beam.{side}_kt", float(end.kt), f"translational spring at the {side} end", "N/m")
            const(f"beam.{side}_kr", float(end.kr), f"rotational spring at the {side} end", "N.m/rad")
    const("time.dt", float(t.dt), "sample time (communication steps are multiples of it)", "s")
    const("time.theta", float(t.theta), "theta of the three-level time-stepping scheme (not used by 'exact')")
    const("time.substeps", int(t.substeps), "sub-steps of the scheme per sample (not used by 'exact')")
    const("time.scheme", str(t.scheme),
          "exact: Richardson FD modes integrated exactly in time; theta: the seed's theta-scheme")
    const("time.input", str(t.input_hold), "force between samples: cubic, foh (straight line) or zoh (held)")
    for a in config.actuators:
        const(f"actuators.{a.name}.x", float(a.x), f"position of actuator {a.name}", "m")
        if a.antialias is not None:
            const(f"actuators.{a.name}.antialias.order", int(a.antialias.order),
                  f"order of the anti-alias filter on force {a.name}'s record (cancels the sensors' own)")
            const(f"actuators.{a.name}.antialias.corner", float(a.antialias.corner),
                  f"-3 dB corner of the anti-alias filter on force {a.name}'s record", "Hz")
    for s in config.sensors:
        const(f"sensors.{s.name}.x", float(s.x), f"position of sensor {s.name}", "m")
        const(f"sensors.{s.name}.kind", str(s.kind), f"quantity measured by sensor {s.name}")
        if s.antialias is not None:
            const(f"sensors.{s.name}.antialias.order", int(s.antialias.order),
                  f"order of sensor {s.name}'s anti-alias filter (Butterworth)")
            const(f"sensors.{s.name}.antialias.corner", float(s.antialias.corner),
                  f"-3 dB corner of sensor {s.name}'s anti-alias filter", "Hz")
    for m in config.masses:
        const(f"masses.{m.name}.x", float(m.x), f"position of point mass {m.name}", "m")
        const(f"masses.{m.name}.mass", float(m.mass), f"point mass {m.name}", "kg")
    for sp in config.springs:
        const(f"springs.{sp.name}.x", float(sp.x), f"position of spring to ground {sp.name}", "m")
        const(f"springs.{sp.name}.k", float(sp.k), f"spring to ground {sp.name}", "N/m")
    for w in config.weak_segments:
        const(f"weak_segments.{w.name}.x", float(w.x), f"centre of weak segment {w.name}", "m")
        const(f"weak_segments.{w.name}.length", float(w.length), f"length of weak segment {w.name}", "m")
        const(f"weak_segments.{w.name}.factor", float(w.factor), f"remaining fraction of EI in {w.name}")
    k = n_modes(config)
    if t.scheme == "theta":                 # the nodal unknowns of the config's grid
        first = 1 if b.left.translation_fixed else 0
        xs = [b.length * (first + i) / (b.nodes + 1) for i in range(k)]
        for i in range(k):
            out.append(Variable(f"nodes.q[{i + 1}]", "Real", "state", i, 0.0, "m",
                                f"deflection at grid node x = {xs[i]:g} m"))
        for i in range(k):
            out.append(Variable(f"nodes.qd[{i + 1}]", "Real", "state", k + i, 0.0, "m/s",
                                f"velocity at grid node x = {xs[i]:g} m (co-simulation: the scheme's "
                                "(q^j - q^(j-1))/tau)"))
    else:                                   # the Richardson modes
        for i in range(k):
            out.append(Variable(f"modes.q[{i + 1}]", "Real", "state", i, 0.0, None,
                                f"coordinate of Richardson mode {i + 1} (mass-normalised)"))
        for i in range(k):
            out.append(Variable(f"modes.qd[{i + 1}]", "Real", "state", k + i, 0.0, None,
                                f"velocity of Richardson mode {i + 1}"))
        at = 2 * k
        for s, filt in zip(config.sensors, effective_filters(config)):   # in series after the sensor
            for j in range(0 if filt is None else filt.order):
                out.append(Variable(f"filters.{s.name}[{j + 1}]", "Real", "state", at + j, 0.0, None,
                                    f"state {j + 1} of sensor {s.name}'s anti-alias filter (its sections' "
                                    "outputs and scaled rates)"))
            at += 0 if filt is None else filt.order
    for v in [v for v in out if v.role == "state"]:
        out.append(Variable(f"der({v.name})", "Real", "derivative", v.index, None, None, f"derivative of {v.name}"))
    if fmi == 3:
        out.append(Variable("time", "Real", "time", 0, None, "s", "simulation time"))
    return out


def _num(v: float) -> str:
    return repr(float(v))


def model_description_xml(variables: Sequence[Variable], *, identity: FmuIdentity, description: str, dt: float,
                          sources: Sequence[str], exchange: bool = True) -> bytes:
    """``modelDescription.xml``: model exchange (unless ``exchange`` is false: a config with channel delays) and
    co-simulation with the same model identifier."""
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": identity.model_name, "guid": identity.guid,
        "description": description, "generationTool": "ebb-ident fmu_build.standalone",
        "variableNamingConvention": "structured", "numberOfEventIndicators": "0"})
    common = {"modelIdentifier": identity.model_identifier, "canGetAndSetFMUstate": "true",
              "canSerializeFMUstate": "true", "canNotUseMemoryManagementFunctions": "true",
              "canBeInstantiatedOnlyOncePerProcess": "false", "providesDirectionalDerivative": "true"}
    interfaces = [SubElement(root, "ModelExchange", common | {"completedIntegratorStepNotNeeded": "true"})] \
        if exchange else []
    interfaces.append(SubElement(root, "CoSimulation", common | {"canHandleVariableCommunicationStepSize": "true",
                                                                 "canInterpolateInputs": "false",
                                                                 "maxOutputDerivativeOrder": "0"}))
    for element in interfaces:
        files = SubElement(element, "SourceFiles")
        for name in sources:
            SubElement(files, "File", {"name": name})
    units_categories_experiment(root, variables, dt)
    mv = SubElement(root, "ModelVariables")
    state_index = {}
    for vr, v in enumerate(variables):
        attrib = {"name": v.name, "valueReference": str(vr)}
        if v.description:
            attrib["description"] = v.description
        child: dict[str, str] = {}
        if v.role == "parameter":
            attrib |= {"causality": "parameter", "variability": "tunable"}
            child["start"] = _num(cast(float, v.value))  # parameters and inputs start at a float (fmu_variables)
        elif v.role == "input":
            attrib |= {"causality": "input", "variability": "continuous"}
            child["start"] = _num(cast(float, v.value))
        elif v.role == "output":
            attrib |= {"causality": "output", "variability": "continuous"}
        elif v.role == "constant":
            attrib |= {"causality": "calculatedParameter", "variability": "fixed"}
        elif v.role == "state":
            attrib |= {"causality": "local", "variability": "continuous", "initial": "exact"}
            child["start"] = "0.0"
            state_index[v.name] = vr + 1
        else:
            attrib |= {"causality": "local", "variability": "continuous"}
            child["derivative"] = str(state_index[v.name[4:-1]])
        if v.unit:
            child["unit"] = v.unit
        sv = SubElement(mv, "ScalarVariable", attrib)
        SubElement(sv, v.type, child)
    ms = SubElement(root, "ModelStructure")
    outputs = [i + 1 for i, v in enumerate(variables) if v.role == "output"]
    derivs = [i + 1 for i, v in enumerate(variables) if v.role == "derivative"]
    if outputs:
        node = SubElement(ms, "Outputs")
        for i in outputs:
            SubElement(node, "Unknown", {"index": str(i)})
    if derivs:
        node = SubElement(ms, "Derivatives")
        for i in derivs:
            SubElement(node, "Unknown", {"index": str(i)})
    node = SubElement(ms, "InitialUnknowns")
    for i, v in enumerate(variables, start=1):
        if v.role in ("output", "derivative"):
            SubElement(node, "Unknown", {"index": str(i)})
        elif v.role == "constant":
            SubElement(node, "Unknown", {"index": str(i), "dependencies": ""})
    return parseString(tostring(root, encoding="UTF-8")).toprettyxml(indent="  ", encoding="UTF-8")


def units_categories_experiment(root: Element, variables: Sequence[Variable], dt: float) -> None:
    """The elements between the interfaces and the variables, the same in FMI 2.0 and 3.0: the units the variables
    use, the log categories, the default experiment (start 0, step ``dt``)."""
    units = sorted({v.unit for v in variables if v.unit})
    if units:
        node = SubElement(root, "UnitDefinitions")
        for name in units:
            unit = SubElement(node, "Unit", {"name": name})
            if UNIT_DEFINITIONS.get(name):
                SubElement(unit, "BaseUnit", {k: str(e) for k, e in UNIT_DEFINITIONS[name].items()})
    cats = SubElement(root, "LogCategories")
    SubElement(cats, "Category", {"name": "logStatusError", "description": "errors (always reported)"})
    SubElement(cats, "Category", {"name": "logAll", "description": "everything (with debug logging on)"})
    SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stepSize": _num(dt)})


def build_description_xml(identity: FmuIdentity, sources: Sequence[str], fmi: int = 2) -> bytes:
    """``sources/buildDescription.xml`` (FMI 2.0.4 / 3.0 layout): the C99 files and libm."""
    root = Element("fmiBuildDescription", {"fmiVersion": f"{fmi}.0"})
    bc = SubElement(root, "BuildConfiguration", {
        "modelIdentifier": identity.model_identifier,
        "description": "plain C99, no dependencies besides the C math library"})
    fs = SubElement(bc, "SourceFileSet", {"language": "C99"})
    for name in sources:
        SubElement(fs, "SourceFile", {"name": name})
    SubElement(bc, "Library", {"name": "m", "description": "the C math library (where it is a separate library)"})
    return parseString(tostring(root, encoding="UTF-8")).toprettyxml(indent="  ", encoding="UTF-8")


def _c_double(v: float) -> str:
    if math.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    return repr(float(v))


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _array(ctype: str, name: str, items: Sequence[str]) -> str:
    body = ", ".join(items) if items else "0"                 # C has no empty arrays
    return f"static const {ctype} {name}[] = {{{body}}};\n"


def _delay_header(config: BeamConfig, n_sensors: int) -> str:
    """The delay lines of ``ebb_config.h`` (``ebb_delay.c``): per output its delayed index or -1 (the field
    outputs are undelayed), per delayed sensor its taps ``EBB_DELAY_TAP0[d] … EBB_DELAY_TAP0[d + 1] - 1`` (lags
    ascending, weights as :func:`~ebb_model.acquisition.delay_line.delay_taps` gives them, to the last bit), the
    length of every history ring (the largest lag) and the delayed sensors' names (for the messages)."""
    lines = delay_lines(config)
    index = [-1] * n_sensors
    for d, (i, _, _) in enumerate(lines):
        index[i] = d
    starts = np.cumsum([0] + [lags.size for _, lags, _ in lines])
    names = ", ".join(config.sensors[i].name for i, _, _ in lines)
    text = (f"\n/* the channels' converter delays as delay lines (ebb_delay.c) */\n#define EBB_NDELAYED {len(lines)}\n"
            f"#define EBB_DELAY_LEN {max((int(lags.max()) for _, lags, _ in lines), default=0)}\n"
            f"#define EBB_DELAYED_NAMES {_c_string(names)}\n")
    text += _array("int", "EBB_SENS_DELAYED", [str(d) for d in index])
    text += _array("int", "EBB_DELAY_TAP0", [str(int(k)) for k in starts])
    text += _array("int", "EBB_DELAY_LAG", [str(int(j)) for _, lags, _ in lines for j in lags])
    text += _array("double", "EBB_DELAY_WEIGHT", [_c_double(w) for _, _, ws in lines for w in ws])
    return text


def config_header(config: BeamConfig, variables: Sequence[Variable], identity: FmuIdentity,
                  field_sensors: Sequence[Sensor] = ()) -> str:
    """``ebb_config.h``: the structure of the beam and the variable table, as C constants (no matrices)."""
    b, t = config.beam, config.time
    sensors = tuple(config.sensors) + tuple(field_sensors)
    values = config.parameter_values()
    lines = [
        "/* ebb_config.h -- generated by fmu_build.standalone: the structure of this beam (no matrices). */",
        "#ifndef EBB_CONFIG_H", "#define EBB_CONFIG_H", "", "#include <math.h>", "",
        f"#define EBB_GUID {_c_string(identity.guid)}",
        f"#define EBB_LENGTH {_c_double(b.length)}",
        f"#define EBB_NODES {int(b.nodes)}",
        f"#define EBB_LEFT_KT {_c_double(b.left.kt)}",
        f"#define EBB_LEFT_KR {_c_double(b.left.kr)}",
        f"#define EBB_RIGHT_KT {_c_double(b.right.kt)}",
        f"#define EBB_RIGHT_KR {_c_double(b.right.kr)}",
        f"#define EBB_DT {_c_double(t.dt)}",
        f"#define EBB_HOLD {_HOLDS[t.input_hold]}",
        f"#define EBB_SCHEME {'EBB_THETA' if t.scheme == 'theta' else 'EBB_EXACT'}",
        f"#define EBB_THETA_VALUE {_c_double(t.theta)}",
        f"#define EBB_SUBSTEPS {int(t.substeps)}",
        f"#define EBB_NMODES {n_modes(config)}",
        f"#define EBB_NFILT {n_filter_states(config)}",
        f"#define EBB_NSTATES {2 * n_modes(config) + n_filter_states(config)}",
        f"#define EBB_NACT {len(config.actuators)}",
        f"#define EBB_NSENS {len(sensors)}",
        f"#define EBB_NMASS {len(config.masses)}",
        f"#define EBB_NSPRING {len(config.springs)}",
        f"#define EBB_NWEAK {len(config.weak_segments)}",
        f"#define EBB_NVARS {len(variables)}", "",
    ]
    text = "\n".join(lines)
    text += _array("double", "EBB_ACT_X", [_c_double(a.x) for a in config.actuators])
    text += _array("double", "EBB_SENS_X", [_c_double(s.x) for s in sensors])
    text += _array("int", "EBB_SENS_KIND", [str(SENSOR_KINDS.index(s.kind)) for s in sensors])
    filters = effective_filters(config) + [None] * len(field_sensors)
    text += _array("int", "EBB_SENS_AA_ORDER", [str(0 if f is None else f.order) for f in filters])
    text += _array("double", "EBB_SENS_AA_CORNER", [_c_double(0.0 if f is None else f.corner) for f in filters])
    text += _delay_header(config, len(sensors))
    text += _array("double", "EBB_MASS_X", [_c_double(m.x) for m in config.masses])
    text += _array("double", "EBB_MASS_M", [_c_double(m.mass) for m in config.masses])
    text += _array("double", "EBB_SPRING_X", [_c_double(sp.x) for sp in config.springs])
    text += _array("double", "EBB_SPRING_K", [_c_double(sp.k) for sp in config.springs])
    text += _array("double", "EBB_WEAK_X", [_c_double(w.x) for w in config.weak_segments])
    text += _array("double", "EBB_WEAK_LEN", [_c_double(w.length) for w in config.weak_segments])
    text += _array("double", "EBB_WEAK_FACTOR", [_c_double(w.factor) for w in config.weak_segments])
    text += _array("double", "EBB_PARAM_START", [_c_double(values[n]) for n in PARAMETER_NAMES])
    text += "\n/* variable table, indexed by value reference */\n"
    text += _array("signed char", "EBB_VAR_TYPE", [str(_TYPES[v.type]) for v in variables])
    text += _array("signed char", "EBB_VAR_ROLE", [str(_ROLES[v.role]) for v in variables])
    text += _array("int", "EBB_VAR_INDEX", [str(v.index) for v in variables])
    text += _array("int", "EBB_VAR_SIZE", [str(v.size) for v in variables])
    # a constant's value is of its type (fmu_variables)
    text += _array("double", "EBB_VAR_REAL", [_c_double(cast(float, v.value))
                                              if v.type == "Real" and v.role == "constant" else "0.0"
                                              for v in variables])
    text += _array("int", "EBB_VAR_INT", [str(v.value) if v.type == "Integer" else "0" for v in variables])
    text += _array("char *const", "EBB_VAR_STRING",
                   [_c_string(cast(str, v.value)) if v.type == "String" else "0" for v in variables])
    text += _array("char *const", "EBB_VAR_NAME", [_c_string(v.name) for v in variables])
    text += "\n#endif\n"
    return text

