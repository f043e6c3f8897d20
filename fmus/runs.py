"""Run one FMU over an input series under fmpy (fast low-level path) or under the ecos master.

run_fmpy and fmus.ecos_runs.run_ecospy do the same thing, comparable value for value: start
values (parameters, the inputs' first samples) are set before initialization; then, for k =
0..n-1, the inputs' k-th samples are set and the FMU steps from t_k = k*h to t_k + h. Outputs
are arrays (n + 1,): sample 0 after initialization, sample k after step k. Only Real (FMI 3.0:
Float64) inputs and outputs are exchanged; start values may be real, integer or boolean.
FastSlave and run_fmpy take FMI 2.0 and FMI 3.0 co-simulation FMUs alike; FastSlave's one-call
step carries the FMU's state rollback where it has one (NativeStep, fmus/fast_step).
"""

from __future__ import annotations

import ctypes
import functools
import itertools
import re
import shutil
import tempfile
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmus import fast_step
from fmus.descriptions import model_description
from fmus.fmu_messages import recording_callbacks_2, recording_logger_3
from fmus.run_inputs import check_series as _check_series
from fmus.run_inputs import typed_start_values as _typed_start_values
from fmus.run_inputs import value_kind

__all__ = ["run_fmpy", "FastSlave", "NativeStep", "fmi_major", "value_kind", "REAL_TYPES"]

REAL_TYPES = ("Real", "Float64")  # the FMI 2.0 and FMI 3.0 names of a double


def fmi_major(description) -> int | None:
    """2 or 3 for an FMI 2.0 / 3.0 model description, None for any other version."""
    major = str(description.fmiVersion).split(".")[0]
    return int(major) if major in ("2", "3") else None


# The code objects of FastSlave's step functions, one per instance, each named after its
# instance ("step[boom (HydraulicCylinder)]"): the step watchdog finds a stuck step by its code
# object, and a native crash's faulthandler dump (orchestrator.campaign.isolation; code names,
# no variables) names the FMU that crashed. Weak: freed instances leave nothing behind.
STEP_CODES: weakref.WeakSet = weakref.WeakSet()
_SERIALS = itertools.count()  # one number per FastSlave construction
STEP_NAME = re.compile(r"\bstep\[(?P<label>[^\]]*)\]")  # a step's code name in a dump


@dataclass(frozen=True)
class NativeStep:
    """A FastSlave's step for a loop in C: `function(call, t, h)` (int, fmus/fast_step's
    fmi2_step or fmi3_step) at `function_address`, with `call_address` its bound StepCall;
    `label` names the instance ("boom (HydraulicCylinder)"); `failure(code, t)` is the
    RuntimeError step() raises for the nonzero code a step at t (s) returned."""

    function_address: int
    call_address: int
    label: str
    failure: Callable[[int, float], RuntimeError]
    save_address: int | None = None  # rollback.c's save and restore, the bound Rollback
    restore_address: int | None = None  # (None: the FMU cannot get and set its state)
    rollback_address: int | None = None


def _one_call_failure(label: str, calls: tuple[str, str, str], last_error: list,
                      code: int, t: float) -> RuntimeError:
    failed = code >> 8  # which call (fmi2_step.c): 1 set, 2 step, 3 get, 4 terminate asked;
    if failed == 4:  # rollback.c: 5 get state, 6 set state
        return RuntimeError(f"{label} asked to terminate the simulation at t = {t}")
    said = f": {last_error[0]}" if last_error[0] else ""
    return RuntimeError(f"{label}: {calls[failed - 1]} failed at t = {t}{said}")


class FastSlave:
    """One FMU instance driven through fmpy's raw ctypes functions with pre-allocated buffers.

    `fmu` is a .fmu path (or an extracted FMU's folder) of an FMI 2.0 or 3.0 co-simulation FMU;
    `inputs`/`outputs` are names of Real (FMI 3.0: scalar Float64) variables. After
    construction the instance is initialized; `step(t, h, values)` sets the inputs (shape
    (n_inputs,)), steps and returns the outputs (shape (n_outputs,), a view of an internal
    buffer: copy it to keep it). Given `unzip_dir` (an extracted FMU), instances share that
    folder and its loaded binary; otherwise each instance extracts its own copy and removes it
    on close().
    """

    # Set, step, get in one foreign call (fmus.fast_step); False: three (tests/test_fast_step.py)
    one_call = True

    def __init__(self, fmu: str | Path, inputs: Sequence[str], outputs: Sequence[str],
                 start_values: Mapping[str, float] | None = None,
                 instance_name: str = "instance", unzip_dir: str | Path | None = None) -> None:
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        self.description = model_description(fmu)
        # Read by the step watchdog while the FMU is loaded and initialized
        # (orchestrator.campaign.watchdog.stuck_call): what is being made, and which making.
        self.making = f"{instance_name} ({self.description.modelName})", next(_SERIALS)
        self.fmi_version = fmi_major(self.description)
        if self.fmi_version is None or self.description.coSimulation is None:
            raise ValueError(f"{self.description.modelName} is not an FMI 2.0 or 3.0 "
                             "co-simulation FMU")
        variables = {v.name: v for v in self.description.modelVariables}
        for name in [*inputs, *outputs]:
            variable = variables.get(name)
            if variable is None or variable.type not in REAL_TYPES \
                    or getattr(variable, "dimensions", None):
                raise ValueError(f"{self.description.modelName} has no Real variable '{name}'")
        self._owns_unzip_dir = unzip_dir is None
        self._unzip_dir = str(unzip_dir) if unzip_dir is not None else extract(
            str(fmu), unzipdir=tempfile.mkdtemp(prefix="excosim-fmu-"))
        self.slave = None
        try:
            kind = FMU2Slave if self.fmi_version == 2 else FMU3Slave
            self.slave = kind(guid=self.description.guid, unzipDirectory=self._unzip_dir,
                              modelIdentifier=self.description.coSimulation.modelIdentifier,
                              instanceName=instance_name)
            self._initialize(variables, start_values or {})
        except BaseException:
            if self.slave is not None:
                self.slave.freeInstance()
                self.slave = None
            self._remove_unzip_dir()
            raise
        self._vr = {name: v.valueReference for name, v in variables.items()}
        self._bind(inputs, outputs)
        # The input buffer starts as the instance was initialised (a given start value, else
        # the FMU's own), so a step before any write sets nothing new: an input left alone
        # keeps its start value, e.g. a cylinder's p_pump.
        given = start_values or {}
        self.inputs[:] = [float(given[n]) if n in given else
                          float(variables[n].start) if variables[n].start is not None else 0.0
                          for n in inputs]

    def _bind(self, inputs: Sequence[str], outputs: Sequence[str]) -> None:
        """Our own function pointers into the loaded binary, without fmpy's logging wrapper and
        with pre-converted arguments, bound into argument-free calls: ctypes' per-call argument
        conversion costs more than the FMI call itself (about 2 us versus 0.5 us per
        fmi2GetReal here). FMI 3.0's fmi3SetFloat64 / fmi3GetFloat64 take the value count as
        well, and fmi3DoStep four result flags (pre-allocated here)."""
        dll, version = self.slave.dll, self.fmi_version
        self.native_step: NativeStep | None = None
        """The one-call step for a loop in C (NativeStep), None without fmus.fast_step."""
        names = ("fmi2SetReal", "fmi2GetReal", "fmi2DoStep") if version == 2 else \
            ("fmi3SetFloat64", "fmi3GetFloat64", "fmi3DoStep")
        self._names = names
        set_real, get_real, do_step = (dll._FuncPtr((n, dll)) for n in names)
        component = ctypes.c_void_p(self.slave.component)
        reference = ctypes.c_uint  # fmi2ValueReference and fmi3ValueReference
        vr_in = (reference * len(inputs))(*[self._vr[n] for n in inputs])
        vr_out = (reference * len(outputs))(*[self._vr[n] for n in outputs])
        n_in, n_out = ctypes.c_size_t(len(inputs)), ctypes.c_size_t(len(outputs))
        self.inputs = np.zeros(len(inputs))
        """Input buffer, shape (n_inputs,): write into it and call step(t, h) to skip a copy."""
        self._out = np.zeros(len(outputs))
        in_ptr = self.inputs.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        out_ptr = self._out.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        counts_in, counts_out = ((), ()) if version == 2 else ((n_in,), (n_out,))
        self._set = functools.partial(set_real, component, vr_in, n_in, in_ptr, *counts_in)
        self._get = functools.partial(get_real, component, vr_out, n_out, out_ptr, *counts_out)
        set_inputs, get_outputs, out, inputs = self._set, self._get, self._out, self.inputs
        set_name, get_name, step_name = names
        # Names the instance in step errors, and for the step watchdog
        # (orchestrator.campaign.watchdog), which finds a stuck step by its code object
        # (STEP_CODES) and reads `label` and `t` from its frame.
        label = f"{self.slave.instanceName} ({self.description.modelName})"
        last_error = self._last_error

        def said() -> str:  # what the FMU logged as the reason, if anything
            return f": {last_error[0]}" if last_error[0] else ""
        if version == 2:
            do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
            self._do_step = functools.partial(do_step, component)  # (t, h, 1): bench/
        fast = fast_step.library() if self.one_call else None
        if fast is not None:
            # The three calls in one foreign call (fmus/fast_step/); what the struct points
            # into is held by self.
            self._value_references = vr_in, vr_out
            self._fast = fast_step.StepCall(
                self.slave.component, *(ctypes.cast(f, ctypes.c_void_p).value
                                        for f in (set_real, get_real, do_step)),
                ctypes.addressof(vr_in), len(inputs), self.inputs.ctypes.data,
                ctypes.addressof(vr_out), len(outputs), self._out.ctypes.data)
            one_call = fast.fmi2_step if version == 2 else fast.fmi3_step
            bound = ctypes.c_void_p(ctypes.addressof(self._fast))
            failure = functools.partial(_one_call_failure, label, (
                set_name, step_name, get_name, "", *fast_step.STATE_CALLS[version]), last_error)
            self.rollback, rollback = fast_step.bind_rollback(dll, self.slave.component, version) \
                if self.can_roll_back else (None, {})
            self.native_step = NativeStep(ctypes.cast(one_call, ctypes.c_void_p).value,
                                          bound.value, label, failure, **rollback)

            # `component` a local of the frame, as in the other paths: the step watchdog
            # identifies the instance by it (orchestrator.campaign.watchdog.stuck_step).
            def step(t: float, h: float, values: np.ndarray | None = None, *,
                     component=component) -> np.ndarray:
                if values is not None:
                    inputs[:] = values
                code = one_call(bound, t, h)
                if code:
                    raise failure(code, t)
                return out
        elif version == 2:
            def step(t: float, h: float, values: np.ndarray | None = None) -> np.ndarray:
                if values is not None:
                    inputs[:] = values
                if set_inputs() > 1:
                    raise RuntimeError(f"{label}: {set_name} failed at t = {t}{said()}")
                if do_step(component, t, h, 1) > 1:
                    raise RuntimeError(f"{label}: {step_name} failed at t = {t}{said()}")
                if get_outputs() > 1:
                    raise RuntimeError(f"{label}: {get_name} failed at t = {t}{said()}")
                return out
        else:
            # No argtypes: ctypes then passes the pre-built objects as they are (the doubles
            # as c_double made per call), half the cost of checking pointer argtypes.
            double, no_set_prior = ctypes.c_double, ctypes.c_bool(True)
            terminate = ctypes.c_bool(False)
            event, stop = ctypes.byref(ctypes.c_bool(False)), ctypes.byref(terminate)
            early, last = ctypes.byref(ctypes.c_bool(False)), ctypes.byref(ctypes.c_double(0.0))

            def step(t: float, h: float, values: np.ndarray | None = None) -> np.ndarray:
                if values is not None:
                    inputs[:] = values
                if set_inputs() > 1:
                    raise RuntimeError(f"{label}: {set_name} failed at t = {t}{said()}")
                if do_step(component, double(t), double(h), no_set_prior, event, stop, early,
                           last) > 1:
                    raise RuntimeError(f"{label}: {step_name} failed at t = {t}{said()}")
                if terminate.value:
                    raise RuntimeError(f"{label} asked to terminate the simulation at t = {t}")
                if get_outputs() > 1:
                    raise RuntimeError(f"{label}: {get_name} failed at t = {t}{said()}")
                return out

        # Code objects compare by value: the serial keeps two instances of one name apart.
        name = f"step[{label.replace(']', ')')}]#{self.making[1]}"
        step.__code__ = step.__code__.replace(co_name=name, co_qualname=name)
        STEP_CODES.add(step.__code__)
        self.step = step
        """step(t, h, values=None): set the inputs to `values` (or use `self.inputs` as it is),
        step from t (s) by h (s), return the outputs (the internal buffer)."""

    def run(self, inputs: np.ndarray, h: float, t0: float = 0.0) -> np.ndarray:
        """Step len(inputs) times from t0 (s) by h (s), step k with row k of `inputs` (n,
        n_inputs): the outputs after each step, (n, n_outputs). One foreign call where the
        one-call step serves (fmus/fast_step/steps.c; no Python frame per step, so the step
        watchdog does not see into it), else step by step; the same numbers either way."""
        if self.slave is None:
            raise RuntimeError(f"{self.description.modelName}: the FMU instance is closed")
        series = np.ascontiguousarray(inputs, dtype=float)
        if series.ndim != 2 or series.shape[1] != len(self.inputs):
            raise ValueError(f"inputs must be (n, {len(self.inputs)}), got {series.shape}")
        result = np.empty((len(series), len(self._out)))
        if self.native_step is None:
            for k, row in enumerate(series):
                result[k] = self.step(t0 + k * h, h, row)
            return result
        done = ctypes.c_long(0)
        code = fast_step.library().fmi_steps(
            self.native_step.function_address, self.native_step.call_address,
            series.ctypes.data, result.ctypes.data, len(series), t0, h, ctypes.byref(done))
        if code:
            raise self.native_step.failure(code, t0 + done.value * h)
        return result

    def _initialize(self, variables: dict, start_values: Mapping[str, float]) -> None:
        self._last_error = [""]  # the FMU's last error message, for the step's error
        if self.fmi_version == 2:
            self._callbacks = recording_callbacks_2(self._last_error, self.slave.instanceName)
            self.slave.instantiate(callbacks=self._callbacks)
        else:
            self.slave.instantiate(logMessage=recording_logger_3(self._last_error))
        if self.fmi_version == 2:
            self.slave.setupExperiment(startTime=0.0)
        for name, value in _typed_start_values(self.description, start_values).items():
            # setReal / setInteger / setBoolean (FMI 2.0), setFloat64 / setInt32 / ... (3.0)
            getattr(self.slave, f"set{variables[name].type}")([variables[name].valueReference],
                                                              [value])
        if self.fmi_version == 2:
            self.slave.enterInitializationMode()
        else:
            self.slave.enterInitializationMode(startTime=0.0)
        self.slave.exitInitializationMode()

    def outputs(self) -> np.ndarray:
        """Current outputs, shape (n_outputs,) (internal buffer)."""
        if self._get() > 1:
            raise RuntimeError(f"{self._names[1]} failed")
        return self._out

    def read(self, names: Sequence[str]) -> np.ndarray:
        """Current values (n,) of any Real (Float64) variables, by name (fmpy's checked call)."""
        references = [self._vr[n] for n in names]
        getter = self.slave.getReal if self.fmi_version == 2 else self.slave.getFloat64
        return np.array(getter(references))

    @property
    def can_roll_back(self) -> bool:  # canGetAndSetFMUstate: what repeating a step needs
        return bool(self.description.coSimulation.canGetAndSetFMUstate)

    @property
    def can_serialize_state(self) -> bool:  # the FMU can get, set and serialize its state
        return bool(self.can_roll_back and self.description.coSimulation.canSerializeFMUstate)

    def serialize_state(self) -> bytes:
        """The instance's whole state as the FMU serializes it (fmi2SerializeFMUstate /
        fmi3SerializeFMUState): what restore_state takes, in this or another instance."""
        state = self.slave.getFMUState()
        try:
            return self.slave.serializeFMUState(state)
        finally:
            self.slave.freeFMUState(state)

    def restore_state(self, data: bytes) -> None:
        """Put the instance into a state from serialize_state. The FMU checks the bytes first
        (ours refuse another build's, a truncated or a corrupted state, and leave the instance
        as it was): fmpy's exception on refusal; the FMU logs why."""
        state = (self.slave.deSerializeFMUstate if self.fmi_version == 2
                 else self.slave.deserializeFMUState)(bytes(data))
        try:
            self.slave.setFMUState(state)
        finally:
            self.slave.freeFMUState(state)
        self.outputs()  # the output buffer from the restored values, as a step leaves it

    def close(self) -> str | None:
        """Terminate and free the instance, unload the binary, remove the unzip folder; safe
        twice. None, or one line when its fmiXTerminate failed though it had logged no error
        before (after an error FMI lets terminate fail): "pile (Pile): fmi2Terminate failed: .."."""
        self.native_step, failure = None, None  # nothing may step the freed instance from C
        if self.slave is not None:
            fast_step.free_rollback(getattr(self, "rollback", None))  # before the instance
            label, before = f"{self.slave.instanceName} ({self.description.modelName})", \
                self._last_error[0]
            try:
                self.slave.terminate()
            except Exception as error:  # noqa: BLE001 - the instance must still be freed
                failure = None if before else f"{label}: fmi{self.fmi_version}Terminate " \
                    f"failed: {self._last_error[0] or str(error).splitlines()[0]}"
            finally:
                self.slave.freeInstance()
                self.slave = None
                self._remove_unzip_dir()
        return failure

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
        result[1:] = slave.run(series, step_size)
    return {name: result[:, i] for i, name in enumerate(outputs)}
