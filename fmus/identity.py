"""What an FMU is, by content, and whether its archive is safe to open.

An FMU's identity is the sha256 of what runs and what it says it is: modelDescription.xml, every
file under binaries/ and every file under sources/, by name in sorted order (`content_hash`).
Zip details (entry dates and order, compression, documentation/, extra files) are not part of
it, so two zips of the same build are the same FMU and a build whose binary was replaced is
another one. The integrity of a file as it was written (a run log's attachment) is still checked
on its bytes (hashlib.sha256 of the file).

Any archive that comes from outside (a run log's attachment, an FMU file a scenario names) is
checked before it is hashed or extracted (`check_archive`): at most LIMITS.max_files entries,
LIMITS.max_file_bytes per entry and LIMITS.max_total_bytes in all (uncompressed, as declared:
Python's zipfile never inflates an entry beyond its declared size), and no entry that is a link
or another special file, an absolute or escaping path (`/x`, `C:x`, `..`) or a name with a NUL
byte. Every refusal is an UnsafeArchive, a ValueError of one line naming the archive and entry.
"""

from __future__ import annotations

import hashlib
import io
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

__all__ = ["LIMITS", "ArchiveLimits", "UnsafeArchive", "check_archive", "content_hash",
           "unsafe_name"]

_IDENTITY_PARTS = ("binaries/", "sources/")
_CHUNK = 1 << 20


@dataclass(frozen=True)
class ArchiveLimits:
    """Bounds on an archive from outside: entries, bytes per entry, bytes in all."""

    max_files: int = 1000
    max_file_bytes: int = 64 * 2**20
    max_total_bytes: int = 256 * 2**20


LIMITS = ArchiveLimits()


class UnsafeArchive(ValueError):
    """An archive that is not opened: not a zip, too large, or an entry that could reach outside
    the folder it is extracted into. str() is one line."""


def unsafe_name(name: str) -> str | None:
    """Why a name inside an archive (or a run log's attachment name) is refused, or None."""
    if "\x00" in name:
        return "has a NUL byte in its name"
    posix = name.replace("\\", "/")
    if posix.startswith("/") or (len(posix) > 1 and posix[1] == ":"):
        return "is an absolute path"
    if ".." in PurePosixPath(posix).parts:
        return "escapes the folder it is extracted into (..)"
    return None


def check_archive(data: bytes, what: str, limits: ArchiveLimits = LIMITS) -> zipfile.ZipFile:
    """The open zip of `data` after the checks of the module docstring; UnsafeArchive naming
    `what` (e.g. "attachment fmus/Pile.fmu") and the entry otherwise."""
    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, OSError, ValueError) as error:
        raise UnsafeArchive(f"{what}: not a zip archive ({error})") from None
    entries = archive.infolist()
    if len(entries) > limits.max_files:
        raise UnsafeArchive(f"{what}: {len(entries)} entries, more than the {limits.max_files} "
                            "allowed")
    total, seen = 0, set()
    for info in entries:
        shown = repr(info.orig_filename)[:80]
        problem = unsafe_name(info.orig_filename)  # zipfile cuts .filename at a NUL byte
        kind = stat.S_IFMT(info.external_attr >> 16)
        if problem is None and kind not in (0, stat.S_IFREG, stat.S_IFDIR):
            problem = "is a link" if kind == stat.S_IFLNK else "is not a regular file"
        if problem is None and info.filename in seen:
            problem = "appears twice"
        if problem is None and info.file_size > limits.max_file_bytes:
            problem = (f"holds {info.file_size} bytes, more than the {limits.max_file_bytes} "
                       "allowed per file")
        if problem is not None:
            raise UnsafeArchive(f"{what}: entry {shown} {problem}; not opened")
        seen.add(info.filename)
        total += info.file_size
        if total > limits.max_total_bytes:
            raise UnsafeArchive(f"{what}: more than {limits.max_total_bytes} bytes uncompressed "
                                "in all; not opened")
    return archive


def content_hash(fmu: str | Path | bytes, what: str | None = None,
                 limits: ArchiveLimits = LIMITS) -> str:
    """sha256 (hex) of an FMU's content (module docstring) from its path or bytes; the archive
    is checked first (UnsafeArchive; a corrupt entry is one too)."""
    if isinstance(fmu, bytes | bytearray):
        data, label = bytes(fmu), what or "FMU"
    else:
        data, label = Path(fmu).read_bytes(), what or str(fmu)
    archive = check_archive(data, label, limits)
    digest = hashlib.sha256()
    names = sorted(info.filename for info in archive.infolist() if not info.is_dir() and (
        info.filename == "modelDescription.xml" or info.filename.startswith(_IDENTITY_PARTS)))
    try:
        for name in names:
            info = archive.getinfo(name)
            digest.update(f"{name}:{info.file_size}:".encode())
            with archive.open(info) as entry:
                while chunk := entry.read(_CHUNK):
                    digest.update(chunk)
    except Exception as error:  # BadZipFile (CRC), zlib.error, EOFError, ...
        raise UnsafeArchive(f"{label}: entry {name!r} cannot be read ({error})") from None
    return digest.hexdigest()

