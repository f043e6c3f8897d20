"""Fuzz worker of tests/test_fmu_conformance.py: drives one FMU through seeded random call sequences
with hostile values, in a process of its own, so a crash fails the test instead of killing pytest.

    python tests/fmu_fuzz.py FMU_PATH FMI_VERSION SEED N_SEQUENCES

Each sequence instantiates, sets random parameters and inputs (0, negative, 1e-300, 1e308, NaN,
inf among plausible ones), initializes (reading outputs in initialization mode on the way), then
steps with random inputs, step sizes (0, 1e-310, 1e-12, 1e3, NaN, inf, negative) and an
occasional FMU state round trip (sometimes corrupted). Every call must return OK or Error, an
Error must log an error message, and an OK call must leave every Real output and calculated
parameter finite. Each call is written to stderr before it runs (the reproducer of a crash: the
lines after the last "sequence" line); the last stdout line is {"sequences", "calls",
"initialized", "steps" (OK ones), "problems"} as JSON.
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from ctypes import byref
from typing import Any

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException

HOSTILE = [0.0, -1.0, 1e-300, -1e-300, 1e308, -1e308, math.nan, math.inf, -math.inf, 1e-12]
STEP_SIZES = [0.0, 1e-310, 1e-12, 1e-3, 0.05, 1e3, math.nan, math.inf, -math.inf, -1e-3]
# A 1e3 s step may legitimately take seconds (HydraulicCylinder: up to 1e8 RK4 substeps), so a
# run takes only this many; later draws of 1e3 become 1 s.
LONG_STEPS = 2
INTEGERS = [0, -1, 1, 2, 2**31 - 1, -(2**31)]
OK, ERROR = 0, 3


class Fuzzer:
    def __init__(self, fmu: str, fmi_version: int, folder: str) -> None:
        self.version = fmi_version
        md = read_model_description(fmu)
        self.variables = md.modelVariables
        self.parameters = [v for v in md.modelVariables if v.causality == "parameter"]
        self.inputs = [v for v in md.modelVariables if v.causality == "input"]
        self.checked = [v.valueReference for v in md.modelVariables if v.type in ("Real", "Float64")
                        and v.causality in ("output", "calculatedParameter")]
        self.errors_logged = self.calls = self.initialized = self.steps = 0
        self.long_steps = LONG_STEPS
        self.problems: list[str] = []
        unzip = extract(fmu, unzipdir=folder)
        identifier = md.coSimulation.modelIdentifier
        if fmi_version == 2:
            from fmpy import calloc, free  # the C allocator, as fmpy's default callbacks use
            from fmpy.fmi2 import (
                FMU2Slave,
                fmi2CallbackAllocateMemoryTYPE,
                fmi2CallbackFreeMemoryTYPE,
                fmi2CallbackFunctions,
                fmi2CallbackLoggerTYPE,
            )
            from fmpy.logging import addLoggerProxy
            self.slave: Any = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                                        modelIdentifier=identifier, instanceName="fuzz")
            self.callbacks = fmi2CallbackFunctions()
            self.callbacks.logger = fmi2CallbackLoggerTYPE(
                lambda env, name, status, category, message: self._logged(status))
            self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            addLoggerProxy(byref(self.callbacks))
        else:
            from fmpy.fmi3 import FMU3Slave
            self.slave = FMU3Slave(guid=md.guid, unzipDirectory=unzip,
                                   modelIdentifier=identifier, instanceName="fuzz")

    def _logged(self, status: int) -> None:
        if status == ERROR:
            self.errors_logged += 1

    def call(self, name: str, *args: Any) -> tuple[bool, Any]:
        """Runs slave.<name>(*args); True when it returned OK."""
        shown = ", ".join(_short(a) for a in args)
        sys.stderr.write(f"{name}({shown})\n")
        self.calls += 1
        before = self.errors_logged
        try:
            return True, getattr(self.slave, name)(*args)
        except FMICallException as exc:
            if exc.status != ERROR:
                self.problems.append(f"{name}{args!r} returned status {exc.status}")
            elif self.errors_logged == before:
                self.problems.append(f"{name}{args!r} returned Error without a logged error")
            return False, None

    def outputs_finite(self, when: str) -> None:
        ok, values = self.call("getReal" if self.version == 2 else "getFloat64", self.checked)
        if ok and not all(math.isfinite(x) for x in values):
            bad = [v.name for v in self.variables if v.valueReference in self.checked
                   and not math.isfinite(values[self.checked.index(v.valueReference)])]
            self.problems.append(f"{when}: OK call left non-finite {bad}")

    def value(self, rng: np.random.Generator, var: Any, hostile: float) -> Any:
        if var.type == "Boolean":
            return bool(rng.integers(2))
        start = float(var.start) if var.start is not None else 0.0
        if var.type in ("Integer", "Int32"):
            return int(rng.choice(INTEGERS)) if rng.random() < hostile else int(start)
        if rng.random() < hostile:
            return float(rng.choice(HOSTILE))
        if var.min is not None and var.max is not None and rng.random() < 0.3:
            return float(rng.uniform(float(var.min), float(var.max)))
        # Near the start value, mostly valid: so that sequences get past initialization. (Not
        # far off it: a valid but extreme HydraulicCylinder, k_relief = 0.1 instead of 5e-9, needs
        # 1e8 substeps, seconds, for any step.)
        return start * float(rng.uniform(0.5, 1.5)) if start else float(rng.normal(0.0, 0.1))

    def set_values(self, rng: np.random.Generator, variables: list, share: float,
                   hostile: float) -> None:
        for var in variables:
            if rng.random() >= share:
                continue
            value = self.value(rng, var, hostile)
            kind = {"Real": "Real", "Float64": "Float64", "Integer": "Integer",
                    "Int32": "Int32"}.get(var.type, "Boolean")
            self.call(f"set{kind}", [var.valueReference], [value])

    def sequence(self, rng: np.random.Generator) -> None:
        if self.version == 2:
            self.slave.instantiate(callbacks=self.callbacks)
        else:
            self.slave.instantiate(logMessage=lambda env, status, category, message:
                                   self._logged(status))
        try:
            self._run(rng)
        finally:
            sys.stderr.write("freeInstance()\n")
            getattr(self.slave, f"fmi{self.version}FreeInstance")(self.slave.component)

    def _run(self, rng: np.random.Generator) -> None:
        hostile = float(rng.choice([0.0, 0.0, 0.05, 0.3]))
        self.set_values(rng, self.parameters, float(rng.choice([0.0, 0.1, 0.5])), hostile)
        self.set_values(rng, self.inputs, 0.7, hostile)
        start = float(rng.choice([0.0, 0.0, 1.5, math.nan]))
        if self.version == 2:
            self.call("setupExperiment", None, start)
            self.call("enterInitializationMode")
        else:
            self.call("enterInitializationMode", None, start)
        time = start if math.isfinite(start) else 0.0
        if rng.random() < 0.7:
            self.outputs_finite("initialization mode")
        self.set_values(rng, self.inputs, 0.3, hostile)
        if not self.call("exitInitializationMode")[0]:
            return
        self.initialized += 1
        self.outputs_finite("after initialization")
        for _ in range(int(rng.integers(1, 10))):
            self.set_values(rng, self.inputs, 0.6, 0.2)
            if rng.random() < 0.15:
                self.state_round_trip(rng)
            h = float(rng.choice(STEP_SIZES)) if rng.random() < 0.5 else 1e-3
            if h >= 1e3:
                h, self.long_steps = (h, self.long_steps - 1) if self.long_steps else (1.0, 0)
            t = time if rng.random() < 0.95 else time + 1.0
            ok, _ = self.call("doStep", t, h)
            if ok:
                time += h
                self.steps += 1
                self.outputs_finite(f"doStep({t!r}, {h!r})")
            elif rng.random() < 0.5:
                self.call("doStep", time, 1e-3)  # after an Error: refused again, no crash
                break
        self.call("terminate")

    def state_round_trip(self, rng: np.random.Generator) -> None:
        ok, state = self.call("getFMUState")
        if not ok:
            return
        ok, data = self.call("serializeFMUState", state)
        if ok:
            data = bytearray(data)
            if rng.random() < 0.5 and data:  # corrupt it: must be refused, never crash
                at, bit = int(rng.integers(len(data))), int(rng.integers(8))
                sys.stderr.write(f"# flip bit {bit} of byte {at}\n")
                data[at] ^= 1 << bit
            ok, restored = self.call("deserializeFMUState", bytes(data))
            if ok:
                self.call("setFMUState", restored)
                self.call("freeFMUState", restored)
                self.outputs_finite("after setFMUState")
        self.call("freeFMUState", state)


def _short(arg: Any) -> str:
    """An argument for the trace: long lists and byte strings abbreviated."""
    if isinstance(arg, list) and len(arg) > 6:
        return f"[{arg[0]!r}, ... {len(arg)} values]"
    if isinstance(arg, bytes):
        return f"<{len(arg)} bytes>"
    return repr(arg)


def main(argv: list[str]) -> None:
    fmu, version, seed, n = argv[0], int(argv[1]), int(argv[2]), int(argv[3])
    with tempfile.TemporaryDirectory(prefix="excosim-fuzz-") as folder:
        fuzzer = Fuzzer(fmu, version, folder)
        for index in range(n):
            sys.stderr.write(f"sequence {index} (seed {seed})\n")
            fuzzer.sequence(np.random.default_rng([seed, index]))
    print(json.dumps({"sequences": n, "calls": fuzzer.calls, "initialized": fuzzer.initialized,
                      "steps": fuzzer.steps, "problems": fuzzer.problems}))


if __name__ == "__main__":
    main(sys.argv[1:])
