"""Our HydraulicCylinder with a fault patched into its step, built into a test's folder: an FMU
that hangs, fails or crashes from a given time on, for the tests of what a run does then."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import fmus
from fmus.builder import MODELS_DIR

HANG = ("    if (t >= {t}) {{\n        volatile int spin = 1;\n"
        "        while (spin) {{\n        }}\n    }}\n")
FAIL = ("    if (t >= {t}) {{\n        *error = \"a burst hose (test fault)\";\n        return 1;\n"
        "    }}\n")
CRASH = "    if (t >= {t}) abort();\n"


def patched_cylinder(folder: Path, fault: str, t_s: float, name: str) -> Path:
    """folder/<name>.fmu: the cylinder whose step runs `fault` (HANG, FAIL, CRASH) from t_s on."""
    model = Path(shutil.copytree(MODELS_DIR / "HydraulicCylinder", folder / "HydraulicCylinder"))
    source = (model / "model.c").read_text()
    marker = "    (void)t;\n"
    assert source.count(marker) == 1
    patched = fault.format(t=repr(float(t_s)))
    if fault is CRASH:
        patched = "    extern void abort(void);\n" + patched
    (model / "model.c").write_text(source.replace(marker, patched))
    old = os.environ.get("EXCOSIM_FMU_DIR")
    os.environ["EXCOSIM_FMU_DIR"] = str(folder / "built")
    try:
        built = fmus.build_model(model)
    finally:
        if old is None:
            del os.environ["EXCOSIM_FMU_DIR"]
        else:
            os.environ["EXCOSIM_FMU_DIR"] = old
    return Path(shutil.copyfile(built, folder / f"{name}.fmu"))
