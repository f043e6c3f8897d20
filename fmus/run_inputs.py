"""The inputs of an FMU run (fmus.runs, fmus.ecos_runs): variable kinds, input series and start
values typed for the FMU."""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np

_INTEGER = re.compile(r"^(Integer|U?Int(8|16|32|64))$")


def value_kind(type_name: str) -> str | None:
    """"Real", "Integer" or "Boolean" for an FMI 2.0 or 3.0 variable type (Float64 and Float32
    are Real, Int8..UInt64 Integer); None for any other (String, Binary, Clock, Enumeration)."""
    if type_name in ("Real", "Float64", "Float32"):
        return "Real"
    if _INTEGER.match(type_name):
        return "Integer"
    return "Boolean" if type_name == "Boolean" else None


def check_series(inputs: Mapping[str, np.ndarray]) -> int:
    """The length n of the input series (one sample per step); ValueError unless they are
    non-empty and of one length."""
    lengths = {len(np.asarray(series)) for series in inputs.values()}
    if len(lengths) != 1 or 0 in lengths:
        raise ValueError("inputs must be non-empty 1-D series of equal length (one per step)")
    return lengths.pop()


def typed_start_values(description, start_values: Mapping[str, float]) -> dict:
    """Start values converted to each variable's kind (float, int, bool); ValueError for a
    name the model lacks or a type it cannot take."""
    types = {v.name: v.type for v in description.modelVariables}
    typed = {}
    for name, value in start_values.items():
        if name not in types:
            raise ValueError(f"{description.modelName} has no variable '{name}'")
        convert = {"Real": float, "Integer": int, "Boolean": bool}.get(value_kind(types[name]))
        if convert is None:
            raise ValueError(f"variable '{name}' has unsupported type {types[name]}")
        typed[name] = convert(value)
    return typed
