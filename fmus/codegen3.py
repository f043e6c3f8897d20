"""Generate modelDescription.xml for FMI 3.0 Co-Simulation from the same ModelTable as FMI 2.0.

The variable table is shared: value references, causality, variability, units (FMI 3.0
<UnitDefinitions> with the SI base-unit exponents of codegen.BASE_UNITS), start, min and max are
the ones the FMI 2.0 description gets. Only the element names differ (Real -> Float64,
Integer -> Int32) and the model structure lists value references instead of indices.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from fmus.codegen import BASE_UNITS, OUTPUT_DEPENDENCIES, initial_unknowns
from fmus.table import ModelTable, Variable

__all__ = ["model_description_fmi3", "FMI3_TYPES"]

FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


def _start(var: Variable) -> str:
    if isinstance(var.start, bool):
        return "true" if var.start else "false"
    if var.type == "Integer":
        return str(int(var.start))
    return repr(float(var.start))


def _variable(parent: ET.Element, v: Variable) -> None:
    attributes = {"name": v.name, "valueReference": str(v.value_reference),
                  "causality": v.causality, "variability": v.variability}
    if v.description:
        attributes["description"] = v.description
    if v.initial in ("exact", "approx"):
        attributes["initial"] = v.initial
    if v.unit:
        attributes["unit"] = v.unit
    for key, bound in (("min", v.min), ("max", v.max)):
        if bound is not None:
            attributes[key] = repr(float(bound)) if v.type == "Real" else str(int(bound))
    if v.start is not None:
        attributes["start"] = _start(v)
    ET.SubElement(parent, FMI3_TYPES[v.type], attributes)


def model_description_fmi3(table: ModelTable, token: str, sources: list[str],
                           generation_tool: str) -> bytes:
    """modelDescription.xml for FMI 3.0 Co-Simulation, as UTF-8 bytes.

    `token` is the instantiationToken (the build's content hash, like the FMI 2.0 GUID).
    `sources` is unused: FMI 3.0 lists sources in sources/buildDescription.xml, not here.
    """
    del sources
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0",
        "modelName": table.identifier,
        "instantiationToken": token,
        "description": table.description,
        "generationTool": generation_tool,
        "variableNamingConvention": "structured",
    })
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": table.identifier,
        "canHandleVariableCommunicationStepSize": "true",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canGetAndSetFMUState": "true",
        "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false",
        "providesAdjointDerivatives": "false",
        "hasEventMode": "false",
        "providesIntermediateUpdate": "false",
        "mightReturnEarlyFromDoStep": "false",
    })
    units = sorted(set(table.units()) | {"s"})  # "s": the unit of the independent time
    if units:
        unit_defs = ET.SubElement(root, "UnitDefinitions")
        for unit in units:
            element = ET.SubElement(unit_defs, "Unit", {"name": unit})
            if unit in BASE_UNITS:
                ET.SubElement(element, "BaseUnit", BASE_UNITS[unit])

    categories = ET.SubElement(root, "LogCategories")
    for name, text in (("logStatusError", "errors"), ("logStatusWarning", "warnings"),
                       ("logEvents", "initialisation, steps and state handling")):
        ET.SubElement(categories, "Category", {"name": name, "description": text})

    if table.default_step_size or table.default_stop_time:
        experiment = {"startTime": "0"}
        if table.default_stop_time:
            experiment["stopTime"] = repr(table.default_stop_time)
        if table.default_step_size:
            experiment["stepSize"] = repr(table.default_step_size)
        ET.SubElement(root, "DefaultExperiment", experiment)

    model_variables = ET.SubElement(root, "ModelVariables")
    # FMI 3.0 requires exactly one independent variable; the layer (fmi3_cs.c) serves it as the
    # value reference one past the table.
    ET.SubElement(model_variables, "Float64", {
        "name": "time", "valueReference": str(len(table.variables)), "causality": "independent",
        "variability": "continuous", "unit": "s", "description": "simulation time"})
    for v in table.variables:
        _variable(model_variables, v)

    # FMI 3.0 section 2.4.8: outputs in ModelVariables order, depending on no input (see
    # codegen.OUTPUT_DEPENDENCIES); then the initial unknowns, depending on every known.
    structure = ET.SubElement(root, "ModelStructure")
    for v in table.variables:
        if v.causality == "output":
            ET.SubElement(structure, "Output", {"valueReference": str(v.value_reference),
                                                "dependencies": OUTPUT_DEPENDENCIES})
    for v in initial_unknowns(table):
        ET.SubElement(structure, "InitialUnknown", {"valueReference": str(v.value_reference)})

    ET.indent(root)
    text = ET.tostring(root, encoding="unicode")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + text + "\n").encode("utf-8")
