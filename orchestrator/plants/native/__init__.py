"""The simulated excavator's step loop (coupling.c), bound with ctypes: the one implementation.

`NativeCoupling(...)` packs what the loop reads per step (the arm coupling's stroke tables and
geometry, the arm inertia, the servos' constants and states, the pump's law, the arm
coupling's settings) into coupling.c's struct once; `track(strokes, rates, accelerations,
...)` then runs a stroke reference's steps in one call. The loop steps the four FMUs itself:
through their one-call steps (fmus.runs.NativeStep), or, for a component that converts its
ports, through a callback into Python. It keeps a board of the FMU in a step
(orchestrator.plants.native.board), so that a stuck or crashing FMU is still named.

The arm coupling is implicit (iterated with the cylinders' state rollback, coupling.c's
docstring) when all three cylinder FMUs can get and set their state, else explicit (the cross
inertia from the planned accelerations); `coupling_note` says which, and why.
"""

from __future__ import annotations

import ctypes
import functools
import math
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from orchestrator.plants.arm_coupling import ArmCoupling
from orchestrator.plants.arm_dynamics import ArmInertia
from orchestrator.plants.master import Master
from orchestrator.plants.native.board import LOOP_CODES, Board
from plant_models.geometry import GRAVITY_M_S2
from plant_models.linear_servo import LinearJointServo
from plant_models.servo import JointServo

_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


class _Table(ctypes.Structure):
    _fields_ = [(name, _DOUBLE_P) for name in ("angle", "c1", "c2", "c3", "arm", "arm_slope")] \
        + [("inv_dx", ctypes.c_double), ("intervals", ctypes.c_long)]


class _Servo(ctypes.Structure):
    _fields_ = [("linear", ctypes.c_long)] + [(name, ctypes.c_double) for name in (
        "kp", "kf", "keep", "gain", "mass", "extend", "retract", "least", "per_reserve_extend",
        "per_reserve_retract")] + [
        ("metered", ctypes.c_double * 2), ("pull", ctypes.c_double * 2),
        ("p_tank", ctypes.c_double), ("areas", ctypes.c_double * 2),
        ("compensated", ctypes.c_long), ("per_velocity", ctypes.c_double),
        ("filtered", ctypes.c_double), ("last", ctypes.c_double), ("has_last", ctypes.c_long),
        ("held", ctypes.c_double), ("design_load", ctypes.c_double)]


class _Coupling(ctypes.Structure):
    _fields_ = [
        ("cylinder_out", _DOUBLE_P * 3), ("cylinder_in", _DOUBLE_P * 3),
        ("pile_out", _DOUBLE_P), ("pile_in", _DOUBLE_P),
        ("x_ref", _DOUBLE_P), ("v_ref", _DOUBLE_P), ("a_ref", _DOUBLE_P),
        ("rows", _DOUBLE_P), ("joints", _DOUBLE_P),
        ("n", ctypes.c_long), ("k", ctypes.c_long), ("n_columns", ctypes.c_long),
        ("table", _Table * 3),
        ("lengths", ctypes.c_double * 3), ("foot", ctypes.c_double * 2),
        ("weights", ctypes.c_double * 3), ("coms", (ctypes.c_double * 2) * 3),
        ("masses", ctypes.c_double * 3), ("gravity", ctypes.c_double),
        ("servo", _Servo * 3),
        ("supplied", ctypes.c_long), ("full", ctypes.c_double * 3),
        ("q_max", ctypes.c_double), ("margin", ctypes.c_double), ("ceiling", ctypes.c_double),
        ("power", ctypes.c_double),
        ("servo_every", ctypes.c_long), ("implicit", ctypes.c_long),
        ("max_iterations", ctypes.c_long), ("tolerance", ctypes.c_double),
        ("force", ctypes.c_double * 3), ("previous_force", ctypes.c_double * 3),
        ("mobility", ctypes.c_double * 3),
        ("pose", ctypes.c_double * 30),
    ]


class _Loop(ctypes.Structure):
    _fields_ = [("step", ctypes.c_void_p * 4), ("call", ctypes.c_void_p * 4),
                ("save", ctypes.c_void_p * 3), ("restore", ctypes.c_void_p * 3),
                ("rollback", ctypes.c_void_p * 3),
                ("h", ctypes.c_double), ("steps", ctypes.c_long),
                ("pile_time", ctypes.c_double), ("board", ctypes.c_void_p),
                ("iterations", ctypes.c_long), ("unconverged", ctypes.c_long)]


_STEP_CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double,
                                  ctypes.c_double)
_CALLBACK_FAILED = 0x7ff  # a Python step's code: the exception is kept and raised after the loop
COLUMNS = 41  # the rows' columns without the supply's 3 (simulated_excavator's signals)
_ORDER = ("boom", "stick", "bucket", "pile")  # coupling.c's Loop and Board


@lru_cache(maxsize=1)
def _library() -> ctypes.CDLL | str:
    """The built library, or why it cannot be had (one line)."""
    from fmus.builder import BuildError
    from fmus.shared_library import build_library

    try:
        path = build_library("coupling", Path(__file__).resolve().parent, ("coupling.c",))
    except BuildError as error:
        return str(error).splitlines()[0]
    library = ctypes.CDLL(str(path))
    library.coupling_size.restype = ctypes.c_long
    offsets = (ctypes.c_long * 15)()
    library.coupling_offsets(offsets)
    expected = [getattr(_Coupling, f).offset for f in ("n", "table", "lengths", "servo",
                                                       "supplied", "pose")] \
        + [_Servo.compensated.offset, _Servo.has_last.offset, _Table.inv_dx.offset,
           ctypes.sizeof(_Loop), _Loop.pile_time.offset, _Loop.board.offset,
           _Coupling.force.offset, _Servo.held.offset, _Loop.unconverged.offset]
    if library.coupling_size() != ctypes.sizeof(_Coupling) or list(offsets) != expected:
        return "coupling.c's struct and its binding disagree (rebuild the library)"
    # No argtypes: ctypes then passes the pre-built pointer object as it is (FastSlave).
    library.coupling_run.restype = ctypes.c_long
    return library


IMPLICIT = "implicit: iterated per step with the cylinders' state rollback"


def _explicit(lacking: list[str], role: str | None = None) -> str:
    """Why the arm coupling is explicit, for `role` (None: the plant as a whole)."""
    who = f"{', '.join(lacking)}: the FMU" if role is None else \
        "explicit: this FMU" if role in lacking else f"explicit: {', '.join(lacking)} FMU"
    return (f"{who} cannot get and set its state (canGetAndSetFMUstate), so the arm's cross "
            "inertia comes from the planned accelerations")


def arm_coupling_notes(descriptions: dict[str, object]) -> dict[str, str]:
    """cylinder role -> how the step loop couples the arm's cross inertia into it (IMPLICIT, or
    why it is explicit), from the roles' FMU model descriptions (boom, stick, bucket): the
    coupling is implicit only when every cylinder FMU can get and set its state."""
    lacking = [role for role in _ORDER[:3]
               if not descriptions[role].coSimulation.canGetAndSetFMUstate]
    return {role: _explicit(lacking, role) if lacking else IMPLICIT for role in _ORDER[:3]}


def coupling_note(master: Master) -> str | None:
    """Why the arm coupling of `master`'s cylinders is explicit (one line naming the roles),
    None when it is implicit (every cylinder FMU can roll back its state)."""
    lacking = [name for name in _ORDER[:3] if master[name].rollback is None]
    return _explicit(lacking) if lacking else None


def _pointer(array: np.ndarray):
    return array.ctypes.data_as(_DOUBLE_P)


class NativeCoupling:
    """coupling.c's struct for one plant (see the module docstring): its FMUs (an
    orchestrator.plants.master.Master with components boom, stick, bucket, pile), its
    ArmCoupling and ArmInertia, its three servos (JointServo or LinearJointServo), the pump's
    LoadSensingPump.law_parameters (None: each valve on its own supply), the communication
    step step_s (s), the servos' sample time servo_sample_s (s, a multiple of step_s), and the
    arm coupling's tolerance_rad_s2 (joint acceleration) and max_iterations per step."""

    def __init__(self, master: Master, coupling: ArmCoupling, inertia: ArmInertia,
                 servos: Sequence[JointServo | LinearJointServo],
                 supply_parameters: tuple | None, step_s: float, servo_sample_s: float,
                 tolerance_rad_s2: float = 1e-2, max_iterations: int = 8) -> None:
        library = _library()
        if isinstance(library, str):
            raise ValueError(f"the step loop cannot be built: {library}")
        self._library = library
        self._master, self._servos, self._step_s = master, tuple(servos), float(step_s)
        every = round(servo_sample_s / step_s)  # a whole number: SimulatedExcavatorConfig
        c = _Coupling()
        cylinders = [master[j] for j in _ORDER[:3]]
        pile = master["pile"]
        self._keep = [component.outputs for component in cylinders] \
            + [component.inputs for component in cylinders] + [pile.outputs, pile.inputs]
        for i, component in enumerate(cylinders):
            c.cylinder_out[i] = _pointer(component.outputs)
            c.cylinder_in[i] = _pointer(component.inputs)
        c.pile_out, c.pile_in = _pointer(pile.outputs), _pointer(pile.inputs)
        for i, table in enumerate(coupling.tables):
            arrays = [np.array(getattr(table, name), dtype=float) for name in (
                "angle", "c1", "c2", "c3", "arm", "arm_slope")]
            self._keep += arrays
            c.table[i] = _Table(*[_pointer(a) for a in arrays], table.inv_dx, len(table.c1))
        if coupling._coms != inertia._coms or coupling._lengths != inertia._lengths:
            raise ValueError("the arm coupling and the arm inertia describe different arms")
        c.lengths[:] = coupling._lengths
        c.foot[:] = coupling._foot
        c.weights[:] = coupling._weights
        for i, com in enumerate(coupling._coms):
            c.coms[i][:] = com
        c.masses[:] = inertia._masses
        c.gravity = GRAVITY_M_S2
        for i, servo in enumerate(self._servos):
            _servo_into(servo, c.servo[i])
        c.supplied = supply_parameters is not None
        if supply_parameters is not None:
            fulls, c.q_max, c.margin, c.ceiling, c.power = supply_parameters
            c.full[:] = [-1.0 if full is None else full for full in fulls]
        self.note = coupling_note(master)
        """Why the arm coupling is explicit (coupling_note), None when it is implicit."""
        c.servo_every, c.implicit = every, self.note is None
        c.tolerance, c.max_iterations = float(tolerance_rad_s2), int(max_iterations)
        c.mobility[:] = [-1.0] * 3  # none measured yet (coupling.c then takes a rigid one)
        self._c = c
        self.clock: tuple[int, float] = (0, 0.0)
        """(steps, Pile time s) where the last track() ended, an FMU error included."""
        self.iterations = (0, 0)
        """(cylinder steps of the arm coupling, steps that ended unconverged) since the
        plant started: iterations per step = the first / the plant's step count."""
        self._address = ctypes.addressof(c)
        components = [master[name] for name in _ORDER]
        self._board = Board([_label(component) for component in components])
        self._errors: list[BaseException] = []
        loop = _Loop()
        steps = []
        for i, component in enumerate(components):
            native = component.native_step
            if native is not None:
                loop.step[i], loop.call[i] = native.function_address, native.call_address
            else:  # a component that converts its ports: its Python step, called back
                callback = _STEP_CALLBACK(functools.partial(_python_step, component.step,
                                                            self._errors))
                self._keep.append(callback)
                loop.step[i] = ctypes.cast(callback, ctypes.c_void_p).value
            steps.append(native)
            if i < 3 and component.rollback is not None:
                loop.save[i], loop.restore[i], loop.rollback[i] = component.rollback
        loop.h, loop.board = self._step_s, self._board.address()
        self._loop, self._native_steps = loop, tuple(steps)

    def temporary_folders(self) -> list[str]:
        """The board's folder (orchestrator.plants.native.board), if there is one."""
        return [] if self._board is None else [self._board.folder]

    def close(self) -> None:
        """Remove the board; safe twice. A later track() raises (the FMUs are closed)."""
        board, self._board = self._board, None
        if board is not None:
            board.close()

    def state(self) -> dict[str, list[float]]:
        """What the arm coupling carries from one step to the next, JSON-able: the last
        two steps' cross-inertia forces (N, the last first) and the cylinders' step
        mobilities (s/kg)."""
        return {"force_n": list(self._c.force), "previous_force_n": list(self._c.previous_force),
                "mobility_s_kg": list(self._c.mobility)}

    def set_state(self, state: dict[str, list[float]]) -> None:
        """Continue from a state() (a resumed run); ValueError unless it holds 3 finite
        forces and 3 finite mobilities >= 0."""
        force, previous, mobility = ([float(value) for value in state[key]] for key in (
            "force_n", "previous_force_n", "mobility_s_kg"))
        if not (len(force) == len(previous) == len(mobility) == 3) or not all(
                math.isfinite(value) for value in force + previous + mobility) \
                or any(value < 0.0 and value != -1.0 for value in mobility):
            raise ValueError("an arm coupling state holds 3 finite forces and 3 mobilities "
                             "(>= 0, or -1: none yet)")
        self._c.force[:], self._c.previous_force[:], self._c.mobility[:] = \
            force, previous, mobility

    def track(self, strokes: np.ndarray, rates: np.ndarray, accelerations: np.ndarray,
              n_columns: int, steps: int, pile_time: float) -> tuple[np.ndarray, np.ndarray,
                                                                     int, float]:
        """The steps of one stroke reference (each (n, 3): m, m/s, m/s^2) from the plant's
        step count and Pile time (s): returns the signal rows (n, n_columns), the joint angles
        (n, 3) rad, and the step count and Pile time after them. An FMU's error propagates;
        `clock` then holds the count and time reached, and the servos' states are those of
        the last step the loop computed."""
        if self._board is None or any(
                self._master[name].native_step is not step
                for name, step in zip(_ORDER, self._native_steps, strict=True)):
            raise RuntimeError("the step loop's FMUs are closed")
        c = self._c
        references = [np.ascontiguousarray(a, dtype=float) for a in (strokes, rates,
                                                                    accelerations)]
        n = len(references[0])
        # The C side reads 3 values per step and writes whole rows: shapes checked here.
        if any(a.shape != (n, 3) for a in references):
            raise ValueError(f"stroke reference arrays must be (n, 3), got "
                             f"{[a.shape for a in references]}")
        if n_columns != COLUMNS + 3 * c.supplied:
            raise ValueError(f"{n_columns} signal columns; the coupling writes "
                             f"{COLUMNS + 3 * c.supplied}")
        rows, joints = np.empty((n, n_columns)), np.empty((n, 3))
        c.x_ref, c.v_ref, c.a_ref = (_pointer(a) for a in references)
        c.rows, c.joints, c.n, c.k, c.n_columns = _pointer(rows), _pointer(joints), n, 0, \
            n_columns
        for i, servo in enumerate(self._servos):
            _servo_state_into(servo, c.servo[i])
        loop = self._loop
        board = self._board  # a local: the step watchdog reads it from this frame (board.py)
        loop.steps, loop.pile_time = steps, pile_time
        try:
            code = self._library.coupling_run(ctypes.c_void_p(self._address),
                                              ctypes.c_void_p(ctypes.addressof(loop)))
        finally:
            self._keep_state(loop.steps, loop.pile_time)
        if code == 1:
            raise self._not_finite()
        if code == 2:
            raise self._pile_not_finite(loop.pile_time - self._step_s)
        if code:
            index, call_code = (code >> 16) - 1, code & 0xffff
            if self._errors:
                raise self._errors.pop()
            raise self._native_steps[index].failure(call_code, board.layout.t)
        return rows, joints, loop.steps, loop.pile_time

    def _keep_state(self, steps: int, pile_time: float) -> None:
        """The servos' states back from the struct, and the clock reached."""
        for i, servo in enumerate(self._servos):
            state = self._c.servo[i]
            if isinstance(servo, JointServo):
                servo.set_state(state.filtered, state.last if state.has_last else None,
                                state.held)
            else:
                servo.set_state(state.held)
        self.clock = steps, pile_time
        self.iterations = self._loop.iterations, self._loop.unconverged

    def _pile_not_finite(self, t: float) -> RuntimeError:
        """The Pile's bucket mass or soil force not finite after its step from t (s, its own
        clock): named as the pile's, before the master passes it on as the cylinders' load."""
        pile = self._master["pile"]
        values = ", ".join(f"{name} {float(value)!r}" for name, value in
                           zip(("bucket_mass", "F_y", "F_z"), pile.outputs[:3], strict=True))
        return RuntimeError(f"{_label(pile)}: its output is not finite after its step from "
                            f"t = {t:.6g} s ({values})")

    def _not_finite(self) -> ValueError:
        return ValueError("a cylinder's stroke is not finite: " + ", ".join(
            f"{name} {self._master[name].outputs[0]!r}" for name in ("boom", "stick", "bucket")))


LOOP_CODES.add(NativeCoupling.track.__code__)


def _label(component) -> str:
    native = component.native_step
    return native.label if native is not None else \
        f"{component.name} ({component.description.modelName})"


def _python_step(step, errors: list, call, t: float, h: float) -> int:
    """A component's Python step called back from coupling.c: 0, or _CALLBACK_FAILED with the
    exception kept in `errors` (ctypes would print and drop it)."""
    try:
        step(t, h)
    except BaseException as error:  # noqa: BLE001 - re-raised by track() after the loop
        errors.append(error)
        return _CALLBACK_FAILED
    return 0


def _servo_into(servo: JointServo | LinearJointServo, out: _Servo) -> None:
    """A servo's constants (its __slots__) into coupling.c's Servo."""
    if isinstance(servo, LinearJointServo):
        out.linear, out.kp, out.per_velocity = 1, servo._kp, servo._per_velocity
        return
    for name in ("kp", "kf", "keep", "gain", "mass", "extend", "retract", "least",
                 "per_reserve_extend", "per_reserve_retract", "p_tank", "design_load"):
        setattr(out, name, getattr(servo, f"_{name}"))
    out.metered[:], out.pull[:], out.areas[:] = servo._metered, servo._pull, servo._areas
    out.compensated = bool(servo._compensated)


def _servo_state_into(servo: JointServo | LinearJointServo, out: _Servo) -> None:
    """A servo's state() into coupling.c's Servo."""
    if isinstance(servo, LinearJointServo):
        (out.held,) = servo.state()
        return
    filtered, last, held = servo.state()
    out.filtered, out.has_last = filtered, last is not None
    out.last = 0.0 if last is None else last
    out.held = held
