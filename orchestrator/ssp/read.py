"""A plant or one role of it from an SSP 1.0 archive made by another tool (or by export.py):
the component's FMU, its parameter values and its port map become the role's `fmu`,
`parameters` and `ports`.

In a scenario: `[plant.bucket] ssp = "variant.ssp"` (the component named "bucket", or
`component = "..."`), or `[plant] ssp = "plant.ssp"` for every role whose component the archive
has (a role's own `ssp` wins). The scenario's own `parameters` and `ports` of the role apply on
top of the archive's. What is read:

- the component's `source` FMU, extracted once per archive content under the FMU cache;
- its ParameterBindings: each SSV file in the archive (or inline ParameterValues), Real,
  Integer and Boolean values;
- its port map: a system connector "<role>.<port>" connected to one of the component's
  connectors makes that connector the port's variable; an SSP LinearTransformation on the
  connection becomes the port's scale and offset (export.py writes them so).

Anything else that would change the meaning silently is refused in one line (ValueError): a
schema error, a component that is missing or not an FMU, a parameter mapping, another kind of
transformation, a connector that is mapped twice.
"""

from __future__ import annotations

import hashlib
import zipfile
from pathlib import Path
from typing import Any

from lxml import etree

from plant_models.model_spec import ROLE_OF

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
ROLES = tuple(ROLE_OF)
_VALUE_TYPES = {"Real": float, "Integer": int, "Boolean": lambda text: text == "true"}


def expand_ssp(data: dict[str, Any], base_dir: Path, user: dict[str, set]
               ) -> tuple[dict[str, Any], dict[str, set]]:
    """`data` (a scenario's plain data) with every `ssp` reference replaced by the component's
    fmu, parameters and ports (module docstring); and role -> the parameter names the archive
    set. user: role -> the parameters the scenario files and --set gave (over the archive's;
    the preset's defaults are under them). Relative archive paths resolve against base_dir.
    ValueError "plant.<role>.ssp: ..." or "plant.ssp: ..."."""
    plant = data.get("plant")
    if not isinstance(plant, dict):
        return data, {}
    plant = dict(plant)
    whole = plant.pop("ssp", None)
    given: dict[str, set] = {}
    for role in ROLES:
        table = plant.get(role)
        table = dict(table) if isinstance(table, dict) else {}
        own = table.pop("ssp", None)
        component = table.pop("component", role)
        archive = own if own is not None else whole
        if archive is None:
            continue
        where = f"plant.{role}.ssp" if own is not None else "plant.ssp"
        if not isinstance(archive, str) or not isinstance(component, str):
            raise ValueError(f"{where}: expected a file name, got {archive!r}")
        path = (base_dir / archive).expanduser()
        try:
            read = read_component(path, component)
        except ValueError as error:
            raise ValueError(f"{where}: {error}") from None
        if read is None:
            if own is not None:
                raise ValueError(f"{where}: {path.name} has no component {component!r}")
            continue  # the plant's archive without this role: the role stays as it is
        fmu, parameters, ports = read
        table["fmu"] = str(fmu)
        below = dict(table.get("parameters") or {})
        mine = user.get(role, set())
        table["parameters"] = {**{k: v for k, v in below.items() if k not in mine},
                               **parameters, **{k: v for k, v in below.items() if k in mine}}
        table["ports"] = {**ports, **dict(table.get("ports") or {})}
        given[role] = set(parameters)
        plant[role] = table
    return {**data, "plant": plant}, given


def read_component(path: Path, component: str
                   ) -> tuple[Path, dict[str, Any], dict[str, Any]] | None:
    """(extracted FMU path, parameters, port map) of `component` in the SSP archive at path;
    None when the archive has no such component. ValueError (one line) for a bad archive."""
    try:
        data = path.read_bytes()
        archive = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise ValueError(f"no such file {str(path)!r}") from None
    except (OSError, zipfile.BadZipFile) as error:
        raise ValueError(f"{path.name}: not an SSP archive ({error})") from None
    with archive:
        try:
            text = archive.read("SystemStructure.ssd")
        except KeyError:
            raise ValueError(f"{path.name}: no SystemStructure.ssd") from None
        try:  # the SSP 1.0 schema, as FMPy ships it
            from fmpy.ssp.ssd import validate_tree

            root = etree.fromstring(text)
            validate_tree(root, "SystemStructureDescription.xsd")
        except Exception as error:  # noqa: BLE001 - lxml's syntax and FMPy's schema errors
            lines = [line for line in str(error).splitlines() if line.strip()]
            raise ValueError(f"{path.name}: not a valid SSP 1.0 system structure: "
                             f"{lines[-1] if lines else type(error).__name__}") from None
        system = root.find(f"{{{SSD}}}System")
        found = [c for c in system.iter(f"{{{SSD}}}Component") if c.get("name") == component]
        if not found:
            return None
        element = found[0]
        source = element.get("source", "")
        if element.get("type", "application/x-fmu-sharedlibrary") != \
                "application/x-fmu-sharedlibrary" or not source.endswith(".fmu"):
            raise ValueError(f"{path.name}: component {component!r} is not an FMU ({source!r})")
        fmu = _extract(archive, data, source, path.name)
        parameters = _parameters(archive, element, path.name, component)
        ports = _ports(system, component, path.name)
    return fmu, parameters, ports


def _extract(archive: zipfile.ZipFile, data: bytes, source: str, name: str) -> Path:
    """The component's FMU, written once under the FMU cache per archive content."""
    from fmus.builder import fmu_dir

    try:
        content = archive.read(source)
    except KeyError:
        raise ValueError(f"{name}: the component's FMU {source!r} is not in the archive") \
            from None
    target = fmu_dir() / "ssp" / hashlib.sha256(data).hexdigest()[:12] / Path(source).name
    if not target.is_file() or target.read_bytes() != content:
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".part")
        partial.write_bytes(content)
        partial.replace(target)
    return target


def _parameters(archive, element, name: str, component: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    bindings = element.find(f"{{{SSD}}}ParameterBindings")
    for binding in [] if bindings is None else bindings.findall(f"{{{SSD}}}ParameterBinding"):
        if binding.find(f"{{{SSD}}}ParameterMapping") is not None:
            raise ValueError(f"{name}: component {component!r} has a parameter mapping, which "
                             "excosim cannot map; give the values themselves")
        inline = binding.find(f"{{{SSD}}}ParameterValues")
        if inline is not None:
            root = inline.find(f"{{{SSV}}}ParameterSet")
        else:
            source = binding.get("source", "")
            try:
                root = etree.fromstring(archive.read(source))
            except KeyError:
                raise ValueError(f"{name}: parameter set {source!r} of component "
                                 f"{component!r} is not in the archive") from None
        for parameter in root.iter(f"{{{SSV}}}Parameter"):
            for kind, convert in _VALUE_TYPES.items():
                value = parameter.find(f"{{{SSV}}}{kind}")
                if value is not None:
                    out[parameter.get("name")] = convert(value.get("value"))
                    break
    return out


def _ports(system, component: str, name: str) -> dict[str, Any]:
    """role port -> connector name, or {variable, scale, offset} with a transformation."""
    ports: dict[str, Any] = {}
    prefix = f"{component}."
    for connection in system.iter(f"{{{SSD}}}Connection"):
        start = (connection.get("startElement"), connection.get("startConnector"))
        end = (connection.get("endElement"), connection.get("endConnector"))
        if start[0] is None and end[0] == component:
            outer, inner, into = start[1], end[1], True
        elif end[0] is None and start[0] == component:
            outer, inner, into = end[1], start[1], False
        else:
            continue
        if not outer.startswith(prefix):
            continue
        port = outer[len(prefix):]
        if port in ports:
            raise ValueError(f"{name}: port {outer!r} is connected twice")
        transformations = [child for child in connection if child.tag.startswith(f"{{{SSC}}}")]
        if not transformations:
            ports[port] = inner
            continue
        linear = transformations[0]
        if linear.tag != f"{{{SSC}}}LinearTransformation" or len(transformations) > 1:
            raise ValueError(f"{name}: connection of {outer!r} has a "
                             f"{etree.QName(linear).localname}, which excosim cannot map (only "
                             "a LinearTransformation)")
        factor = float(linear.get("factor", "1"))
        offset = float(linear.get("offset", "0"))
        if factor == 0.0:
            raise ValueError(f"{name}: connection of {outer!r} has a factor of 0")
        # into the FMU: fmu = factor si + offset, so si = fmu / factor - offset / factor
        scale, shift = (1.0 / factor, -offset / factor) if into else (factor, offset)
        ports[port] = {"variable": inner, "scale": scale, "offset": shift}
    return ports
