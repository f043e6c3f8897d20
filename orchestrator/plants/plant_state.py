"""What of the simulated excavator carries from one period to the next, saved at a period's end
and restored into a new plant, so that a resumed run (`excosim run --resume`,
orchestrator.campaign.resume) continues as if it had never stopped.

Carried over (orchestrator.plants.simulated_excavator):

- each FMU instance (boom, stick, bucket, pile): its whole state as the FMU serializes it
  (fmi2SerializeFMUstate / fmi3SerializeFMUState): strokes, pressures, the trench, the time;
- each servo's pressure-feedback filter (plant_models.servo.JointServo.state: the high-passed
  force and the last force sample; the linear servo carries nothing);
- the load cell's noise generator (numpy's bit generator state);
- the cylinders' step count and the pile's time (the start times of the next FMU steps);
- the pose the FMUs were instantiated at: a restore instantiates them there, as the first
  period did, then puts each into its saved state.

Not saved: the components' input buffers (the step loop writes every input before the step
that reads it, but p_pump and p_LS on the constant supply: they keep their start values, which
a restored instance starts from again) and everything computed from the configuration
(couplings, servo designs), which the scenario rebuilds.

The state is JSON-able (`resume_state`), format STATE_FORMAT::

    {"format": 2, "fmus": {component: base64 of the serialized FMU state},
     "servos": {joint: [...]},
     "arm_coupling": {"force_n": [3], "previous_force_n": [3], "mobility_s_kg": [3]},
     "load_cell_rng": {...}, "steps": int, "pile_time_s": float,
     "start_pose_rad": [boom, stick, bucket]}

("arm_coupling": what the step loop's arm coupling carries from step to step,
orchestrator.plants.native.NativeCoupling.state; format 1, before the servo held its command
and the coupling was iterated, is not read.)
"""

from __future__ import annotations

import base64
import binascii
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from plant_models.linkage import JOINT_NAMES

STATE_FORMAT = 2


class ResumableState:
    """resume_state() and restore_state() of orchestrator.plants.simulated_excavator's plant
    (a mixin: it reads the plant's master, servos, generator and step counters)."""

    def resume_state(self) -> dict[str, Any] | None:
        """The plant's state now, JSON-able (module docstring); None before the first period,
        after close(), or when one of the FMUs cannot serialize its state."""
        master = self._master
        if master is None or self._closed:
            return None
        components = master.components
        if not all(component.can_save_state for component in components.values()):
            return None
        return {
            "format": STATE_FORMAT,
            "fmus": {name: base64.b64encode(component.save_state()).decode("ascii")
                     for name, component in components.items()},
            "servos": {joint: list(servo.state())
                       for joint, servo in zip(JOINT_NAMES, self._servos, strict=True)},
            "arm_coupling": self._loop.state(),
            "load_cell_rng": self._rng.bit_generator.state,
            "steps": self._steps,
            "pile_time_s": self._pile_time,
            "start_pose_rad": [float(angle) for angle in self._start_pose],
        }

    def restore_state(self, state: Mapping[str, Any]) -> None:
        """Continue from a resume_state() of a plant of the same configuration. Only on a plant
        that has not started yet (no period dug). The FMUs validate their states (ours refuse
        another build's, a truncated or a corrupted one). ValueError naming what is wrong: the
        field, or the component whose FMU refused its state (the FMU logs why)."""
        if self._master is not None:
            raise ValueError("restore_state: the plant has started already")
        fields = _checked(state)
        self._start(np.asarray(fields["start_pose_rad"], dtype=float))
        components = self._master.components
        saved = fields["fmus"]
        if set(saved) != set(components):
            raise ValueError(f"the state holds FMU states of {', '.join(sorted(saved))}; the "
                             f"plant has {', '.join(components)}")
        for name, component in components.items():
            try:
                data = base64.b64decode(saved[name], validate=True)
            except (binascii.Error, ValueError, TypeError):
                raise ValueError(f"{name}: its saved FMU state is not base64") from None
            try:
                component.restore_state(data)
            except Exception as error:  # fmpy raises plain Exceptions for FMI error statuses
                raise ValueError(f"{name}: its FMU refused the saved state") from error
        servos = fields["servos"]
        if set(servos) != set(JOINT_NAMES):
            raise ValueError(f"the state holds servo states of {', '.join(sorted(servos))}; "
                             f"the plant's servos are {', '.join(JOINT_NAMES)}")
        for joint, servo in zip(JOINT_NAMES, self._servos, strict=True):
            values = servos[joint]
            try:
                servo.set_state(*values)
            except (TypeError, ValueError, OverflowError):
                raise ValueError(f"{joint}: servo state {values!r} does not fit its "
                                 f"{type(servo).__name__}") from None
        coupling = fields["arm_coupling"]
        try:
            self._loop.set_state(coupling)
        except (TypeError, ValueError, KeyError, OverflowError):
            raise ValueError(f"arm_coupling state {coupling!r} is not 3 forces (N) and 3 "
                             "mobilities (s/kg)") from None
        try:
            self._rng.bit_generator.state = fields["load_cell_rng"]
        except (TypeError, ValueError, KeyError, OverflowError) as error:
            raise ValueError(f"load_cell_rng is not a state of this generator ({error})"
                             ) from None
        self._steps, self._pile_time = fields["steps"], fields["pile_time_s"]


def _checked(state: Any) -> Mapping[str, Any]:
    """The state's fields, checked for presence and type; ValueError naming the first bad one."""
    if not isinstance(state, Mapping):
        raise ValueError(f"the plant state is a {type(state).__name__}, not an object")
    if state.get("format") != STATE_FORMAT:
        raise ValueError(f"plant state format {state.get('format')!r}; this version reads "
                         f"{STATE_FORMAT}")
    kinds = {"fmus": Mapping, "servos": Mapping, "arm_coupling": Mapping,
             "load_cell_rng": Mapping, "steps": int,
             "pile_time_s": float, "start_pose_rad": list}
    for name, kind in kinds.items():
        value = state.get(name)
        if not isinstance(value, kind) or isinstance(value, bool):
            raise ValueError(f"plant state field {name!r} is missing or not a "
                             f"{kind.__name__}")
    if state["steps"] < 0 or not (math.isfinite(state["pile_time_s"])
                                  and state["pile_time_s"] >= 0.0):
        raise ValueError("plant state: steps and pile_time_s must be >= 0")
    pose = state["start_pose_rad"]
    if len(pose) != 3 or not all(isinstance(a, float) and math.isfinite(a) for a in pose):
        raise ValueError("plant state field 'start_pose_rad' must be 3 finite angles (rad)")
    if not all(isinstance(values, list) for values in state["servos"].values()):
        raise ValueError("plant state field 'servos' must map each joint to a list")
    return state
