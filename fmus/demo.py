"""Brief simulations of every FMU with fmpy, summarised in a few lines per model."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from fmus.builder import build, model_names

__all__ = ["demo"]


def _run(fmu: Path, stop_time: float, inputs: dict[str, float], start: dict[str, float]):
    import fmpy  # imported here: building FMUs must not need fmpy's simulation stack

    signals = None
    if inputs:
        dtype = [("time", float)] + [(name, float) for name in inputs]
        values = tuple(inputs.values())
        signals = np.array([(0.0, *values), (stop_time, *values)], dtype=dtype)
    return fmpy.simulate_fmu(str(fmu), stop_time=stop_time, step_size=1e-3, output_interval=1e-3,
                             input=signals, start_values=start)


def _start_values(fmu: Path) -> dict[str, float]:
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
            if v.start is not None and v.type == "Real"}


def _cylinder(fmu: Path) -> list[str]:
    lines = []
    cases = (("extends, no load", 1.0, 0.0, 0.2), ("extends against 200 kN", 1.0, 2e5, 0.2),
             ("retracts, no load", -1.0, 0.0, 1.1))
    for label, u, load, x0 in cases:
        r = _run(fmu, 1.0, {"u": u, "F_ext": load}, {"x0": x0})
        lines.append(f"  u={u:+.0f} {label}: x {x0:.2f} -> {r['x'][-1]:.3f} m, "
                     f"v = {r['v'][-1]:+.3f} m/s, p_A = {r['p_A'][-1] / 1e6:.2f} MPa, "
                     f"p_B = {r['p_B'][-1] / 1e6:.2f} MPa")
    start = _start_values(fmu)
    r = _run(fmu, 1.0, {"u": 1.0, "F_ext": 0.0}, {"x0": 1.1})
    lines.append(f"  u=+1 into the end stop: x = {r['x'][-1]:.3f} m (stroke {start['stroke']:g}), "
                 f"p_A = {r['p_A'][-1] / 1e6:.2f} MPa (supply {start['p_supply'] / 1e6:g}, "
                 f"relief {start['p_relief'] / 1e6:g})")
    return lines


def _pile(fmu: Path) -> list[str]:
    """One bucket pass through the ground, then a dump; mass bookkeeping at the end."""
    import fmpy

    duration, n = 2.0, 2001
    t = np.linspace(0.0, duration, n)
    s = t / duration
    signals = np.zeros(n, dtype=[("time", float), ("tip_y", float), ("tip_z", float),
                                 ("bucket_angle", float), ("dump", float)])
    signals["time"], signals["tip_y"] = t, -10.0 + 2.5 * s
    signals["tip_z"], signals["bucket_angle"] = 0.5 - 1.3 * np.sin(np.pi * s), 2.3 - 1.2 * s
    signals["dump"] = s > 0.9
    r = fmpy.simulate_fmu(str(fmu), stop_time=duration, step_size=1e-3, output_interval=1e-3,
                          input=signals)
    peak = int(np.argmax(r["bucket_mass"]))
    total = r["pile_mass"][-1] + r["bucket_mass"][-1] + r["dumped_mass"][-1]
    return [f"  bucket pass 0.8 m deep, y -10 -> -7.5 m: bucket_mass peaks at "
            f"{r['bucket_mass'][peak]:.2f} kg (t = {r['time'][peak]:.2f} s), "
            f"peak soil force |F| = {np.hypot(r['F_y'], r['F_z']).max() / 1e3:.2f} kN",
            f"  after the dump: dumped_mass = {r['dumped_mass'][-1]:.2f} kg; pile + bucket + "
            f"dumped = {total:.6f} kg (initial {r['pile_mass'][0]:.6f} kg)"]


def _generic(fmu: Path) -> list[str]:
    """Outputs after 1 s at the start inputs; arrays h[1..n] as their range."""
    r = _run(fmu, 1.0, {}, {})
    scalars: list[str] = []
    arrays: dict[str, list[float]] = {}
    for name in r.dtype.names[1:]:
        match = re.fullmatch(r"(\w+)\[\d+\]", name)
        if match:
            arrays.setdefault(match.group(1), []).append(float(r[name][-1]))
        else:
            scalars.append(f"{name} = {float(r[name][-1]):.4g}")
    parts = scalars + [f"{n}[1..{len(v)}] in [{min(v):.4g}, {max(v):.4g}]"
                       for n, v in arrays.items()]
    return ["  after 1 s at the start inputs: " + ", ".join(parts)]


DEMOS: dict[str, Callable[[Path], list[str]]] = {"HydraulicCylinder": _cylinder, "Pile": _pile}


def demo() -> str:
    """Build every FMU, simulate each briefly with fmpy; return a few lines of text per model."""
    lines = []
    for name in model_names():
        fmu = build(name)
        lines.append(f"{name} ({fmu})")
        try:
            lines += DEMOS.get(name, _generic)(fmu)
        except (KeyError, ValueError):  # the model's variables changed: fall back
            lines += _generic(fmu)
    return "\n".join(lines)
