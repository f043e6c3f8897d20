"""The reference pages, generated from the code: every scenario key (the pydantic models of
orchestrator.scenario), every CLI command and option (the typer app, walked as click sees it)
and every run-log channel field (orchestrator.runlog.schemas and plan_scene).

Types, defaults, ranges and units come from the code. A meaning comes from the code where it has
one (a CLI option's help, a JSON schema's description) and otherwise from
docs/reference/descriptions.toml, keyed by the code's own names; `undocumented()` lists every
item that has neither, and tests/test_docs.py fails on any (and on a description whose item the
code no longer has). docs/hooks.py puts the tables into the pages as mkdocs builds them.
"""

from __future__ import annotations

import inspect
import tomllib
import types
import typing
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DESCRIPTIONS = ROOT / "docs" / "reference" / "descriptions.toml"
ROLES = ("boom", "stick", "bucket", "pile")
JOINTS = ("boom", "stick", "bucket")
# Keys read before the pydantic models see the data: `base` by orchestrator.scenario.files,
# the SSP keys by orchestrator.ssp.read (they become the role's fmu, parameters and ports).
FILE_KEYS = ("base", "plant.ssp", "plant.<role>.ssp", "plant.<role>.component")
# Unit of a name by its suffix, longest first (the project's naming convention: SI or the file
# unit in the name).
UNITS = (
    ("_deg_s3", "deg/s^3"), ("_deg_s2", "deg/s^2"), ("_deg_s", "deg/s"), ("_rad_s2", "rad/s^2"),
    ("_rad_s", "rad/s"), ("_m_per_kg", "m/kg"), ("_kg_m2", "kg/m^2"), ("_kg2_m4", "kg^2/m^4"),
    ("_l_min", "L/min"), ("_m_s", "m/s"), ("_m3", "m^3"), ("_kg", "kg"), ("_deg", "deg"),
    ("_rad", "rad"), ("_hz", "Hz"), ("_Pa", "Pa"), ("_pa", "Pa"), ("_bar", "bar"), ("_kN", "kN"),
    ("_N", "N"), ("_w", "W"), ("_ms", "ms"), ("_s", "s"), ("_m", "m"),
)


def unit_of(name: str) -> str:
    for suffix, unit in UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def descriptions(path: Path = DESCRIPTIONS) -> dict[str, dict[str, str]]:
    return tomllib.loads(path.read_text())


# --- scenario keys -----------------------------------------------------------------------------

def _model_of(annotation) -> type | None:
    from pydantic import BaseModel

    for candidate in (annotation, *typing.get_args(annotation)):
        if inspect.isclass(candidate) and issubclass(candidate, BaseModel):
            return candidate
    return None


def _type_name(annotation) -> str:
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return _type_name(args[0])
    if origin is typing.Literal:
        return "string"
    if origin in (typing.Union, types.UnionType):
        names = [_type_name(a) for a in args if a is not type(None)]
        return " or ".join(dict.fromkeys(names))
    if origin is tuple:
        return f"list of {_type_name(args[0])}s"
    if origin is dict:
        return "table"
    if inspect.isclass(annotation) and getattr(annotation, "model_fields", None):
        return "table"
    return {bool: "boolean", int: "integer", float: "number", str: "string"}.get(
        annotation, getattr(annotation, "__name__", str(annotation)))


def _range(field) -> str:
    parts = []
    for item in field.metadata:
        for attribute, sign in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
            value = getattr(item, attribute, None)
            if value is not None and abs(value) < 2**62:
                parts.append(f"{sign} {getattr(item, attribute)}")
    annotation = field.annotation
    for candidate in (annotation, *typing.get_args(annotation)):
        if typing.get_origin(candidate) is typing.Literal:
            parts.append("one of " + ", ".join(f'"{a}"' for a in typing.get_args(candidate)))
    inner = [meta for arg in typing.get_args(annotation)
             if typing.get_origin(arg) is typing.Annotated for meta in arg.__metadata__]
    for item in (*field.metadata, *inner):  # orchestrator.scenario.values.numbers: its checks
        closure = _closure(getattr(item, "func", None))
        if "count" in closure:
            parts.append(" ".join(filter(None, (
                f"{closure['count']} numbers", closure.get("requirement"),
                "strictly increasing" if closure.get("increasing") else ""))))
    return ", ".join(parts)


def _closure(function) -> dict:
    if function is None or not getattr(function, "__closure__", None):
        return {}
    return {name: cell.cell_contents
            for name, cell in zip(function.__code__.co_freevars, function.__closure__,
                                  strict=True)}


def _flat(data: dict, prefix: str = "") -> dict[str, object]:
    flat = {}
    for key, value in data.items():
        if isinstance(value, dict) and key not in ("parameters", "ports", "piston_areas"):
            flat.update(_flat(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _preset_defaults() -> dict[str, dict[str, object]]:
    from orchestrator.scenario.model import preset_defaults
    from plant_models import presets

    return {name: _flat(preset_defaults(name)) for name in presets.NAMES}


def _shown(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_shown(v) for v in value) + "]"
    return repr(value).replace("'", '"')


def _default(field, key: str = "", defaults: dict | None = None) -> str:
    from pydantic_core import PydanticUndefined

    if field.default is PydanticUndefined:
        given = {name: values[key] for name, values in (defaults or {}).items()
                 if key in values and not isinstance(values[key], dict)}
        if given and len({repr(v) for v in given.values()}) == 1:
            return f"preset: `{_shown(next(iter(given.values())))}`"
        if given:
            return "; ".join(f"{name}: `{_shown(value)}`" for name, value in given.items())
        return "the file's stem" if key == "name" else "from the preset"
    if field.default is None:
        return "absent"
    return f"`{field.default!r}`".replace("'", '"')


def scenario_keys() -> list[dict[str, str]]:
    """One row per key of a scenario file (the four plant roles share `plant.<role>.*`)."""
    from orchestrator.scenario.model import Scenario

    rows: dict[str, dict[str, str]] = {}
    defaults = _preset_defaults()

    def walk(model, prefix: str) -> None:
        for name, field in model.model_fields.items():
            key = prefix + (field.alias or name)
            for role in ROLES:
                key = key.replace(f"plant.{role}.", "plant.<role>.")
                key = key if key != f"plant.{role}" else "plant.<role>"
            sub = _model_of(field.annotation)
            rows.setdefault(key, {
                "key": key, "type": _type_name(field.annotation),
                "unit": "" if sub else unit_of(name), "default": _default(field, key, defaults),
                "range": _range(field), "description": field.description or ""})
            if sub is not None:
                walk(sub, key + ".")

    walk(Scenario, "")
    for key in FILE_KEYS:
        rows[key] = {"key": key, "type": "string", "unit": "", "default": "absent", "range": "",
                     "description": ""}
    order = [row["key"] for row in rows.values()]
    return sorted(rows.values(), key=lambda row: order.index(row["key"].rsplit(".", 1)[0])
                  if "." in row["key"] and row["key"].rsplit(".", 1)[0] in order
                  else order.index(row["key"]))


# --- CLI ---------------------------------------------------------------------------------------

def cli_commands() -> list[tuple[str, str, list[dict[str, str]]]]:
    """(command path, its help, one row per option and argument) for every command."""
    import click
    import typer

    from orchestrator.cli.app import app

    found = []

    def walk(command, path: str) -> None:
        context = click.Context(command, info_name=path)
        rows = []
        for param in command.params:
            if param.name == "help" or getattr(param, "hidden", False):
                continue
            kind = "argument" if isinstance(param, click.Argument) else "option"
            names = param.opts + param.secondary_opts if kind == "option" else [param.name.upper()]
            default = param.default if kind == "option" and not param.required else None
            rows.append({"name": ", ".join(names), "kind": kind,
                         "type": "flag" if getattr(param, "is_flag", False)
                         else getattr(getattr(param, "type", None), "name", "text"),
                         "default": "" if default in (None, False, ()) or callable(default)
                         else f"`{default}`", "required": "yes" if param.required else "",
                         "description": " ".join((getattr(param, "help", None) or "").split())})
        found.append((path, " ".join((command.help or "").split()), rows))
        if hasattr(command, "list_commands"):
            for name in command.list_commands(context):
                walk(command.get_command(context, name), f"{path} {name}")

    walk(typer.main.get_command(app), "excosim")
    return found


# --- run-log channels --------------------------------------------------------------------------

def _message_rows(message) -> list[dict[str, str]]:
    rows = []
    for field in message.fields + message.repeated:
        name = field
        for joint in JOINTS if message.name in ("JointState", "DisplaySample") else ():
            name = name.replace(f"_{joint}_", "_<joint>_")
        rows.append({"field": name, "repeated": "repeated" if field in message.repeated else "",
                     "unit": unit_of(field) or ("1" if field == "u" else ""),
                     "key": f"{message.full_name}.{name}"})
    return list({row["field"]: row for row in rows}.values())


def _json_rows(schema: dict, prefix: str, title: str) -> list[dict[str, str]]:
    rows = []
    for name, spec in schema.get("properties", {}).items():
        shown = "<joint>" if name in JOINTS else name
        path = f"{prefix}{shown}"
        if any(row["field"] == path for row in rows):
            continue
        rows.append({"field": path, "repeated": spec.get("type", ""), "unit": unit_of(name),
                     "key": f"{title}.{path}", "schema_text": spec.get("description", "")})
        rows.extend(_json_rows(spec, path + ".", title))
        if isinstance(spec.get("items"), dict):
            rows.extend(_json_rows(spec["items"], path + "[].", title))
    return rows


def channels() -> list[dict]:
    """One entry per channel: topic, schema, when, and its fields with units and meaning."""
    from orchestrator.runlog import schemas
    from orchestrator.runlog.plan_scene import PERIOD_START_SCHEMA

    text = descriptions().get("channels", {})
    found = []
    for topic, schema, when in text["topics"]:
        entry = {"topic": topic, "schema": schema, "when": when, "fields": []}
        message = next((m for m in schemas.MESSAGES if m.full_name == schema), None)
        if message is not None:
            entry["fields"] = _message_rows(message)
        json_schema = {"excosim.PeriodSummary": schemas.PERIOD_SUMMARY_SCHEMA,
                       "excosim.PeriodStart": PERIOD_START_SCHEMA,
                       "excosim.ResumeState": schemas.RESUME_STATE_SCHEMA}.get(schema)
        if json_schema is not None:
            entry["fields"] = _json_rows(json_schema, "", schema)
        for row in entry["fields"]:
            row["description"] = row.pop("schema_text", "") or text.get("fields", {}).get(
                row["key"], "")
        found.append(entry)
    return found


# --- what lacks a description ------------------------------------------------------------------

def undocumented(text: dict | None = None) -> list[str]:
    """Every scenario key, CLI command, option or argument and channel field without a meaning,
    and every description of an item the code does not have."""
    text = descriptions() if text is None else text
    scenario = text.get("scenario", {})
    missing = [f"scenario key {row['key']}" for row in scenario_keys()
               if not (row["description"] or scenario.get(row["key"]))]
    known = {row["key"] for row in scenario_keys()}
    missing += [f"stale description of scenario key {key}" for key in scenario if key not in known]
    for path, help_text, rows in cli_commands():
        if not help_text:
            missing.append(f"command {path}")
        missing += [f"{row['kind']} {row['name']} of {path}" for row in rows
                    if not row["description"]]
    fields = text.get("channels", {}).get("fields", {})
    keys = set()
    for entry in channels():
        for row in entry["fields"]:
            keys.add(row["key"])
            if not (row["description"] or fields.get(row["key"])):
                missing.append(f"field {row['field']} of {entry['topic']} ({entry['schema']})")
    missing += [f"stale description of field {key}" for key in fields if key not in keys]
    return missing


# --- Markdown ----------------------------------------------------------------------------------

def _cell(value: str) -> str:
    return value.replace("|", "\\|").replace("\n", " ")


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_cell(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def scenario_markdown() -> str:
    text = descriptions().get("scenario", {})
    rows = [(f"`{row['key']}`", row["type"], row["unit"], row["default"], row["range"],
             row["description"] or text.get(row["key"], "")) for row in scenario_keys()]
    return _table(("key", "type", "unit", "default", "range", "meaning"), rows)


def cli_markdown() -> str:
    parts = []
    for path, help_text, rows in cli_commands():
        parts.append(f"## `{path}`\n\n{help_text}\n")
        if rows:
            parts.append(_table(("option", "type", "default", "required", "meaning"), [
                (f"`{row['name']}`", row["type"], row["default"], row["required"],
                 row["description"]) for row in rows]))
    return "\n".join(parts)


def channels_markdown() -> str:
    parts = []
    for entry in channels():
        parts.append(f"## `{entry['topic']}`\n\nSchema `{entry['schema']}`; one message per "
                     f"{entry['when']}.\n")
        if entry["fields"]:
            parts.append(_table(("field", "kind", "unit", "meaning"), [
                (f"`{row['field']}`", row["repeated"], row["unit"], row["description"])
                for row in entry["fields"]]))
    return "\n".join(parts)


GENERATORS = {"scenario-keys": scenario_markdown, "cli": cli_markdown,
              "channels": channels_markdown}

if __name__ == "__main__":
    for item in undocumented():
        print(item)
