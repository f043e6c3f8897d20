"""Field types of the scenario schema, and one-line messages for pydantic's validation errors.

TOML gives typed values (int, float, bool, str, list, table); the scenario accepts them as they
are, without pydantic's lax conversions: a number field takes an int or a float but no string
and no bool; a list of n numbers takes exactly n numbers; nothing takes NaN or infinity.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Any

from pydantic import BeforeValidator, ValidationError
from pydantic_core import PydanticCustomError


def _describe(value: Any) -> str:
    """A short rendering of a bad value for an error message."""
    if isinstance(value, dict):
        return "a table"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _finite_number(value: Any) -> float:
    if not _is_number(value):
        raise PydanticCustomError("number", "expected a number, got {got}",
                                  {"got": _describe(value)})
    if not math.isfinite(value):
        raise PydanticCustomError("number", "expected a finite number, got {got}",
                                  {"got": _describe(value)})
    return float(value)


Number = Annotated[float, BeforeValidator(_finite_number)]
"""A finite float; accepts a TOML integer or float, nothing else."""


def _parameter_value(value: Any) -> bool | int | float:
    if isinstance(value, bool | int):
        return value
    if isinstance(value, float):
        return _finite_number(value)
    raise PydanticCustomError("number", "expected a number or true/false, got {got}",
                              {"got": _describe(value)})


ParameterValue = Annotated[bool | int | float, BeforeValidator(_parameter_value)]
"""An FMU start value: a TOML bool, integer or finite float, kept as it is (the FMU's variable
type decides whether it fits)."""


def numbers(count: int, check: Callable[[float], bool] | None = None,
            requirement: str = "", increasing: bool = False) -> Any:
    """Type of a list of exactly `count` finite numbers, each passing `check` (say `requirement`
    in the message when one does not), strictly increasing if `increasing`."""

    def validate(value: Any) -> tuple[float, ...]:
        if not isinstance(value, list | tuple):
            raise PydanticCustomError("numbers", "expected {count} numbers, got {got}",
                                      {"count": count, "got": _describe(value)})
        if len(value) != count:
            raise PydanticCustomError("numbers", "expected {count} numbers, got {got}",
                                      {"count": count, "got": len(value)})
        floats = tuple(_finite_number(v) for v in value)
        if check is not None and not all(check(v) for v in floats):
            raise PydanticCustomError("numbers", "expected {count} numbers {req}, got {got}",
                                      {"count": count, "req": requirement,
                                       "got": list(floats)})
        if increasing and any(b <= a for a, b in zip(floats, floats[1:], strict=False)):
            raise PydanticCustomError("numbers", "expected {count} strictly increasing numbers, "
                                      "got {got}", {"count": count, "got": list(floats)})
        return floats

    return Annotated[tuple[float, ...], BeforeValidator(validate)]


def first_error(error: ValidationError) -> tuple[str, str]:
    """(dotted field name, one-line reason) of the first problem pydantic found."""
    problem = error.errors(include_url=False)[0]
    field = ".".join(str(part) for part in problem["loc"])
    kind, value = problem["type"], problem.get("input")
    if kind == "extra_forbidden":
        reason = "unknown key"
    elif kind == "missing":
        reason = "required"
    elif kind in ("number", "numbers", "value_error"):
        reason = _lower_first(problem["msg"])
    elif kind == "model_type" or kind == "dict_type":
        reason = f"expected a table, got {_describe(value)}"
    elif kind.startswith("int") or kind.startswith("string") or kind.startswith("bool"):
        wanted = {"int": "an integer", "string": "a string", "bool": "true or false"}
        prefix = kind.split("_")[0]
        if kind.endswith("_type") or kind.endswith("_parsing"):
            reason = f"expected {wanted[prefix]}, got {_describe(value)}"
        else:
            reason = f"{_lower_first(problem['msg'])}, got {_describe(value)}"
    else:
        reason = f"{_lower_first(problem['msg'])}, got {_describe(value)}"
    if len(error.errors()) > 1:
        reason += f" (and {len(error.errors()) - 1} more problem(s))"
    return field or "(top level)", reason


def _lower_first(text: str) -> str:
    text = text.replace("Input should be", "must be").replace("Value error, ", "")
    return text[:1].lower() + text[1:]
