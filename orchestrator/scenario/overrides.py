"""`--set KEY=VALUE` overrides of a scenario, applied to its TOML data before validation.

KEY is dotted (`plant.pile.parameters.density`); VALUE is read as a TOML value (`5`, `0.5`,
`true`, `[100, 100, 100]`, `"text"`), and anything that is not one is taken as a plain string
(`--set machine.preset=lab`).

>>> apply_overrides({"periods": 20}, ["periods=5", "plant.pile.parameters.density=1800"], "f")
{'periods': 5, 'plant': {'pile': {'parameters': {'density': 1800}}}}
"""

from __future__ import annotations

import copy
import re
import tomllib
from collections.abc import Mapping, Sequence
from typing import Any

from orchestrator.scenario.errors import ScenarioError

_KEY_PART = re.compile(r"[A-Za-z0-9_-]+")


def parse_override(item: str) -> tuple[list[str], Any]:
    """('a.b.c', value) from 'a.b.c=VALUE'; ValueError (one line) for a malformed item."""
    key, sep, text = item.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ValueError(f"--set {item!r}: expected KEY=VALUE, e.g. periods=5")
    parts = key.split(".")
    for part in parts:
        if not _KEY_PART.fullmatch(part):
            raise ValueError(f"--set {item!r}: bad key {key!r} (dotted names of letters, digits, "
                             "_ and -)")
    text = text.strip()
    try:
        value = tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        value = text
    except RecursionError:
        raise ValueError(f"--set {key}: the value is nested too deeply") from None
    return parts, value


def apply_overrides(data: Mapping[str, Any], items: Sequence[str], source: str) -> dict:
    """A copy of `data` with every `KEY=VALUE` item set, in order.

    Raises ValueError (a ScenarioError naming `source` when it is available) for a malformed item
    or a key that runs through a value that is not a table.
    """

    result = copy.deepcopy(dict(data))
    for item in items:
        try:
            parts, value = parse_override(item)
        except ValueError as error:
            raise ScenarioError(source, "", str(error)) from None
        table = result
        for depth, part in enumerate(parts[:-1]):
            below = table.setdefault(part, {})
            if not isinstance(below, dict):
                where = ".".join(parts[: depth + 1])
                raise ScenarioError(source, where, f"is not a table, so --set {item!r} cannot "
                                    "set a key inside it")
            table = below
        table[parts[-1]] = value
    return result
