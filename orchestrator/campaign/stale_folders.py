"""Temporary folders a killed process could not remove, removed by the next one.

A run (`excosim run`'s supervisor, a sweep worker's log) makes its temporary folder with
owned_folder(), which writes the owner's process id into it. A SIGKILL leaves the folder
behind; remove_stale(), called when the next run starts, removes every folder of that prefix
whose owner no longer runs and that is older than MIN_AGE_S (so a folder being made right now,
or one of a process whose id was just reused, is left alone). Folders without an owner file are
not ours to judge and stay.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path

OWNER_FILE = "owner.pid"
MIN_AGE_S = 60.0


def owned_folder(prefix: str) -> Path:
    """A new temporary folder with this process's id in it."""
    folder = Path(tempfile.mkdtemp(prefix=prefix))
    (folder / OWNER_FILE).write_text(str(os.getpid()))
    return folder


def remove_stale(prefix: str) -> list[Path]:
    """Remove the stale folders of `prefix` in the temporary directory (module docstring);
    the folders removed."""
    removed = []
    now = time.time()
    try:
        candidates = list(Path(tempfile.gettempdir()).glob(f"{prefix}*"))
    except OSError:
        return removed
    for folder in candidates:
        try:
            owner = int((folder / OWNER_FILE).read_text().strip())
            old = now - folder.stat().st_mtime > MIN_AGE_S
        except (OSError, ValueError):
            continue
        if old and not _running(owner):
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    return removed


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: running
        return True
    return True
