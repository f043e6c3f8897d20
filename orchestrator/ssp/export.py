"""A scenario's plant as an SSP 1.0 archive (System Structure and Parameterization): the format
libcosim/cosim-cli, ecos, OMSimulator and FMPy read.

The archive holds:

- SystemStructure.ssd: one component per plant role (boom, stick, bucket, pile), each with the
  role's FMU (resources/<file>.fmu, one copy per distinct file), its connectors (the FMU
  variables that play the role's ports) and a parameter binding;
- resources/<role>.ssv: the role's parameter values, a parameter set named PARAMETER_SET in
  every file (ecos chooses the set to apply by name);
- for each port whose port map converts units, a system connector "<role>.<port>" in SI,
  connected to the component connector through an SSP linear transformation (the port's scale
  and offset). Ports in SI need none, and have none: libcosim (libcosimc 0.0.6) refuses any
  connection to the system's own connectors, so a plant in SI loads there, one with converted
  ports in ecos and FMPy.

What a peer master does not get: the arm's rigid-body dynamics and its coupling into the
cylinders (loads and reflected inertia through F_ext and mass_load), the servos, the
load-sensing pump's law and the Pile's kinematics live in excosim's step loop
(orchestrator.plants.native), not in an FMU; no FMU-to-FMU connection carries them. The system's
description says so. A peer master that drives the system's connectors as the step loop does
gets the same physics from the FMUs; one that steps it alone gets each FMU at its inputs.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

from lxml import etree

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
PARAMETER_SET = "initialValues"
PEER_NOTE = ("excosim plant: the FMUs of the cylinder roles (boom, stick, bucket) and the pile. "
             "The arm's dynamics and its coupling into the cylinders (F_ext, mass_load), the "
             "servos (u), the load-sensing pump (p_pump, p_LS) and the tip's kinematics (the "
             "pile's tip_y, tip_z, bucket_angle) live in excosim's master, not in an FMU: a "
             "peer master drives these connectors itself.")
_TYPES = {"Real": "Real", "Float64": "Real", "Float32": "Real", "Integer": "Integer",
          "Int32": "Integer", "Int64": "Integer", "Boolean": "Boolean"}
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # fixed: the archive's bytes depend on its content only


def export_ssp(scenario: Any, path: str | Path) -> Path:
    """Write the scenario's plant (plant kind "sim") to the SSP archive `path` (module
    docstring); returns the path. ValueError (one line) for another plant kind or an FMU that
    cannot be read."""
    from fmpy import read_model_description

    from orchestrator.plants.master import fmu_path
    from plant_models.model_spec import ROLE_OF, ROLES

    if scenario.plant.kind != "sim":
        raise ValueError(f"plant.kind {scenario.plant.kind!r}: only a simulated plant (\"sim\") "
                         "is made of FMUs")
    specs = scenario.fmu_specs()
    files: dict[str, bytes] = {}
    ssd = etree.Element(f"{{{SSD}}}SystemStructureDescription",
                        nsmap={"ssd": SSD, "ssc": SSC, "ssv": SSV},
                        version="1.0", name=scenario.name)
    system = etree.SubElement(ssd, f"{{{SSD}}}System", name="excavator", description=PEER_NOTE)
    system_connectors = etree.SubElement(system, f"{{{SSD}}}Connectors")
    elements = etree.SubElement(system, f"{{{SSD}}}Elements")
    connections = etree.SubElement(system, f"{{{SSD}}}Connections")
    for role, spec in specs.items():
        source = Path(fmu_path(spec, role))
        name = _resource_name(source, files)
        description = read_model_description(str(source))
        variables = {v.name: v for v in description.modelVariables}
        component = etree.SubElement(elements, f"{{{SSD}}}Component", name=role,
                                     type="application/x-fmu-sharedlibrary",
                                     source=f"resources/{name}")
        connectors = etree.SubElement(component, f"{{{SSD}}}Connectors")
        inputs = _role_inputs(ROLE_OF[role])
        for port in ROLES[ROLE_OF[role]]:
            variable = variables.get(spec.variable(port))
            if variable is None:
                continue  # an optional port the FMU lacks
            kind = "input" if port in inputs else "output"
            _connector(connectors, variable.name, kind)
            transformation = spec.port_maps.get(port)
            if transformation is not None:
                _connector(system_connectors, f"{role}.{port}", kind)
                start, end = ((None, f"{role}.{port}"), (role, variable.name))
                if kind == "output":
                    start, end = end, start
                connection = etree.SubElement(connections, f"{{{SSD}}}Connection",
                                              _endpoints(start, end))
                # si = scale * fmu + offset: into an input fmu = si / scale - offset / scale
                factor, offset = (transformation.scale, transformation.offset) \
                    if kind == "output" else (1.0 / transformation.scale,
                                              -transformation.offset / transformation.scale)
                etree.SubElement(connection, f"{{{SSC}}}LinearTransformation",
                                 factor=repr(factor), offset=repr(offset))
        bindings = etree.SubElement(component, f"{{{SSD}}}ParameterBindings")
        etree.SubElement(bindings, f"{{{SSD}}}ParameterBinding", source=f"resources/{role}.ssv")
        files[f"resources/{role}.ssv"] = _ssv(spec.parameters, variables, role)
    for empty in (system_connectors, connections):
        if len(empty) == 0:
            system.remove(empty)
    etree.SubElement(ssd, f"{{{SSD}}}DefaultExperiment", startTime="0.0")
    files["SystemStructure.ssd"] = etree.tostring(ssd, xml_declaration=True, encoding="UTF-8",
                                                  pretty_print=True)
    target = Path(path)
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for member in sorted(files):
            info = zipfile.ZipInfo(member, _ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, files[member])
    return target


def _role_inputs(kind: str) -> tuple[str, ...]:
    from plant_models.model_spec import CYLINDER_INPUTS, PILE_INPUTS

    return CYLINDER_INPUTS if kind == "cylinder" else PILE_INPUTS


def _resource_name(source: Path, files: dict[str, bytes]) -> str:
    """The FMU's name under resources/, one copy per distinct file (a name clash of two
    different files gets a suffix)."""
    data = source.read_bytes()
    name, stem, n = source.name, source.stem, 1
    while f"resources/{name}" in files and files[f"resources/{name}"] != data:
        n += 1
        name = f"{stem}-{n}.fmu"
    files[f"resources/{name}"] = data
    return name


def _connector(parent, name: str, kind: str) -> None:
    connector = etree.SubElement(parent, f"{{{SSD}}}Connector", name=name, kind=kind)
    etree.SubElement(connector, f"{{{SSC}}}Real")


def _endpoints(start: tuple, end: tuple) -> dict[str, str]:
    """A connection's attributes; an element None is the system itself (no attribute)."""
    out = {}
    for side, (element, connector) in (("start", start), ("end", end)):
        if element is not None:
            out[f"{side}Element"] = element
        out[f"{side}Connector"] = connector
    return out


def _ssv(parameters, variables, role: str) -> bytes:
    """The role's parameter set (SSV 1.0) of its FMU's declared types."""
    root = etree.Element(f"{{{SSV}}}ParameterSet", nsmap={"ssv": SSV}, version="1.0",
                         name=PARAMETER_SET)
    values = etree.SubElement(root, f"{{{SSV}}}Parameters")
    for name, value in sorted(parameters.items()):
        variable = variables.get(name)
        kind = _TYPES.get(getattr(variable, "type", ""), "Real")
        parameter = etree.SubElement(values, f"{{{SSV}}}Parameter", name=name)
        text = ("true" if value else "false") if kind == "Boolean" else \
            str(int(value)) if kind == "Integer" else repr(float(value))
        etree.SubElement(parameter, f"{{{SSV}}}{kind}", value=text)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
