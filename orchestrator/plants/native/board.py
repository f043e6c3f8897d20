"""The board of the step loop in C: which FMU is in a step now, and from which time.

While coupling.c's loop steps the FMUs there is no Python frame per FMU step, which is what
the step watchdog and a crash report otherwise read to name the FMU (fmus.runs.STEP_CODES,
STEP_NAME). The loop writes the FMU's index and the step's start time t onto a board before
each step and clears the index after it; the board also holds the four FMUs' names. It lives
in a one-page file mapped into memory (MAP_SHARED) in a folder of its own under the temporary
folder, so that

- the step watchdog reads it from the loop's frame while the main thread is in C
  (`stepping_in(frame)`, orchestrator.campaign.watchdog);
- after the process died in an FMU step (a segfault, abort()), its parent reads the same page
  from the file (`stepping_after_death(folder)`, orchestrator.campaign.isolation: a supervised
  child's temporary folder is one the parent made).

Writing it costs two stores per FMU step. The folder goes with the plant's other temporary
folders (orchestrator.plants.simulated_excavator.SimulatedExcavator.temporary_folders).
"""

from __future__ import annotations

import ctypes
import mmap
import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from types import FrameType

FOLDER_PREFIX = "excosim-stepping-"
FILE_NAME = "board"
LABEL_BYTES = 120
FMUS = 4  # boom, stick, bucket, pile: coupling.c's order


class BoardLayout(ctypes.Structure):
    """coupling.c's Board (which, t) followed by the FMUs' names (utf-8, NUL-padded)."""

    _fields_ = [("which", ctypes.c_long), ("t", ctypes.c_double),
                ("labels", (ctypes.c_char * LABEL_BYTES) * FMUS)]


class Board:
    """A board for FMUs named `labels` (4 names, coupling.c's order) in a new folder under the
    temporary folder; `layout` is the mapped struct, `folder` its folder. close() removes it."""

    def __init__(self, labels: Sequence[str]) -> None:
        if len(labels) != FMUS:
            raise ValueError(f"a board names {FMUS} FMUs, got {len(labels)}")
        self.folder = tempfile.mkdtemp(prefix=FOLDER_PREFIX)
        path = Path(self.folder) / FILE_NAME
        with open(path, "w+b") as file:
            # Written, not truncated to size: a sparse page on a full disk would end the
            # process with SIGBUS at the first store instead of an OSError here.
            file.write(bytes(ctypes.sizeof(BoardLayout)))
            file.flush()
            self._map = mmap.mmap(file.fileno(), ctypes.sizeof(BoardLayout))
        self.layout = BoardLayout.from_buffer(self._map)
        self.layout.which, self.layout.t = -1, 0.0
        for i, label in enumerate(labels):
            self.layout.labels[i].value = label.encode()[:LABEL_BYTES - 1]
        self.labels = tuple(labels)

    def address(self) -> int:
        """The struct's address, for coupling.c's Loop.board."""
        return ctypes.addressof(self.layout)

    def reading(self) -> tuple[int, float, str] | None:
        """(index, t s, name) of the FMU in a step now, None when none is (or the board is
        closed: the watchdog's thread may look while the main thread closes it)."""
        layout = getattr(self, "layout", None)
        if layout is None:
            return None
        which, t = int(layout.which), float(layout.t)
        if not 0 <= which < FMUS:
            return None
        return which, t, self.labels[which]

    def close(self) -> None:
        """Unmap and remove the folder; safe twice."""
        if self._map is None:
            return
        layout = self.layout
        del self.layout  # readers see a closed board from here (reading() -> None)
        try:
            del layout  # the exported buffer must go before the map can close
            self._map.close()
        except BufferError:  # a view is still held somewhere: the map goes with the process
            pass
        self._map = None
        shutil.rmtree(self.folder, ignore_errors=True)


# The code object of the loop's frame that holds a `board` local (NativeCoupling.track sets
# it): a frame of this code is the loop in C, whatever FMU it is stepping.
LOOP_CODES: set = set()


def stepping_in(frame: FrameType | None) -> tuple[int, float, str] | None:
    """(key, t s, "instance (model)") of the FMU step the loop whose frame is `frame` is in
    (the key tells instances apart: the same key and t seen twice are one step), else None."""
    if frame is None or frame.f_code not in LOOP_CODES:
        return None
    board = frame.f_locals.get("board")
    reading = board.reading() if isinstance(board, Board) else None
    if reading is None:
        return None
    which, t, label = reading
    return hash((id(board), which)), t, label


def stepping_after_death(temporary_folder: str | os.PathLike) -> tuple[float, str] | None:
    """(t s, "instance (model)") of the FMU step a dead process's loop was in, from the board
    it left under `temporary_folder`; None when none was in a step (or no board is there)."""
    for path in sorted(Path(temporary_folder).glob(f"{FOLDER_PREFIX}*/{FILE_NAME}")):
        try:
            data = path.read_bytes()
        except OSError:
            continue
        if len(data) != ctypes.sizeof(BoardLayout):
            continue
        layout = BoardLayout.from_buffer_copy(data)
        if 0 <= layout.which < FMUS:
            return float(layout.t), layout.labels[layout.which].value.decode(errors="replace")
    return None
