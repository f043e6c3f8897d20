"""FMU identity and the build cache's trust (fmus/identity.py, fmus/builder.py): builds are
byte-reproducible, an FMU is what its model description, binaries and sources are (not its zip's
bytes), cache files of different source trees never clobber each other, a cached FMU whose
binary was replaced is rebuilt, and an archive from outside is refused before it is opened when
it could reach outside its folder or is too large."""

from __future__ import annotations

import hashlib
import io
import shutil
import stat
import warnings
import zipfile
from pathlib import Path

import pytest

import fmus
from fmus.builder import MODELS_DIR
from fmus.identity import ArchiveLimits, UnsafeArchive, check_archive, content_hash


@pytest.fixture
def out_dir(tmp_path, monkeypatch):
    folder = tmp_path / "fmus-out"
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(folder))
    return folder


def _entries(path: Path) -> list[tuple[zipfile.ZipInfo, bytes]]:
    with zipfile.ZipFile(path) as archive:
        return [(info, archive.read(info)) for info in archive.infolist()]


def _rezip(entries, target: Path, *, reverse: bool = False, date=(2024, 5, 6, 7, 8, 10),
           compression=zipfile.ZIP_STORED, extra: dict[str, bytes] | None = None,
           replace: dict[str, bytes] | None = None) -> Path:
    with zipfile.ZipFile(target, "w", compression) as archive:
        for info, data in (reversed(entries) if reverse else entries):
            archive.writestr(zipfile.ZipInfo(info.filename, date_time=date),
                             (replace or {}).get(info.filename, data))
        for name, data in (extra or {}).items():
            archive.writestr(name, data)
    return target


def test_builds_are_byte_reproducible_across_cache_folders(tmp_path, monkeypatch):
    """Two cache folders, and the package's build (fmus/_built, compiled by pip): one FMU."""
    built = []
    for folder in ("one", "two"):
        monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path / folder))
        built.append(fmus.build_model(MODELS_DIR / "Pile"))
    assert built[0] != built[1] and built[0].read_bytes() == built[1].read_bytes()
    assert fmus.build("Pile").read_bytes() == built[0].read_bytes()
    infos = [info for info, _ in _entries(built[0])]
    assert [i.date_time for i in infos] == [(1980, 1, 1, 0, 0, 0)] * len(infos)
    names = [i.filename for i in infos]
    assert names[:2] == ["modelDescription.xml", "binaries/linux64/Pile.so"]
    assert names[2:] == sorted(names[2:]) and all(n.startswith("sources/") for n in names[2:])


def test_content_hash_is_the_model_not_the_zip(out_dir, tmp_path):
    path = fmus.build_model(MODELS_DIR / "HydraulicCylinder")
    entries = _entries(path)
    again = _rezip(entries, tmp_path / "again.fmu", reverse=True,
                   extra={"documentation/notes.txt": b"same model\n"})
    assert again.read_bytes() != path.read_bytes()
    assert content_hash(again) == content_hash(path) == content_hash(path.read_bytes())
    assert (path.parent / "content.sha256").read_text().strip() == content_hash(path)
    for changed in ("sources/model.c", "binaries/linux64/HydraulicCylinder.so",
                    "modelDescription.xml"):
        data = dict((i.filename, d) for i, d in entries)[changed] + b"\n"
        other = _rezip(entries, tmp_path / "other.fmu", replace={changed: data})
        assert content_hash(other) != content_hash(path), changed


def test_two_source_trees_keep_their_own_cache_files(out_dir, tmp_path):
    ours = fmus.build("HydraulicCylinder")
    copy = Path(shutil.copytree(MODELS_DIR / "HydraulicCylinder",
                                tmp_path / "tree" / "HydraulicCylinder"))
    with open(copy / "model.c", "a") as source:
        source.write("\n/* another tree */\n")
    theirs = fmus.build_model(copy)
    assert theirs.name == ours.name and theirs.parent != ours.parent
    stamp = ours.stat().st_mtime_ns
    assert fmus.build("HydraulicCylinder") == ours and ours.stat().st_mtime_ns == stamp
    assert fmus.build_model(copy) == theirs  # neither tree rebuilt the other's FMU
    assert content_hash(ours) != content_hash(theirs)


def test_a_binary_replaced_inside_a_cached_fmu_is_rebuilt(out_dir, tmp_path):
    path = fmus.build_model(MODELS_DIR / "HydraulicCylinder")
    good = path.read_bytes()
    entries = _entries(path)
    so = "binaries/linux64/HydraulicCylinder.so"
    binary = bytearray(dict((i.filename, d) for i, d in entries)[so])
    binary[len(binary) // 2] ^= 0xFF
    _rezip(entries, tmp_path / "tampered.fmu", replace={so: bytes(binary)},
           date=(1980, 1, 1, 0, 0, 0), compression=zipfile.ZIP_DEFLATED)
    shutil.copyfile(tmp_path / "tampered.fmu", path)  # the same GUID in its description
    assert fmus.build_model(MODELS_DIR / "HydraulicCylinder") == path
    assert path.read_bytes() == good

    (path.parent / "content.sha256").write_text("0" * 64 + "\n")  # a record that disagrees
    stamp = path.stat().st_mtime_ns
    assert fmus.build_model(MODELS_DIR / "HydraulicCylinder").read_bytes() == good
    assert path.stat().st_mtime_ns != stamp  # rebuilt
    assert (path.parent / "content.sha256").read_text().strip() == content_hash(path)


def test_local_content_hashes_name_every_model(out_dir):
    hashes = fmus.local_content_hashes()
    assert sorted(hashes.values()) == sorted(fmus.MODELS)
    assert hashes[content_hash(fmus.build("Pile"))] == "Pile"


def _zip(*members: tuple[str, bytes] | zipfile.ZipInfo, data: bytes = b"x") -> bytes:
    buffer = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(buffer, "w") as archive:
        warnings.simplefilter("ignore")  # a duplicate name is what one case is about
        for member in members:
            if isinstance(member, zipfile.ZipInfo):
                archive.writestr(member, data)
            else:
                archive.writestr(*member)
    return buffer.getvalue()


def _link(name: str, target: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name)
    info.create_system = 3
    info.external_attr = (stat.S_IFLNK | 0o777) << 16
    return info


def _nul_name() -> bytes:
    """A zip whose entry name is b"a\\0b" (zipfile writes no NUL: it is patched into both
    headers)."""
    return _zip(("aZb", b"x")).replace(b"aZb", b"a\x00b")


SMALL = ArchiveLimits(max_files=3, max_file_bytes=100, max_total_bytes=150)


@pytest.mark.parametrize(("data", "expected"), [
    (b"not a zip", "not a zip archive"),
    (_zip(_link("binaries/linux64/M.so", "/lib/x.so")), "'binaries/linux64/M.so' is a link"),
    (_zip(("/etc/cron.d/x", b"x")), "is an absolute path"),
    (_zip(("C:/x.dll", b"x")), "is an absolute path"),
    (_zip(("resources/../../x", b"x")), "escapes the folder it is extracted into"),
    (_zip(("sources\\..\\..\\x", b"x")), "escapes the folder"),
    (_nul_name(), "has a NUL byte in its name"),
    (_zip(("a", b"x"), ("a", b"y")), "'a' appears twice"),
    (_zip(*((f"f{i}", b"x") for i in range(4))), "4 entries, more than the 3 allowed"),
    (_zip(("big", b"x" * 101)), "holds 101 bytes, more than the 100 allowed per file"),
    (_zip(("one", b"x" * 80), ("two", b"x" * 80)), "more than 150 bytes uncompressed in all"),
])
def test_an_unsafe_archive_is_refused_in_one_line(data, expected):
    with pytest.raises(UnsafeArchive) as refused:
        check_archive(data, "attachment fmus/M.fmu", SMALL)
    message = str(refused.value)
    assert message.startswith("attachment fmus/M.fmu: ") and expected in message
    assert "\n" not in message
    with pytest.raises(UnsafeArchive):
        content_hash(data, "attachment fmus/M.fmu", SMALL)


def test_a_safe_archive_passes_and_a_bomb_is_bounded_by_its_declared_size():
    assert check_archive(_zip(("modelDescription.xml", b"<x/>"), ("sources/", b"")),
                         "ok", SMALL).namelist() == ["modelDescription.xml", "sources/"]
    bomb = bytearray(_zip(("modelDescription.xml", b"\0" * 10_000)))
    # Declare 10 bytes where 10 000 are compressed in: reading stops at 10 and the CRC fails.
    with zipfile.ZipFile(io.BytesIO(bytes(bomb))) as archive:
        info = archive.infolist()[0]
    for offset in (info.header_offset + 22, bomb.rfind(b"PK\x01\x02") + 24):
        bomb[offset:offset + 4] = (10).to_bytes(4, "little")
    with pytest.raises(UnsafeArchive, match="cannot be read"):
        content_hash(bytes(bomb), "bomb", SMALL)
    assert hashlib.sha256(bytes(bomb)).hexdigest()  # the bytes themselves stay hashable
