"""Generate variables.h and modelDescription.xml (FMI 2.0 Co-Simulation) from a ModelTable."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from fmus.table import ModelTable, Variable

__all__ = [
    "variables_header", "model_description", "initial_unknowns", "OUTPUT_DEPENDENCIES",
    "SET_INSTANTIATED", "SET_INIT", "SET_STEP",
]

# Phases in which fmi2Set* may write a variable (bit mask, mirrored in common/variable_table.h).
SET_INSTANTIATED, SET_INIT, SET_STEP = 1, 2, 4

# SI base-unit exponents of the units our models use, so tools can convert them
# (FMI 2.0 section 2.2.2, <BaseUnit kg m s A K mol cd rad factor offset>).
BASE_UNITS: dict[str, dict[str, str]] = {
    "m": {"m": "1"},
    "m2": {"m": "2"},
    "m3": {"m": "3"},
    "m/s": {"m": "1", "s": "-1"},
    "m/s2": {"m": "1", "s": "-2"},
    "m3/s": {"m": "3", "s": "-1"},
    "s": {"s": "1"},
    "kg": {"kg": "1"},
    "kg/m3": {"kg": "1", "m": "-3"},
    "kg/m2": {"kg": "1", "m": "-2"},
    "N": {"kg": "1", "m": "1", "s": "-2"},
    "N.s/m": {"kg": "1", "s": "-1"},
    "N/m": {"kg": "1", "s": "-2"},
    "J": {"kg": "1", "m": "2", "s": "-2"},
    "Pa": {"kg": "1", "m": "-1", "s": "-2"},
    "m3/(s.Pa)": {"kg": "-1", "m": "4", "s": "1"},
    "rad": {"rad": "1"},
    "rad/s": {"rad": "1", "s": "-1"},
    "deg": {"rad": "1", "factor": "0.017453292519943295"},
    "1": {},
}

_C_TYPE = {"Real": "VT_REAL", "Integer": "VT_INTEGER", "Boolean": "VT_BOOLEAN"}
_C_CAUSALITY = {
    "parameter": "CA_PARAMETER", "calculatedParameter": "CA_CALCULATED_PARAMETER",
    "input": "CA_INPUT", "output": "CA_OUTPUT", "local": "CA_LOCAL",
}
_C_VARIABILITY = {
    "constant": "VA_CONSTANT", "fixed": "VA_FIXED", "tunable": "VA_TUNABLE",
    "discrete": "VA_DISCRETE", "continuous": "VA_CONTINUOUS",
}


# Every output depends on no input (FMI 2.0 section 2.2.8, 3.0 section 2.4.8): in co-simulation
# our outputs at a communication point are computed by the step (or the initialization) that
# reached it; an input set afterwards changes them only in the next step. So an importer needs no
# algebraic loop between our FMUs, and may read outputs before setting the inputs.
OUTPUT_DEPENDENCIES = ""


def initial_unknowns(table: ModelTable) -> list[Variable]:
    """FMI 2.0 section 2.2.8 (3.0: 2.4.8): the outputs with initial approx/calculated and all
    calculated parameters, in table (= index) order. Their dependencies are left out, which
    declares a dependence on every known: initially an output does depend on parameters and on
    inputs' start values (a cylinder's force is in equilibrium with its start load)."""
    return [v for v in table.variables
            if (v.causality == "output" and v.initial in ("approx", "calculated"))
            or v.causality == "calculatedParameter"]


def set_phases(var: Variable) -> int:
    """When fmi2Set* may write `var` (FMI 2.0 section 4.2.4 state machine)."""
    if var.causality == "input" or (var.causality == "parameter" and var.variability == "tunable"):
        return SET_INSTANTIATED | SET_INIT | SET_STEP
    if var.causality == "parameter":
        return SET_INSTANTIATED | SET_INIT
    if var.initial == "approx":
        return SET_INSTANTIATED
    return 0


def _c_double(value) -> str:
    if value is None:
        return "0.0"
    if isinstance(value, bool):
        return "1.0" if value else "0.0"
    return repr(float(value))


def _c_bound(value, missing: str) -> str:
    return missing if value is None else repr(float(value))


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def variables_header(table: ModelTable, guid: str) -> str:
    """C header with MODEL_IDENTIFIER, MODEL_GUID, N_VARIABLES, VR_* / N_* macros and VARIABLES."""
    lines = [
        "/* Generated from variables.toml by the fmus builder; do not edit. */",
        f"#ifndef VARIABLES_H_{table.identifier}",
        f"#define VARIABLES_H_{table.identifier}",
        '#include "variable_table.h"',
        "",
        f"#define MODEL_IDENTIFIER {table.identifier}",
        f"#define MODEL_IDENTIFIER_STRING {_c_string(table.identifier)}",
        f"#define MODEL_GUID {_c_string(guid)}",
        f"#define N_VARIABLES {len(table.variables)}",
        "",
    ]
    lines += [f"#define VR_{v.macro} {v.value_reference}" for v in table.variables]
    for name, (_, count) in table.arrays.items():
        lines.append(f"#define N_{name} {count}")
    lines += ["", "static const excosim_variable VARIABLES[N_VARIABLES] = {"]
    for v in table.variables:
        lines.append(
            f"    {{{_c_string(v.name)}, {_C_TYPE[v.type]}, {_C_CAUSALITY[v.causality]}, "
            f"{_C_VARIABILITY[v.variability]}, {set_phases(v)}, {_c_double(v.start)}, "
            f"{_c_bound(v.min, '-HUGE_VAL')}, {_c_bound(v.max, 'HUGE_VAL')}}},")
    lines += ["};", "", "#endif", ""]
    return "\n".join(lines)


def _format_start(var: Variable) -> str:
    if isinstance(var.start, bool):
        return "true" if var.start else "false"
    if var.type == "Integer":
        return str(int(var.start))
    return repr(float(var.start))


def model_description(table: ModelTable, guid: str, sources: list[str],
                      generation_tool: str) -> bytes:
    """modelDescription.xml for FMI 2.0 Co-Simulation, as UTF-8 bytes."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": table.identifier,
        "guid": guid,
        "description": table.description,
        "generationTool": generation_tool,
        "variableNamingConvention": "structured",
        "numberOfEventIndicators": "0",
    })
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": table.identifier,
        "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true",
        "providesDirectionalDerivative": "false",
    })
    files = ET.SubElement(cs, "SourceFiles")
    for name in sources:
        ET.SubElement(files, "File", {"name": name})

    units = table.units()
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
    for v in table.variables:
        attributes = {"name": v.name, "valueReference": str(v.value_reference),
                      "causality": v.causality, "variability": v.variability}
        if v.description:
            attributes["description"] = v.description
        if v.initial in ("exact", "approx"):  # "calculated" is the default where allowed
            attributes["initial"] = v.initial
        scalar = ET.SubElement(model_variables, "ScalarVariable", attributes)
        type_attributes = {}
        if v.unit:
            type_attributes["unit"] = v.unit
        if v.min is not None:
            type_attributes["min"] = repr(v.min) if v.type == "Real" else str(int(v.min))
        if v.max is not None:
            type_attributes["max"] = repr(v.max) if v.type == "Real" else str(int(v.max))
        if v.start is not None:
            type_attributes["start"] = _format_start(v)
        ET.SubElement(scalar, v.type, type_attributes)

    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in table.variables if v.causality == "output"]
    if outputs:
        element = ET.SubElement(structure, "Outputs")
        for v in outputs:
            ET.SubElement(element, "Unknown", {"index": str(v.value_reference + 1),
                                               "dependencies": OUTPUT_DEPENDENCIES})
    initial = initial_unknowns(table)
    if initial:
        element = ET.SubElement(structure, "InitialUnknowns")
        for v in initial:  # no dependencies attribute: FMI 2.0 reads "depends on every known"
            ET.SubElement(element, "Unknown", {"index": str(v.value_reference + 1)})

    ET.indent(root)
    text = ET.tostring(root, encoding="unicode")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + text + "\n").encode("utf-8")
