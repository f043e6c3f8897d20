"""The FMUs' own error messages, kept per instance so that a failing FMI call can say why
(fmus.runs.FastSlave: "boom (HydraulicCylinder): fmi2DoStep failed at t = 1.0: a burst hose").
Messages are printed as fmpy prints them, too."""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any

_LAST_ERRORS: dict[bytes, list[str]] = {}  # instance name -> its last error message
_CALLBACKS_2: list = []  # the one FMI 2.0 callbacks structure, made on first use


def recording_callbacks_2(last_error: list[str], instance: str) -> Any:
    """fmpy's FMI 2.0 callbacks (messages printed as fmpy prints them, the variadic arguments
    formatted by fmpy's native proxy) that also keep each instance's last error message, in
    last_error[0] for `instance`. fmpy's proxy holds one Python logger for the whole process,
    so there is one structure, and the instance name tells whose message it is."""
    _LAST_ERRORS[instance.encode("utf-8")] = last_error
    if _CALLBACKS_2:
        return _CALLBACKS_2[0]
    from fmpy import fmi2
    from fmpy.fmi1 import printLogMessage

    def log(component, name, status, category, message) -> None:
        printLogMessage(component, name, status, category, message)
        holder = _LAST_ERRORS.get(name or b"")
        if status >= 3 and holder is not None:  # fmi2Error, fmi2Fatal
            holder[0] = (message or b"").decode("utf-8", "replace")

    callbacks = fmi2.fmi2CallbackFunctions()
    callbacks.logger = fmi2.fmi2CallbackLoggerTYPE(log)
    callbacks.allocateMemory = fmi2.fmi2CallbackAllocateMemoryTYPE(fmi2.calloc)
    callbacks.freeMemory = fmi2.fmi2CallbackFreeMemoryTYPE(fmi2.free)
    try:
        from fmpy.logging import addLoggerProxy

        addLoggerProxy(ctypes.byref(callbacks))
    except (ImportError, OSError, AttributeError):
        pass  # messages then arrive unformatted; ours carry no format arguments
    _CALLBACKS_2.append(callbacks)
    return callbacks


def recording_logger_3(last_error: list[str]) -> Callable[..., None]:
    """fmpy's FMI 3.0 log printer that also keeps the last error message in last_error[0]."""
    from fmpy.fmi3 import printLogMessage

    def log(environment, status, category, message) -> None:
        printLogMessage(environment, status, category, message)
        if status >= 3:  # fmi3Error, fmi3Fatal
            last_error[0] = (message or b"").decode("utf-8", "replace")

    return log
