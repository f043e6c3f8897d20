"""Ask an FMU at load time whether it initialises with a scenario's start values.

The checks an FMU makes at initialization (our models: a rod wider than the bore, a floor above
the ground, a non-finite stiffness bound, ...) would otherwise surface only when the plant starts,
after the run log exists. `initialization_error` instantiates the FMU once, sets the start
values, runs initialization and frees it again, and returns the FMU's own error message. It runs
native code, so the scenario loader asks only our own models (built here from our sources);
an FMU file of unknown origin is not run before the trust rule has allowed it
(docs/reliability.md). Answers are cached per FMU file and start values.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import sys
import tempfile
import threading
from collections.abc import Iterator, Mapping
from functools import lru_cache
from pathlib import Path

_CONVERT = {"Real": float, "Integer": int, "Boolean": bool}
_LOCK = threading.Lock()  # one probe at a time: each swaps sys.stdout and must restore it


class _ThisThreadsPrints(io.TextIOBase):
    """sys.stdout while a probe runs: the probing thread's prints (fmpy's logger) go to
    `buffer`, every other thread's to the stream that was there (an emulated device printing
    beside a scenario load must not lose its lines to the probe)."""

    def __init__(self, stream, buffer: io.StringIO) -> None:
        self._stream, self._buffer, self._thread = stream, buffer, threading.get_ident()

    def write(self, text: str) -> int:
        target = self._buffer if threading.get_ident() == self._thread else self._stream
        return target.write(text)

    def flush(self) -> None:
        self._stream.flush()


@contextlib.contextmanager
def capture_this_thread(buffer: io.StringIO) -> Iterator[None]:
    """Within the block, what this thread prints (fmpy's logger: the FMUs' messages) goes to
    `buffer`; other threads print as before."""
    with _LOCK:
        stream = sys.stdout
        sys.stdout = _ThisThreadsPrints(stream, buffer)
        try:
            yield
        finally:
            sys.stdout = stream


def initialization_error(path: Path, start_values: Mapping[str, bool | int | float]
                         ) -> str | None:
    """None when the FMU at `path` (FMI 2.0 co-simulation) initialises with `start_values`
    (variable name -> value, converted to each variable's type); else the first error it
    logged, or fmpy's message when it logged none."""
    stat = Path(path).stat()
    return _probe(str(path), stat.st_mtime_ns, stat.st_size, tuple(sorted(start_values.items())))


@lru_cache(maxsize=256)
def _probe(path: str, mtime_ns: int, size: int, start_values: tuple) -> str | None:
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    from orchestrator.scenario.fmu_paths import model_description

    description = model_description(Path(path))
    variables = {v.name: v for v in description.modelVariables}
    folder = tempfile.mkdtemp(prefix="excosim-probe-")
    slave, printed = None, io.StringIO()
    try:
        # fmpy's own logger prints "[ERROR] <message>" (its native proxy formats the FMU's
        # variadic message; a logger of our own would have to replace fmpy's process-wide one).
        with capture_this_thread(printed):
            try:
                unzip = extract(path, unzipdir=folder)
                slave = FMU2Slave(guid=description.guid, unzipDirectory=unzip,
                                  modelIdentifier=description.coSimulation.modelIdentifier,
                                  instanceName="probe")
                slave.instantiate()
                slave.setupExperiment(startTime=0.0)
                slave.enterInitializationMode()
                for name, value in start_values:
                    variable = variables[name]
                    setter = {"Real": slave.setReal, "Integer": slave.setInteger,
                              "Boolean": slave.setBoolean}[variable.type]
                    setter([variable.valueReference], [_CONVERT[variable.type](value)])
                slave.exitInitializationMode()
                slave.terminate()
            except Exception as error:  # fmpy raises plain Exceptions for FMI error statuses
                logged = [line.partition("] ")[2] for line in printed.getvalue().splitlines()
                          if line.startswith(("[ERROR]", "[FATAL]", "[DISCARD]"))]
                return logged[0] if logged else str(error)
            finally:
                _free(slave)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return None


def _free(slave) -> None:
    try:
        if getattr(slave, "component", None) is not None:
            slave.freeInstance()
        elif slave is not None:
            slave.freeLibrary()
    except Exception:  # noqa: BLE001 - the answer is the initialization's
        pass
