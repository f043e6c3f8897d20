"""What a cylinder FMU must agree with before it fills a role, measured on the FMU itself, as its
model description cannot say it (a few hundred steps each, cached per FMU file and settings):

- the load's sign. Positive F_ext resists extension (plant_models.model_spec). With the spool
  closed (u = 0) and the piston at mid-stroke, a step of F_ext = +load_n must push the piston
  in, or leave it where it is (an actuator that ignores its load). An FMU that counts +F_ext as
  pushing the piston out moves it out: the arm's weight would then drive it the wrong way. A
  run without load cannot see this (the identification runs unloaded), so this one loads it.
- the stroke. The piston must reach the linkage's stroke: started 5 % short of it and driven out
  at u = +0.3, it must pass 99.9 % of it before it stops (or 4000 samples pass). A shorter
  cylinder sits on its end stop wherever the linkage needs more.

Both raise ValueError("<role>: <what is wrong and what to set>"), one line.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from plant_models.port_units import PortMap

SETTLE_SAMPLES = 20  # before the load step: the FMU's start transient
LOAD_SAMPLES = 200  # the load step's length
SIGN_TOLERANCE = 1e-6  # of the stroke: a displacement below this is "did not move"
REACH_START = 0.95  # of the linkage's stroke: where the reach test starts
REACH_FRACTION = 0.999  # of the linkage's stroke: what the piston must pass
REACH_COMMAND = 0.3
REACH_SAMPLES = 4000
SAMPLES_PER_STEP = 10  # the checks sample at step_s / 10, as the identification does

_CACHE: dict[tuple, str | None] = {}


def check_cylinder(role: str, fmu_path: str | Path, ports: Mapping[str, str],
                   parameters: Mapping[str, float | int | bool], stroke_m: float,
                   load_n: float, step_s: float,
                   conversions: Mapping[str, PortMap] | None = None,
                   sample_s: float | None = None) -> None:
    """Run the module docstring's checks on the FMU at fmu_path for cylinder `role`.

    ports: role -> FMU variable (roles u, F_ext, x, x0; a missing role is its own name);
    parameters: start values; stroke_m (m): the linkage's stroke; load_n (N, > 0): the load of
    the sign test (the arm's static load on this cylinder is a fitting size); step_s (s): the
    communication step; conversions: role -> PortMap of ports whose FMU values are not SI;
    sample_s (s): the step of the checks' runs (default step_s / 10; an FMU that takes only its
    own fixed step is run at it).
    ValueError (one line, starting with `role`) when the FMU fails one."""
    path = Path(fmu_path)
    content = path.read_bytes()
    conversions = dict(conversions or {})
    key = (hashlib.sha256(content).hexdigest(), tuple(sorted(parameters.items())),
           tuple(sorted(ports.items())), tuple(sorted(conversions.items())), float(stroke_m),
           float(load_n), float(step_s), sample_s)
    if key not in _CACHE:
        _CACHE[key] = _problem(role, path, ports, parameters, stroke_m, load_n,
                               sample_s or step_s / SAMPLES_PER_STEP, conversions)
    if _CACHE[key] is not None:
        raise ValueError(f"{role}: {_CACHE[key]}")


def _problem(role: str, path: Path, ports, parameters, stroke_m: float, load_n: float,
             dt: float, conversions: Mapping[str, PortMap]) -> str | None:
    names = {r: ports.get(r, r) for r in ("u", "F_ext", "x", "x0")}
    identity = PortMap("")

    def fmu(role: str, si: float) -> float:
        return conversions.get(role, identity).from_si(si)

    x_map = conversions.get("x", identity)
    inputs = [names["u"], names["F_ext"]]
    start = {**parameters, names["u"]: fmu("u", 0.0), names["F_ext"]: fmu("F_ext", 0.0)}

    def run(x0: float, u: float, load: float, samples: int, stop=None) -> np.ndarray:
        """Strokes (SI) of `samples` steps from x0 with u held and F_ext = load after the
        settle (the sign test) or from the start (load 0)."""
        from fmus.runs import FastSlave

        strokes = []
        # Named as the role: a watchdog that stops a hung instance names it so.
        with FastSlave(path, inputs, [names["x"]], {**start, names["x0"]: fmu("x0", x0)},
                       role, None) as slave:
            for k in range(samples):
                force = load if k >= SETTLE_SAMPLES else 0.0
                out = slave.step(k * dt, dt, np.array([fmu("u", u), fmu("F_ext", force)]))
                strokes.append(x_map.scale * float(out[0]) + x_map.offset)
                if stop is not None and stop(strokes):
                    break
        return np.array(strokes)

    try:
        x = run(0.5 * stroke_m, 0.0, abs(load_n), SETTLE_SAMPLES + LOAD_SAMPLES)
    except Exception as error:  # noqa: BLE001 - fmpy and the FMU raise many kinds
        return (f"the load-sign test (u = 0, F_ext = {abs(load_n) / 1e3:+.3g} kN at x = "
                f"{0.5 * stroke_m:.4g} m) failed: {str(error).splitlines()[0]}")
    moved = float(x[-1] - x[SETTLE_SAMPLES - 1])
    if moved > SIGN_TOLERANCE * stroke_m:
        return (f"its load acts the wrong way: with the spool closed, F_ext = "
                f"{abs(load_n) / 1e3:+.3g} kN moved the piston out by {moved * 1e3:.3g} mm in "
                f"{LOAD_SAMPLES * dt:.3g} s; here a positive F_ext resists extension (pushes "
                f"the piston in). Map the port reversed: ports.F_ext = {{ variable = "
                f"\"{names['F_ext']}\", scale = -1 }}")
    goal = REACH_FRACTION * stroke_m

    def stopped(strokes: list[float]) -> bool:
        return strokes[-1] >= goal or _stalled(strokes, stroke_m)

    begin = REACH_START * stroke_m
    try:
        x = run(begin, REACH_COMMAND, 0.0, REACH_SAMPLES, stopped)
    except Exception as error:  # noqa: BLE001
        return (f"it cannot start at x = {begin:.4g} m, 5 % short of the linkage's stroke "
                f"{stroke_m:.4g} m ({str(error).splitlines()[0]}): is its stroke shorter? Set "
                "its stroke parameter to the linkage's")
    # Stopped short of the goal: on an end stop. Neither there nor stopped (a slow actuator
    # within the samples): nothing is known, nothing is refused.
    if np.all(np.isfinite(x)) and x.max() < goal and _stalled(list(x), stroke_m):
        return (f"its stroke ends at {x.max():.4g} m where the linkage needs {stroke_m:.4g} m "
                f"(driven out at u = +{REACH_COMMAND:g} from {begin:.4g} m, it stopped there): "
                "set its stroke parameter to the linkage's")
    return None


def _stalled(strokes: list[float], stroke_m: float) -> bool:
    """No progress over the last 50 samples."""
    return len(strokes) > 50 and strokes[-1] - strokes[-51] <= SIGN_TOLERANCE * stroke_m


def static_load_n(loads, index: int) -> float:
    """The sign test's load for cylinder `index`: the arm's static load on it (N), at least
    1 N (a joint whose load vanishes at the pose still gets a test)."""
    value = abs(float(loads[index]))
    return value if math.isfinite(value) and value >= 1.0 else 1.0
