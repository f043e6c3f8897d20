"""The simulated excavator's per-step coupling in C (coupling.c), bound with ctypes.

`NativeCoupling(...)` packs what the plant's Python loop reads per step (the arm coupling's
stroke tables and geometry, the arm inertia, the servos' constants and filter states, the
pump's law) into coupling.c's struct once; `track(strokes, rates, accelerations, ...)` then
runs a period's steps in one call of coupling.c's loop, which steps the four FMUs itself
through their one-call steps (fmus.runs.NativeStep): Python's per-step work (six foreign calls
and the loop) was about 4 us of a step's 16. The loop keeps a board of the FMU in a step
(orchestrator.plants.native.board), so that a stuck or crashing FMU is still named. Where an
FMU has no one-call step (no fmus.fast_step; a component that converts its ports steps
through Python), the steps run in Python with one call to the coupling before the Pile's step
and one after it. Either way it gives the same bits as the Python loop
(orchestrator.plants.coupling_loop.PythonCoupling; tests/test_native_coupling.py).

`unavailable(servos)` says why the C coupling cannot serve (one line), None when it can: it
needs gcc (the library is built on first use and cached like the FMUs: fmus.shared_library)
and servos that are plant_models.servo.JointServo (the linear servo runs in Python).
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from orchestrator.plants.arm_coupling import ArmCoupling
from orchestrator.plants.arm_dynamics import ArmInertia
from orchestrator.plants.master import Master
from orchestrator.plants.native.board import LOOP_CODES, Board
from plant_models.geometry import GRAVITY_M_S2
from plant_models.servo import JointServo

_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


class _Table(ctypes.Structure):
    _fields_ = [(name, _DOUBLE_P) for name in ("angle", "c1", "c2", "c3", "arm", "arm_slope")] \
        + [("inv_dx", ctypes.c_double), ("intervals", ctypes.c_long)]


class _Servo(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in (
        "kp", "kf", "keep", "gain", "mass", "extend", "retract", "least", "per_reserve_extend",
        "per_reserve_retract")] + [
        ("metered", ctypes.c_double * 2), ("pull", ctypes.c_double * 2),
        ("p_tank", ctypes.c_double), ("areas", ctypes.c_double * 2),
        ("compensated", ctypes.c_long), ("filtered", ctypes.c_double),
        ("last", ctypes.c_double), ("has_last", ctypes.c_long)]


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
        ("pose", ctypes.c_double * 30),
    ]


class _Loop(ctypes.Structure):
    _fields_ = [("step", ctypes.c_void_p * 4), ("call", ctypes.c_void_p * 4),
                ("h", ctypes.c_double), ("steps", ctypes.c_long),
                ("pile_time", ctypes.c_double), ("board", ctypes.c_void_p)]


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
    offsets = (ctypes.c_long * 12)()
    library.coupling_offsets(offsets)
    expected = [getattr(_Coupling, f).offset for f in ("n", "table", "lengths", "servo",
                                                       "supplied", "pose")] \
        + [_Servo.compensated.offset, _Servo.has_last.offset, _Table.inv_dx.offset,
           ctypes.sizeof(_Loop), _Loop.pile_time.offset, _Loop.board.offset]
    if library.coupling_size() != ctypes.sizeof(_Coupling) or list(offsets) != expected:
        return "coupling.c's struct and its binding disagree (rebuild the library)"
    # No argtypes: ctypes then passes the pre-built pointer object as it is (FastSlave).
    library.coupling_before_pile.restype = ctypes.c_int
    library.coupling_after_pile.restype = None
    library.coupling_run.restype = ctypes.c_long
    return library


def unavailable(servos: Sequence[object]) -> str | None:
    """Why the C coupling cannot step a plant with these servos (one line), None if it can."""
    if not all(type(servo) is JointServo for servo in servos):
        return "a servo is not plant_models.servo.JointServo (the linear servo runs in Python)"
    library = _library()
    return library if isinstance(library, str) else None


def _pointer(array: np.ndarray):
    return array.ctypes.data_as(_DOUBLE_P)


class NativeCoupling:
    """coupling.c's struct for one plant (see the module docstring): its FMUs (an
    orchestrator.plants.master.Master with components boom, stick, bucket, pile), its
    ArmCoupling and ArmInertia, its three JointServos, the pump's
    LoadSensingPump.law_parameters (None: each valve on its own supply) and the communication
    step step_s (s)."""

    def __init__(self, master: Master, coupling: ArmCoupling, inertia: ArmInertia,
                 servos: Sequence[JointServo], supply_parameters: tuple | None,
                 step_s: float) -> None:
        self._library = _library()
        self._master, self._servos, self._step_s = master, tuple(servos), float(step_s)
        c = _Coupling()
        cylinders = [master[j] for j in ("boom", "stick", "bucket")]
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
            fulls, c.q_max, c.margin, c.ceiling = supply_parameters
            c.full[:] = [-1.0 if full is None else full for full in fulls]
        self._c = c
        self.clock: tuple[int, float] = (0, 0.0)
        """(steps, Pile time s) where the last track() ended, an FMU error included."""
        address = ctypes.addressof(c)
        self._before = _bound(self._library.coupling_before_pile, address)
        self._after = _bound(self._library.coupling_after_pile, address)
        steps = [master[name].native_step for name in _ORDER]
        self._board: Board | None = None
        self.loop_note: str | None = None
        """Why the FMUs are stepped from Python (one line), None when coupling.c's loop
        steps them."""
        if any(step is None for step in steps):
            self.loop_note = "an FMU has no one-call step (no fmus.fast_step, or its " \
                "component converts ports): the FMUs step from Python"
            return
        self._board = Board([step.label for step in steps])
        loop = _Loop()
        loop.step[:] = [step.function_address for step in steps]
        loop.call[:] = [step.call_address for step in steps]
        loop.h, loop.board = self._step_s, self._board.address()
        self._loop, self._native_steps = loop, tuple(steps)
        self._run = functools.partial(self._library.coupling_run, ctypes.c_void_p(address),
                                      ctypes.c_void_p(ctypes.addressof(loop)))

    def temporary_folders(self) -> list[str]:
        """The board's folder (orchestrator.plants.native.board), if there is one."""
        return [] if self._board is None else [self._board.folder]

    def close(self) -> None:
        """Remove the board; safe twice. The loop in C is gone with it: a later track() steps
        the FMUs from Python (and so meets their own state, e.g. closed)."""
        board, self._board = self._board, None
        if board is not None:
            board.close()

    def track(self, strokes: np.ndarray, rates: np.ndarray, accelerations: np.ndarray,
              n_columns: int, steps: int, pile_time: float) -> tuple[np.ndarray, np.ndarray,
                                                                     int, float]:
        """The steps of one stroke reference (each (n, 3): m, m/s, m/s^2) from the plant's
        step count and Pile time (s): returns the signal rows (n, n_columns), the joint angles
        (n, 3) rad, and the step count and Pile time after them. An FMU's error propagates;
        `clock` then holds the count and time reached, and the servos' filter states are
        those of the last step the coupling computed (as in the Python loop)."""
        c = self._c
        references = [np.ascontiguousarray(a, dtype=float) for a in (strokes, rates,
                                                                    accelerations)]
        n = len(references[0])
        # The C side reads 3 values per step and writes whole rows: shapes checked here.
        if any(a.shape != (n, 3) for a in references):
            raise ValueError(f"stroke reference arrays must be (n, 3), got "
                             f"{[a.shape for a in references]}")
        if n_columns != 34 + 3 * c.supplied:
            raise ValueError(f"{n_columns} signal columns; the coupling writes "
                             f"{34 + 3 * c.supplied}")
        rows, joints = np.empty((n, n_columns)), np.empty((n, 3))
        c.x_ref, c.v_ref, c.a_ref = (_pointer(a) for a in references)
        c.rows, c.joints, c.n, c.k, c.n_columns = _pointer(rows), _pointer(joints), n, 0, \
            n_columns
        for i, servo in enumerate(self._servos):
            filtered, last = servo.state()
            c.servo[i].filtered, c.servo[i].has_last = filtered, last is not None
            c.servo[i].last = 0.0 if last is None else last
        in_c = self._board is not None \
            and all(self._master[name].native_step is step
                    for name, step in zip(_ORDER, self._native_steps, strict=True))
        run = self._run_in_c if in_c else self._run_in_python
        steps, pile_time = run(n, steps, pile_time)
        return rows, joints, steps, pile_time

    def _run_in_c(self, n: int, steps: int, pile_time: float) -> tuple[int, float]:
        """coupling.c's loop over the n steps: (step count, Pile time s) after them."""
        loop = self._loop
        board = self._board  # a local: the step watchdog reads it from this frame (board.py)
        loop.steps, loop.pile_time = steps, pile_time
        try:
            code = self._run()
        finally:
            self._keep_state(loop.steps, loop.pile_time)
        if code == 1:
            raise self._not_finite()
        if code:
            raise self._native_steps[(code >> 16) - 1].failure(code & 0xffff,
                                                               board.layout.t)
        return self.clock

    def _run_in_python(self, n: int, steps: int, pile_time: float) -> tuple[int, float]:
        """The n steps with the FMUs stepped from Python between the coupling's two calls."""
        master, h = self._master, self._step_s
        boom, stick, bucket, pile = (master[name].step for name in _ORDER)
        before, after = self._before, self._after
        try:
            for _ in range(n):
                if before():
                    raise self._not_finite()
                pile(pile_time, h)
                pile_time += h
                after()
                t = steps * h
                boom(t, h)
                stick(t, h)
                bucket(t, h)
                steps += 1
        finally:
            self._keep_state(steps, pile_time)
        return self.clock

    def _keep_state(self, steps: int, pile_time: float) -> None:
        """The servos' filter states back from the struct, and the clock reached."""
        for i, servo in enumerate(self._servos):
            state = self._c.servo[i]
            servo.set_state(state.filtered, state.last if state.has_last else None)
        self.clock = steps, pile_time

    def _not_finite(self) -> ValueError:
        return ValueError("a cylinder's stroke is not finite: " + ", ".join(
            f"{name} {self._master[name].outputs[0]!r}" for name in ("boom", "stick", "bucket")))


LOOP_CODES.add(NativeCoupling._run_in_c.__code__)


def _servo_into(servo: JointServo, out: _Servo) -> None:
    """JointServo's constants (its __slots__) into coupling.c's Servo."""
    for name in ("kp", "kf", "keep", "gain", "mass", "extend", "retract", "least",
                 "per_reserve_extend", "per_reserve_retract", "p_tank"):
        setattr(out, name, getattr(servo, f"_{name}"))
    out.metered[:], out.pull[:], out.areas[:] = servo._metered, servo._pull, servo._areas
    out.compensated = bool(servo._compensated)


def _bound(function, address: int):
    """function(struct) with the pointer converted once (ctypes' argument conversion costs
    more than the call)."""
    return functools.partial(function, ctypes.c_void_p(address))
