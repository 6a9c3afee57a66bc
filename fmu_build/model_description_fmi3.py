"""Turn pythonfmu3's modelDescription into the FMI 3.0 Python beam FMU's.

``Fmi3Slave.to_xml`` lists the variables in value-reference order (so the XML cannot drift from the slave) with
an ``Output`` and ``InitialUnknown`` per output but no dependencies, no units, its own name as the model
identifier and a random instantiation token; it writes the co-simulation flag
``canHandleVariableCommunicationStepSize`` from another option's value, and parameter start values with 16
significant digits (not always the double itself).  :func:`finish_model_description_fmi3` sets, as
:func:`fmu_build.model_description.finish_model_description` does for FMI 2.0:

* the build's identity: ``modelIdentifier``, ``instantiationToken``, ``modelName``, ``description``, and the
  co-simulation capabilities (variable step size; no FMU state);
* ``UnitDefinitions`` (the FMI 2.0 FMU's) and a ``unit`` on every Float64 variable that has one;
* the start values written to round-trip (``repr`` of the double);
* ``ModelStructure``: every ``Output`` with its ``dependencies`` on the inputs that reach it directly (value
  references, ``dependenciesKind="tunable"``: ``D`` depends on the tunable parameters), every output and
  calculated parameter an ``InitialUnknown`` (a calculated parameter with no dependencies: fixed by the build).
"""
from __future__ import annotations

from typing import Mapping, Sequence, cast
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

from ebb_model.errors import FmuError

from .model_description import FmuIdentity, unit_definitions

__all__ = ["finish_model_description_fmi3"]


def finish_model_description_fmi3(
    root: Element,
    *,
    identity: FmuIdentity,
    description: str,
    units: Mapping[str, str],
    feedthrough: Mapping[str, Sequence[str]],
    starts: Mapping[str, float],
) -> bytes:
    """Complete pythonfmu3's ``<fmiModelDescription>`` element and serialise it.

    Parameters
    ----------
    root
        The element returned by ``Fmi3Slave.to_xml()``; modified in place.
    identity
        Names of this build (its ``guid`` is the instantiation token).
    description
        The model's ``description`` attribute.
    units
        Unit of each Float64 variable, by variable name.
    feedthrough
        For each output name (an array's own name), the names of the inputs that reach it directly.
    starts
        The start value of each Float64 variable that has one, by name.

    Returns
    -------
    bytes
        The UTF-8 XML document.

    Raises
    ------
    FmuError
        If the element is not what pythonfmu3 produces or names an input that does not exist.
    """
    root.set("modelName", identity.model_name)
    root.set("instantiationToken", identity.guid)
    root.set("description", description)
    cosim = root.find("CoSimulation")
    variables = root.find("ModelVariables")
    if cosim is None or variables is None:
        raise FmuError("pythonfmu3's model description has no CoSimulation or ModelVariables element",
                       function="build_fmu")
    cosim.set("modelIdentifier", identity.model_identifier)
    cosim.set("canHandleVariableCommunicationStepSize", "true")
    cosim.set("canGetAndSetFMUState", "false")
    cosim.set("canSerializeFMUState", "false")
    cosim.set("canBeInstantiatedOnlyOncePerProcess", "false")

    used: set[str] = set()
    vr: dict[str, str] = {}
    entries = list(variables)
    for sv in entries:
        name = cast(str, sv.get("name"))  # pythonfmu3 writes a name and a value reference on every variable
        vr[name] = cast(str, sv.get("valueReference"))
        if sv.tag == "Float64":
            unit = units.get(name)
            if unit:
                sv.set("unit", unit)
                used.add(unit)
            if sv.get("start") is not None and name in starts:
                sv.set("start", repr(float(starts[name])))
    old_units = root.find("UnitDefinitions")
    if old_units is not None:
        root.remove(old_units)
    if used:
        root.insert(list(root).index(cosim) + 1, unit_definitions(used))

    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    structure = SubElement(root, "ModelStructure")
    for sv in entries:
        if sv.get("causality") != "output":
            continue
        name = cast(str, sv.get("name"))
        deps = []
        for input_name in feedthrough.get(name, ()):
            if input_name not in vr:
                raise FmuError(f"output {name!r} depends on unknown input {input_name!r}", function="build_fmu")
            deps.append(int(vr[input_name]))
        attrib = {"valueReference": vr[name], "dependencies": " ".join(map(str, sorted(deps)))}
        if deps:
            attrib["dependenciesKind"] = " ".join(["tunable"] * len(deps))
        SubElement(structure, "Output", attrib)
    for sv in entries:
        causality = sv.get("causality")
        if causality in ("output", "calculatedParameter"):
            attrib = {"valueReference": vr[cast(str, sv.get("name"))]}
            if causality == "calculatedParameter":
                attrib["dependencies"] = ""  # fixed by the build
            SubElement(structure, "InitialUnknown", attrib)

    return parseString(tostring(root, encoding="UTF-8")).toprettyxml(indent="  ", encoding="UTF-8")
