"""Turn pythonfmu's modelDescription into the beam FMU's.

pythonfmu's ``Fmi2Slave.to_xml`` lists the variables in value-reference order
(so the XML cannot drift from the slave), but has no units, no
``InitialUnknowns`` and no output dependencies, which
``fmpy.validation.validate_fmu`` reports.  :func:`finish_model_description`
adds them:

* ``UnitDefinitions`` with SI base-unit exponents and a ``unit`` on every
  Real variable that has one;
* ``ModelStructure/Outputs`` with ``dependencies`` on the inputs that reach
  an output directly (``D[i, j] != 0``: velocity and acceleration sensors);
  ``dependenciesKind="tunable"`` because ``D`` depends on the tunable
  parameters;
* ``ModelStructure/InitialUnknowns``: every output and calculated parameter;
* the build's identity: ``modelIdentifier``, ``guid``, ``modelName``,
  ``description``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence, cast
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

import numpy as np

from ebb_model.errors import FmuError

__all__ = ["FmuIdentity", "UNIT_DEFINITIONS", "unit_definitions", "finish_model_description", "feedthrough_from_D"]

#: SI base-unit exponents (FMI 2.0 ``BaseUnit`` attributes) of the units the beam FMU uses.
UNIT_DEFINITIONS: dict[str, dict[str, int]] = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "s": {"s": 1},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N.m2": {"kg": 1, "m": 3, "s": -2},
    "kg/m": {"kg": 1, "m": -1},
    "N.s/m2": {"kg": 1, "m": -1, "s": -1},
    "N/m": {"kg": 1, "s": -2},
    "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
    "kg.m": {"kg": 1, "m": 1},
    "N/m2": {"kg": 1, "m": -1, "s": -2},
}


@dataclass(frozen=True)
class FmuIdentity:
    """Names that make one built FMU distinct from every other.

    Attributes
    ----------
    model_identifier
        C identifier; name of the binary and of the slave module.
    class_name
        Name of the slave class inside that module.
    core_package
        Name of the FMU's private copy of ``ebb_model`` in its resources.
    guid
        ``{uuid}`` checked by the loader at ``fmi2Instantiate``.
    model_name
        Human-readable model name.
    """

    model_identifier: str
    class_name: str
    core_package: str
    guid: str
    model_name: str


def unit_definitions(units: set[str]) -> Element:
    """``<UnitDefinitions>`` of ``units`` with their SI base-unit exponents (the same in FMI 2.0 and 3.0)."""
    node = Element("UnitDefinitions")
    for name in sorted(units):
        unit = SubElement(node, "Unit", {"name": name})
        exponents = UNIT_DEFINITIONS.get(name)
        if exponents:
            SubElement(unit, "BaseUnit", {k: str(v) for k, v in exponents.items()})
    return node


def finish_model_description(
    root: Element,
    *,
    identity: FmuIdentity,
    description: str,
    units: Mapping[str, str],
    feedthrough: Mapping[str, Sequence[str]],
) -> bytes:
    """Complete pythonfmu's ``<fmiModelDescription>`` element and serialise it.

    Parameters
    ----------
    root
        The element returned by ``Fmi2Slave.to_xml()``; modified in place.
    identity
        Names of this build.
    description
        The model's ``description`` attribute.
    units
        Unit of each Real variable, by variable name.
    feedthrough
        For each output name, the names of the inputs that reach it directly.
        Outputs not listed have no direct feedthrough.

    Returns
    -------
    bytes
        The UTF-8 XML document.

    Raises
    ------
    FmuError
        If the element is not what pythonfmu produces (no CoSimulation or
        ModelVariables) or names an input that does not exist.
    """
    root.set("modelName", identity.model_name)
    root.set("guid", identity.guid)
    root.set("description", description)
    root.set("variableNamingConvention", "structured")
    cosim = root.find("CoSimulation")
    variables = root.find("ModelVariables")
    if cosim is None or variables is None:
        raise FmuError("pythonfmu's model description has no CoSimulation or ModelVariables element",
                       function="build_fmu")
    cosim.set("modelIdentifier", identity.model_identifier)
    cosim.set("canHandleVariableCommunicationStepSize", "true")
    cosim.set("canGetAndSetFMUstate", "false")
    cosim.set("canSerializeFMUstate", "false")
    cosim.set("canBeInstantiatedOnlyOncePerProcess", "false")

    # units
    used: set[str] = set()
    index: dict[str, int] = {}
    entries = list(variables)
    for i, sv in enumerate(entries, start=1):
        name = cast(str, sv.get("name"))  # pythonfmu writes a name on every ScalarVariable
        index[name] = i
        unit = units.get(name)
        real = sv.find("Real")
        if unit and real is not None:
            real.set("unit", unit)
            used.add(unit)
    if used:
        position = list(root).index(cosim) + 1
        root.insert(position, unit_definitions(used))

    # model structure
    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    structure = SubElement(root, "ModelStructure")
    outputs = [sv for sv in entries if sv.get("causality") == "output"]
    if outputs:
        node = SubElement(structure, "Outputs")
        for sv in outputs:
            name = cast(str, sv.get("name"))
            deps = []
            for input_name in feedthrough.get(name, ()):
                if input_name not in index:
                    raise FmuError(f"output {name!r} depends on unknown input {input_name!r}", function="build_fmu")
                deps.append(index[input_name])
            attrib = {"index": str(index[name]), "dependencies": " ".join(map(str, sorted(deps)))}
            if deps:
                attrib["dependenciesKind"] = " ".join(["tunable"] * len(deps))
            SubElement(node, "Unknown", attrib)
    initial = [sv for sv in entries if sv.get("causality") in ("output", "calculatedParameter")]
    if initial:
        node = SubElement(structure, "InitialUnknowns")
        for sv in initial:
            attrib = {"index": str(index[cast(str, sv.get("name"))])}
            if sv.get("causality") == "calculatedParameter":
                attrib["dependencies"] = ""  # fixed by the build
            SubElement(node, "Unknown", attrib)

    text = parseString(tostring(root, encoding="UTF-8")).toprettyxml(indent="  ", encoding="UTF-8")
    return text


def feedthrough_from_D(D: np.ndarray, output_names: Sequence[str],
                       input_names: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """Inputs that reach each output directly: the non-zero pattern of ``D``.

    Parameters
    ----------
    D
        Feedthrough matrix, shape (n_outputs, n_inputs), at the nominal
        parameters.  Its zero pattern comes from the sensor kinds (a
        displacement row is exactly zero), not from the parameter values.
    output_names, input_names
        Signal names of its rows and columns.

    Returns
    -------
    dict
        Output name -> tuple of input names (only outputs with at least one).
    """
    D = np.asarray(D, dtype=float)
    out: dict[str, tuple[str, ...]] = {}
    for i, oname in enumerate(output_names):
        deps = tuple(input_names[j] for j in range(D.shape[1]) if D[i, j] != 0.0)
        if deps:
            out[oname] = deps
    return out
