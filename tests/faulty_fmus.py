"""Our HydraulicCylinder with a fault patched into its step (or its initialization), built into
a test's folder: an FMU that hangs, fails, crashes or exits from a given time on, for the tests
of what a run does then."""

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
# A store through a null pointer that the compiler cannot see is one (a volatile pointer).
SEGFAULT = ("    if (t >= {t}) {{\n        int *volatile nowhere = 0;\n        *nowhere = 1;\n"
            "    }}\n")
EXIT = "    if (t >= {t}) exit(3);\n"
INIT_HANG = "    {{\n        volatile int spin = 1;\n        while (spin) {{\n        }}\n    }}\n"
_INITIALIZE = "int model_initialize(double *v, void *state, const char **error) {\n"


def patched_cylinder(folder: Path, fault: str, t_s: float, name: str) -> Path:
    """folder/<name>.fmu: the cylinder whose step runs `fault` (HANG, FAIL, CRASH: abort(),
    SEGFAULT: a write through a null pointer, EXIT: exit(3)) from t_s on; INIT_HANG: whose
    initialization spins forever (t_s unused)."""
    model = Path(shutil.copytree(MODELS_DIR / "HydraulicCylinder", folder / "HydraulicCylinder"))
    source = (model / "model.c").read_text()
    marker = _INITIALIZE if fault is INIT_HANG else "    (void)t;\n"
    assert source.count(marker) == 1
    patched = fault.format(t=repr(float(t_s)))
    if fault is INIT_HANG:
        patched = marker + patched
    if fault is CRASH:
        patched = "    extern void abort(void);\n" + patched
    elif fault is EXIT:
        patched = "    extern void exit(int);\n" + patched
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
