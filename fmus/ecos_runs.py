"""One FMU over an input series under the ecos co-simulation master (ecospy), the peer of
fmus.runs.run_fmpy: the same start values, steps and output samples, so the two compare value
for value (tests/test_fmu_checks.py, bench/). Needs the `ecospy` and `tbb` packages (test
extra); load_ecospy loads libtbb itself.
"""

from __future__ import annotations

import ctypes
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from fmus.runs import _check_series, _typed_start_values

__all__ = ["run_ecospy", "load_ecospy"]


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
