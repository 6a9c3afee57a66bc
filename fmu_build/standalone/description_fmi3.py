"""``modelDescription.xml`` of the standalone FMU in FMI 3.0.

The same variables as FMI 2.0 (:func:`~fmu_build.standalone.description.fmu_variables` with ``fmi=3``), written
as FMI 3.0 declares them: typed elements (``Float64``, ``Int32``, ``String``) addressed by value reference, the
deflection field ``w`` as one array variable with its ``Dimension``, ``time`` as the independent variable, the
states' ``derivative`` attributes naming value references, and the model structure as ``Output``,
``ContinuousStateDerivative`` and ``InitialUnknown`` elements.  Model exchange and co-simulation share one model
identifier; both provide directional and adjoint derivatives and saved, serialisable states.  A config with channel
delays has co-simulation only (a delay line is past samples, not a continuous-time state).
"""
from __future__ import annotations

from typing import Sequence, cast
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

from ..model_description import FmuIdentity
from .description import Variable, units_categories_experiment

__all__ = ["model_description_xml3"]

_ELEMENTS = {"Real": "Float64", "Integer": "Int32", "String": "String"}


def _num(v: float) -> str:
    return repr(float(v))


def _variable(parent: Element, vr: int, v: Variable, state_vr: dict[str, int]) -> None:
    attrib = {"name": v.name, "valueReference": str(vr)}
    if v.description:
        attrib["description"] = v.description
    if v.role == "parameter":
        attrib |= {"causality": "parameter", "variability": "tunable", "start": _num(cast(float, v.value))}
    elif v.role == "input":
        attrib |= {"causality": "input", "variability": "continuous", "start": _num(cast(float, v.value))}
    elif v.role == "output":
        attrib |= {"causality": "output", "variability": "continuous"}
    elif v.role == "constant":
        attrib |= {"causality": "calculatedParameter", "variability": "fixed"}
    elif v.role == "time":
        attrib |= {"causality": "independent", "variability": "continuous"}
    elif v.role == "state":
        attrib |= {"causality": "local", "variability": "continuous", "initial": "exact", "start": "0.0"}
        state_vr[v.name] = vr
    else:
        attrib |= {"causality": "local", "variability": "continuous",
                   "derivative": str(state_vr[v.name[4:-1]])}
    if v.unit and v.type == "Real":
        attrib["unit"] = v.unit
    node = SubElement(parent, _ELEMENTS[v.type], attrib)
    if v.size > 1:
        SubElement(node, "Dimension", {"start": str(v.size)})


def model_description_xml3(variables: Sequence[Variable], *, identity: FmuIdentity, description: str, dt: float,
                           sources: Sequence[str], exchange: bool = True) -> bytes:
    """``modelDescription.xml`` (FMI 3.0): model exchange (unless ``exchange`` is false: a config with channel
    delays) and co-simulation with the same model identifier."""
    del sources                         # FMI 3.0 lists the sources in sources/buildDescription.xml only
    root = Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": identity.model_name, "instantiationToken": identity.guid,
        "description": description, "generationTool": "ebb-ident fmu_build.standalone",
        "variableNamingConvention": "structured"})
    common = {"modelIdentifier": identity.model_identifier, "canGetAndSetFMUState": "true",
              "canSerializeFMUState": "true", "canBeInstantiatedOnlyOncePerProcess": "false",
              "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "true"}
    if exchange:
        SubElement(root, "ModelExchange", common | {"needsCompletedIntegratorStep": "false"})
    SubElement(root, "CoSimulation", common | {"canHandleVariableCommunicationStepSize": "true",
                                               "fixedInternalStepSize": _num(dt),
                                               "maxOutputDerivativeOrder": "0", "hasEventMode": "false"})
    units_categories_experiment(root, variables, dt)
    mv = SubElement(root, "ModelVariables")
    state_vr: dict[str, int] = {}
    for vr, v in enumerate(variables):
        _variable(mv, vr, v, state_vr)
    ms = SubElement(root, "ModelStructure")
    for vr, v in enumerate(variables):
        if v.role == "output":
            SubElement(ms, "Output", {"valueReference": str(vr)})
    for vr, v in enumerate(variables):
        if v.role == "derivative":
            SubElement(ms, "ContinuousStateDerivative", {"valueReference": str(vr)})
    for vr, v in enumerate(variables):
        if v.role in ("output", "derivative"):
            SubElement(ms, "InitialUnknown", {"valueReference": str(vr)})
        elif v.role == "constant":
            SubElement(ms, "InitialUnknown", {"valueReference": str(vr), "dependencies": ""})
    return parseString(tostring(root, encoding="UTF-8")).toprettyxml(indent="  ", encoding="UTF-8")
