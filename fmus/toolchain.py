"""What compiles our C: gcc, its flags, fmpy's FMI headers and the FMU platform folders.

Only a build needs this module's compiler: FMUs and libraries built when the package was built
(fmus.packaged) are used without it. Every function raises BuildError with one clear message.
"""

from __future__ import annotations

import importlib.util
import os
import platform
import shutil
import subprocess
from functools import lru_cache
from pathlib import Path

__all__ = ["BuildError", "FolderError", "CFLAGS", "LIBS", "HEADERS", "fmi_headers", "gcc",
           "gcc_version", "compile_shared", "platform_folder"]

CFLAGS = [
    "-std=c11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden",
    # Reproducible floating point: no fused multiply-add, no fast-math reassociation.
    "-ffp-contract=off",
    "-Wall", "-Wextra", "-Werror", "-Wno-unused-parameter",
]
LIBS = ["-lm"]
# The FMI headers (from fmpy's c-code folder) each version compiles against.
HEADERS = {
    2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
    3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h"),
}
# platform.machine() -> the architecture of FMI 3's platform tuple (as fmpy names it).
_ARCHITECTURES = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "aarch64",
                  "arm64": "aarch64"}


class BuildError(RuntimeError):
    """An FMU could not be built; the message says why (missing gcc, compile error, bad table).
    `exit_status`: 2 when the cause is the user's setting (an FMU folder that cannot be made),
    1 for a failure of the build itself."""

    exit_status = 1


class FolderError(BuildError):
    """The FMU folder ($EXCOSIM_FMU_DIR) cannot be made: the user's setting."""

    exit_status = 2


def platform_folder(fmi_version: int, machine: str | None = None) -> str:
    """The folder under binaries/ that fmpy loads this CPU's binary from: FMI 2.0 `linux64`,
    FMI 3.0 the platform tuple `<arch>-linux` (x86_64-linux, aarch64-linux). `machine`:
    platform.machine() unless given."""
    machine = platform.machine() if machine is None else machine
    architecture = _ARCHITECTURES.get(machine.lower())
    if architecture is None:
        raise BuildError(f"no FMI binary folder for this CPU ({machine}): FMUs are built for "
                         "64-bit Linux on x86_64 or aarch64")
    return "linux64" if fmi_version == 2 else f"{architecture}-linux"


def fmi_headers(fmi_version: int = 2) -> Path:
    """fmpy's folder of the FMI `fmi_version`.0 headers."""
    spec = importlib.util.find_spec("fmpy")
    if spec is None or spec.origin is None:
        raise BuildError(f"fmpy is not installed: its FMI {fmi_version}.0 headers (fmpy/c-code) "
                         "are needed")
    headers = Path(spec.origin).parent / "c-code"
    if not all((headers / name).is_file() for name in HEADERS[fmi_version]):
        raise BuildError(f"fmpy has no FMI {fmi_version}.0 headers at {headers}")
    return headers


def gcc() -> str:
    """gcc's path on PATH."""
    found = shutil.which("gcc")
    if found is None:
        raise BuildError("gcc not found on PATH: install a C compiler (e.g. apt install gcc) "
                         "to build the FMUs")
    return found


@lru_cache(maxsize=4)
def gcc_version(compiler: str) -> str:
    """`compiler --version`'s output: part of every build key."""
    try:
        result = subprocess.run([compiler, "--version"], capture_output=True, text=True,
                                check=True)
    except (OSError, subprocess.CalledProcessError) as exc:
        raise BuildError(f"cannot run {compiler} --version: {exc}") from None
    return result.stdout


def compile_shared(compiler: str, source_dir: Path, c_files: list[str], include: Path,
                   output: Path, label: str) -> None:
    """Compile `c_files` (names in `source_dir`) into the shared library `output`, in the source
    folder on relative names so that no temporary path gets into the binary (builds are
    byte-reproducible); `include`: a further header folder. BuildError names the first errors."""
    command = [compiler, *CFLAGS, "-I", ".", "-I", str(include.absolute()), *c_files, "-o",
               str(output.absolute()), *LIBS]
    result = subprocess.run(command, capture_output=True, text=True, cwd=source_dir)
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        errors = [line for line in lines if "error" in line] or lines
        shown = "\n  ".join(line.replace(str(source_dir) + os.sep, "") for line in errors[:5])
        raise BuildError(f"{label}: gcc failed to compile the model:\n  {shown}")
