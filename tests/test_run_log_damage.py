"""A damaged run log is told from a killed run's, and a chunk beyond the bounds is refused.

Bytes overwritten inside a chunk (its records no longer match the CRC the writer stored) are
"damaged at byte N (chunk CRC)" in review, compare, replay and `log repair`, where a file cut
short is "a killed run?"; `run --resume` refuses a damaged log and changes nothing. A chunk that
declares or inflates to more than orchestrator.runlog.inflate.MAX_CHUNK_BYTES, or more than it
declares, is refused by every command in one line (exit 2), at once, without the memory."""

import os
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

import lz4.frame
import pytest
import zstandard
from run_log_files import chunks, cut_inside_chunk

from orchestrator.campaign import run_campaign
from orchestrator.runlog import RunLogError, read_run
from orchestrator.runlog.inflate import MAX_CHUNK_BYTES, ChunkRefused, inflate
from orchestrator.runlog.repair import repair
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = (["review"], ["review", "--json"], ["compare"], ["replay"],
            ["run", "--resume"], ["log", "repair"])


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("damage") / "run.mcap"
    scenario = load_scenario(ROOT / "scenarios" / "paper-2020.toml", ["periods=2"])
    assert run_campaign(scenario, log_path=path).termination == "periods"
    return path


TIME = Path("/usr/bin/time")  # GNU time: the command's own peak memory (%M, kB)


def excosim(*args) -> tuple[subprocess.CompletedProcess, float, int | None]:
    """(the finished command, its wall time in s, its peak resident memory in kB: measured
    by GNU time, since a child's own rusage counts the pages it shared with this process
    before its exec; None without GNU time)."""
    with tempfile.NamedTemporaryFile("r") as peak:
        measure = [str(TIME), "-f", "%M", "-o", peak.name] if TIME.exists() else []
        start = time.perf_counter()
        done = subprocess.run([*measure, sys.executable, "-m", "orchestrator.cli.app",
                               *map(str, args)], capture_output=True, text=True, timeout=120)
        seconds = time.perf_counter() - start
        text = peak.read().strip().splitlines()
    if measure and text and text[0].startswith("Command exited"):
        text = text[1:]
    return done, seconds, int(text[-1]) if measure and text else None


def run_command(command: list[str], path: Path, other: Path, tmp_path: Path):
    """excosim of `command` (an item of COMMANDS) on `path` (`other`: the other log of a
    comparison)."""
    if command == ["compare"]:
        return excosim("compare", other, path)
    if command == ["log", "repair"]:
        return excosim("log", "repair", path, "-o", tmp_path / f"repaired-{path.stem}.mcap")
    return excosim(*command, path)


def overwritten(log: Path, target: Path) -> tuple[Path, int]:
    """A copy of `log` with 4 kB overwritten in the middle of period 2's chunk; (the copy, the
    chunk's first byte)."""
    chunk = chunks(log)[1]
    data = bytearray(log.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 4096] = b"\xab" * 4096
    target.write_bytes(bytes(data))
    return target, chunk.chunk_start_offset


def test_damage_is_not_a_killed_run_in_any_command(log, tmp_path):
    damaged, at = overwritten(log, tmp_path / "damaged.mcap")
    said = f"damaged at byte {at} (chunk CRC)"
    run = read_run(damaged)
    assert run.damage == said and len(run.periods) == 1 and not run.finished
    with pytest.raises(RunLogError, match=r"damaged at byte \d+ \(chunk CRC\) after 1"):
        read_run(damaged, tolerant=False)
    review, _, _ = excosim("review", damaged)
    assert review.returncode == 0, review.stderr
    assert f"the file is {said}; it holds 1 complete period before the damage" in review.stdout
    assert "killed run" not in review.stdout
    compare, _, _ = excosim("compare", log, damaged)
    assert compare.returncode == 0 and "damaged" in compare.stdout and said in compare.stdout
    replay, _, _ = excosim("replay", damaged)
    assert replay.returncode == 0, replay.stderr
    assert f"the log's file is {said}: its complete periods before the damage were replayed" \
        in replay.stdout
    repaired, _, _ = excosim("log", "repair", damaged, "-o", tmp_path / "copy.mcap")
    assert repaired.returncode == 0 and f"is {said}: the copy holds what precedes" \
        in repaired.stdout
    assert len(read_run(tmp_path / "copy.mcap", tolerant=False).periods) == 1
    before = damaged.read_bytes()
    resumed, _, _ = excosim("run", "--resume", damaged)
    assert resumed.returncode == 2 and resumed.stdout == ""
    lines = resumed.stderr.strip().splitlines()
    assert len(lines) == 1 and f"is {said}, after 1 complete period: it is not resumed" \
        in lines[0]
    assert damaged.read_bytes() == before and sorted(os.listdir(tmp_path)) == \
        ["copy.mcap", "damaged.mcap"]
    # A killed run's file still reads as one (the other message).
    killed = cut_inside_chunk(log, tmp_path / "killed.mcap", 1)
    assert read_run(killed).damage is None
    review, _, _ = excosim("review", killed)
    assert "(the file ends early); a killed run?" in review.stdout


def test_a_closed_file_with_a_changed_byte_outside_the_chunks_is_damaged(log, tmp_path):
    data = bytearray(log.read_bytes())
    at = data.index(b"paper-2020")  # the header's scenario name, same length
    data[at:at + 5] = b"PAPER"
    edited = tmp_path / "edited.mcap"
    edited.write_bytes(bytes(data))
    run = read_run(edited)
    assert run.finished and len(run.periods) == 2
    assert run.damage is not None and "(data section CRC" in run.damage
    # A record length made to run past the end of a closed file is damage too.
    first = chunks(log)[0].chunk_start_offset
    struct.pack_into("<Q", data, first + 1, len(data))
    edited.write_bytes(bytes(data))
    assert read_run(edited).damage == (f"damaged at byte {first} (a record runs past the end "
                                       "of the file)")


def chunk_record(compression: bytes, data: bytes, declared: int, crc: int = 0) -> bytes:
    body = struct.pack("<QQQI", 0, 0, declared, crc)
    body += struct.pack("<I", len(compression)) + compression + struct.pack("<Q", len(data))
    return struct.pack("<BQ", 0x06, len(body) + len(data)) + body + data


def with_chunk(log: Path, target: Path, record: bytes) -> Path:
    """A killed run's log (no end) with `record` in place of period 1's chunk."""
    first = chunks(log)[0]
    data = log.read_bytes()
    target.write_bytes(data[:first.chunk_start_offset] + record)
    return target


ZEROS = 64 << 20


def bombs(log: Path, folder: Path) -> dict[str, Path]:
    lz4_data = lz4.frame.compress(b"\0" * ZEROS)
    zstd_data = zstandard.ZstdCompressor().compress(b"\0" * ZEROS)  # declares its 64 MiB
    return {
        "lz4 declaring 10 bytes, holding 64 MiB": with_chunk(
            log, folder / "lz4.mcap", chunk_record(b"lz4", lz4_data, 10)),
        "zstd chunk declaring 2^40 bytes": with_chunk(
            log, folder / "zstd.mcap", chunk_record(b"zstd", zstd_data, 1 << 40)),
        "zstd frame of 64 MiB in a chunk declaring 10 bytes": with_chunk(
            log, folder / "frame.mcap", chunk_record(b"zstd", zstd_data, 10)),
    }


def test_the_bounds_of_inflate():
    data = bytes(range(256)) * 4096
    for compression, packed in (("lz4", lz4.frame.compress(data)),
                                ("zstd", zstandard.ZstdCompressor().compress(data)),
                                ("zstd", zstandard.ZstdCompressor(
                                    write_content_size=False).compress(data))):
        assert inflate(compression, packed, len(data)) == data
        assert inflate(compression, packed[:len(packed) // 2], len(data)) is None  # damaged
        assert inflate(compression, packed, len(data) + 1) is None  # fewer bytes than said
        with pytest.raises(ChunkRefused, match="inflates to more than|declares"):
            inflate(compression, packed, len(data) - 1)
    with pytest.raises(ChunkRefused, match="more than the 256 MiB a chunk may hold"):
        inflate("zstd", b"", MAX_CHUNK_BYTES + 1)
    assert MAX_CHUNK_BYTES == 256 << 20


def test_a_chunk_beyond_the_bounds_is_one_line_in_every_command(log, tmp_path):
    baseline, _, memory = excosim("review", log)
    assert baseline.returncode == 0
    figures = []
    for name, path in bombs(log, tmp_path).items():
        with pytest.raises(RunLogError, match="refused"):
            read_run(path)
        with pytest.raises(RunLogError, match="refused"):
            repair(path, tmp_path / "api-copy.mcap")
        commands = COMMANDS if "frame" not in name else COMMANDS[:1]
        for command in commands:
            done, seconds, peak = run_command(list(command), path, log, tmp_path)
            lines = done.stderr.strip().splitlines()
            assert done.returncode == 2, (name, command, done.stderr[-500:])
            assert len(lines) == 1 and "refused" in lines[0], (name, command, lines)
            assert "MemoryError" not in done.stderr and "Traceback" not in done.stderr
            assert seconds < 30, (name, command, seconds)
            # Nothing of the 64 MiB (or 2^40 bytes) is made: a command's peak is that of a
            # review of the untouched log, give or take what the command imports.
            assert peak is None or peak < memory + 48 * 1024, (name, command, peak, memory)
            figures.append((name, " ".join(command), round(seconds, 2), peak))
        assert not (tmp_path / "api-copy.mcap").exists()
        assert not any(p.name.startswith("repaired-") for p in tmp_path.iterdir())
    print("\nreview of the untouched log:", memory, "kB")
    for figure in figures:
        print(figure)


def test_a_chunk_crc_that_does_not_match_is_damage_not_a_refusal(log, tmp_path):
    records = b"\x00" * 9  # one empty record of an unknown kind
    good = with_chunk(log, tmp_path / "good.mcap",
                      chunk_record(b"", records, len(records), zlib.crc32(records)))
    assert read_run(good).damage is None
    bad = with_chunk(log, tmp_path / "bad.mcap",
                     chunk_record(b"", records, len(records), zlib.crc32(records) ^ 1))
    first = chunks(log)[0].chunk_start_offset
    assert read_run(bad).damage == f"damaged at byte {first} (chunk CRC)"
