"""Our HydraulicCylinder with a fault patched into its step (or its initialization), built into
a test's folder: an FMU that hangs, fails, crashes or exits from a given time on, for the tests
of what a run does then; our Pile whose soil force is NaN once the bucket cuts, or whose
fmi2Terminate fails."""

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


PILE_NAN = "pile_nan"  # F_y NaN from t = 3 s on, the step reported as good
PILE_TERMINATE_ERROR = "pile_terminate_error"  # fmi2Terminate logs an error, returns fmi2Error
# Both faults are in the FMI layer, which checks every value a step computes (a NaN from the
# model fails the step there, naming the pile): so a patched copy of fmus/common is compiled in,
# as a foreign FMU without that check would behave.
_LAYER_FAULTS = {
    PILE_NAN: ("layer_core.h", "    swap = c->state, c->state = c->scratch_state, "
               "c->scratch_state = swap;\n    c->time = t + h;\n",
               "    if (t >= 3.0) c->v[VR_F_y] = NAN; /* test fault */\n"),
    PILE_TERMINATE_ERROR: ("fmi2_cs.c", "    c->phase = PHASE_TERMINATED;\n",
                           "    LOG_ERROR(c, \"fmi2Terminate: a stuck valve (test fault)\");\n"
                           "    return fmi2Error;\n"),
}


def patched_pile(folder: Path, fault: str, name: str) -> Path:
    """folder/<name>.fmu: our Pile, its FMI layer with `fault` (PILE_NAN, PILE_TERMINATE_ERROR)."""
    from fmus import builder

    model = Path(shutil.copytree(MODELS_DIR / "Pile", folder / "Pile"))
    common = Path(shutil.copytree(builder.COMMON_DIR, folder / "common"))
    file, marker, added = _LAYER_FAULTS[fault]
    source = (common / file).read_text()
    assert source.count(marker) == 1
    (common / file).write_text(source.replace(marker, marker + added))
    original, builder.COMMON_DIR = builder.COMMON_DIR, common
    try:
        return _build(model, folder, name)
    finally:
        builder.COMMON_DIR = original


def _build(model: Path, folder: Path, name: str) -> Path:
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
    return _build(model, folder, name)
