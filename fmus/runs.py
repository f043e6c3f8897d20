"""Run one FMU over an input series under fmpy (fast low-level path) or under the ecos master.

Both runners do the same thing, so their results can be compared value for value:
start values (parameters, and the inputs' first samples) are set before initialization; then,
for k = 0..n-1, the inputs' k-th samples are set and the FMU steps from t_k = k*h to t_k + h.
Outputs come back as arrays of shape (n + 1,): sample 0 after initialization, sample k after
step k. Only Real inputs and outputs are exchanged; start values may be Real, Integer or Boolean.

run_ecospy needs the `ecospy` and `tbb` packages (test extra); it loads libtbb itself.
"""

from __future__ import annotations

import ctypes
import shutil
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = ["run_fmpy", "run_ecospy", "load_ecospy", "FastSlave"]


def _check_series(inputs: Mapping[str, np.ndarray]) -> int:
    lengths = {len(np.asarray(series)) for series in inputs.values()}
    if len(lengths) != 1 or 0 in lengths:
        raise ValueError("inputs must be non-empty 1-D series of equal length (one per step)")
    return lengths.pop()


def _typed_start_values(description, start_values: Mapping[str, float]) -> dict:
    types = {v.name: v.type for v in description.modelVariables}
    typed = {}
    for name, value in start_values.items():
        if name not in types:
            raise ValueError(f"{description.modelName} has no variable '{name}'")
        convert = {"Real": float, "Integer": int, "Boolean": bool}.get(types[name])
        if convert is None:
            raise ValueError(f"variable '{name}' has unsupported type {types[name]}")
        typed[name] = convert(value)
    return typed


class FastSlave:
    """One FMU instance driven through fmpy's raw ctypes functions with pre-allocated buffers.

    `fmu` is a .fmu path; `inputs`/`outputs` are Real variable names. After construction the
    instance is initialized; `step(t, h, values)` sets the inputs (shape (n_inputs,)), steps and
    returns the outputs (shape (n_outputs,), a view of an internal buffer: copy it to keep it).
    Given `unzip_dir` (an extracted FMU), instances share that folder and its loaded binary;
    otherwise each instance extracts its own copy and removes it on close().
    """

    def __init__(self, fmu: str | Path, inputs: Sequence[str], outputs: Sequence[str],
                 start_values: Mapping[str, float] | None = None,
                 instance_name: str = "instance", unzip_dir: str | Path | None = None) -> None:
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2ValueReference

        self.description = read_model_description(str(fmu))
        variables = {v.name: v for v in self.description.modelVariables}
        for name in [*inputs, *outputs]:
            if name not in variables or variables[name].type != "Real":
                raise ValueError(f"{self.description.modelName} has no Real variable '{name}'")
        self._owns_unzip_dir = unzip_dir is None
        self._unzip_dir = str(unzip_dir) if unzip_dir is not None else extract(
            str(fmu), unzipdir=tempfile.mkdtemp(prefix="excosim-fmu-"))
        self.slave = None
        try:
            self.slave = FMU2Slave(guid=self.description.guid, unzipDirectory=self._unzip_dir,
                                   modelIdentifier=self.description.coSimulation.modelIdentifier,
                                   instanceName=instance_name)
            self._initialize(variables, start_values or {})
        except BaseException:
            if self.slave is not None:
                self.slave.freeInstance()
                self.slave = None
            self._remove_unzip_dir()
            raise

        # Our own function pointers into the loaded binary, without fmpy's logging wrapper and
        # with pre-converted arguments: ctypes' per-call argument conversion costs more than
        # the FMI call itself (about 2 us versus 0.5 us per fmi2GetReal here).
        dll = self.slave.dll
        self._set_real = dll._FuncPtr(("fmi2SetReal", dll))
        self._get_real = dll._FuncPtr(("fmi2GetReal", dll))
        self._do_step = dll._FuncPtr(("fmi2DoStep", dll))
        self._do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        self._component = ctypes.c_void_p(self.slave.component)
        self._vr_in = (fmi2ValueReference * len(inputs))(
            *[variables[n].valueReference for n in inputs])
        self._vr_out = (fmi2ValueReference * len(outputs))(
            *[variables[n].valueReference for n in outputs])
        self._n_in, self._n_out = ctypes.c_size_t(len(inputs)), ctypes.c_size_t(len(outputs))
        self.inputs = np.zeros(len(inputs))
        """Input buffer, shape (n_inputs,): write into it and call step(t, h) to skip a copy."""
        self._out = np.zeros(len(outputs))
        self._in_ptr = self.inputs.ctypes.data_as(ctypes.POINTER(fmi2Real))
        self._out_ptr = self._out.ctypes.data_as(ctypes.POINTER(fmi2Real))

    def _initialize(self, variables: dict, start_values: Mapping[str, float]) -> None:
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        for name, value in _typed_start_values(self.description, start_values).items():
            vr = [variables[name].valueReference]
            setter = {float: self.slave.setReal, int: self.slave.setInteger,
                      bool: self.slave.setBoolean}[type(value)]
            setter(vr, [value])
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def outputs(self) -> np.ndarray:
        """Current outputs, shape (n_outputs,) (internal buffer)."""
        if self._get_real(self._component, self._vr_out, self._n_out, self._out_ptr) > 1:
            raise RuntimeError("fmi2GetReal failed")
        return self._out

    def step(self, t: float, h: float, values: np.ndarray | None = None) -> np.ndarray:
        """Set the inputs to `values` (or use `self.inputs` as it is), step from t (s) by h (s),
        return the outputs."""
        if values is not None:
            self.inputs[:] = values
        if self._set_real(self._component, self._vr_in, self._n_in, self._in_ptr) > 1:
            raise RuntimeError(f"fmi2SetReal failed at t = {t}")
        if self._do_step(self._component, t, h, 1) > 1:
            raise RuntimeError(f"fmi2DoStep failed at t = {t}")
        return self.outputs()

    def close(self) -> None:
        """Terminate and free the instance, unload the binary, remove the unzip folder."""
        if self.slave is not None:
            try:
                self.slave.terminate()
            except Exception:  # an instance in error state must still be freed
                pass
            finally:
                self.slave.freeInstance()
                self.slave = None
                self._remove_unzip_dir()

    def _remove_unzip_dir(self) -> None:
        if self._owns_unzip_dir:
            shutil.rmtree(self._unzip_dir, ignore_errors=True)

    def __enter__(self) -> FastSlave:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def run_fmpy(fmu: str | Path, inputs: Mapping[str, np.ndarray], outputs: Sequence[str],
             step_size: float, start_values: Mapping[str, float] | None = None
             ) -> dict[str, np.ndarray]:
    """Run `fmu` under fmpy for len(series) steps of step_size (s); see the module docstring.

    inputs: {Real input name: array of shape (n,)}; returns {output name: array (n + 1,)}.
    """
    n = _check_series(inputs)
    series = np.column_stack([np.asarray(s, dtype=float) for s in inputs.values()])
    start = {**{k: float(s[0]) for k, s in inputs.items()}, **dict(start_values or {})}
    result = np.empty((n + 1, len(outputs)))
    with FastSlave(fmu, list(inputs), list(outputs), start) as slave:
        result[0] = slave.outputs()
        for k in range(n):
            result[k + 1] = slave.step(k * step_size, step_size, series[k])
    return {name: result[:, i] for i, name in enumerate(outputs)}


def load_ecospy():
    """Import ecospy, first loading libtbb from the environment's lib folder (global symbols)."""
    if "ecospy" not in sys.modules:
        for folder in (Path(sys.prefix) / "lib", Path(sys.base_prefix) / "lib"):
            candidates = sorted(folder.glob("libtbb.so.*"))
            if candidates:
                ctypes.CDLL(str(candidates[0]), mode=ctypes.RTLD_GLOBAL)
                break
    import ecospy

    return ecospy


def run_ecospy(fmu: str | Path, inputs: Mapping[str, np.ndarray], outputs: Sequence[str],
               step_size: float, start_values: Mapping[str, float] | None = None
               ) -> dict[str, np.ndarray]:
    """Same as run_fmpy, with the ecos co-simulation master stepping the FMU."""
    from fmpy import read_model_description

    ecospy = load_ecospy()
    ecospy.EcosLib.set_log_level("warn")
    n = _check_series(inputs)
    description = read_model_description(str(fmu))
    start = {**{k: float(s[0]) for k, s in inputs.items()}, **dict(start_values or {})}
    typed = _typed_start_values(description, start)
    result = np.empty((n + 1, len(outputs)))
    structure = ecospy.EcosSimulationStructure()
    try:
        structure.add_model("fmu", str(fmu))
        structure.add_parameter_set("start", {f"fmu::{k}": v for k, v in typed.items()})
        sim = ecospy.EcosSimulation(structure=structure, step_size=step_size)
        try:
            if not sim.init(parameter_set="start"):
                raise RuntimeError(f"ecos failed to initialize: {ecospy.EcosLib.get_last_error()}")
            in_ids = [f"fmu::{name}" for name in inputs]
            out_ids = [f"fmu::{name}" for name in outputs]
            columns = [np.asarray(s, dtype=float) for s in inputs.values()]
            result[0] = [sim.get_real(i) for i in out_ids]
            for k in range(n):
                for identifier, column in zip(in_ids, columns, strict=True):
                    sim.set_real(identifier, float(column[k]))
                sim.step()
                result[k + 1] = [sim.get_real(i) for i in out_ids]
            sim.terminate()
        finally:
            sim.free()
    finally:
        structure.free()
    return {name: result[:, i] for i, name in enumerate(outputs)}
