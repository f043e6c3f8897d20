"""Test helper: the chunks of a run log, and copies of it cut the way a killed run leaves it."""

from pathlib import Path

from mcap.reader import make_reader


def chunks(path: Path) -> list:
    """The chunk indexes (mcap ChunkIndex records) of the file's periods, in file order: one per
    period, the chunk that holds its /period record (the pile's surface at t = 0 has a chunk of
    its own before them)."""
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    period = next(c.id for c in summary.channels.values() if c.topic == "/period")
    return sorted((c for c in summary.chunk_indexes if period in c.message_index_offsets),
                  key=lambda c: c.chunk_start_offset)


def cut_inside_chunk(path: Path, cut: Path, index: int = -1) -> Path:
    """Write to `cut` the bytes of `path` up to the middle of chunk `index` (a run killed while
    writing that period) and return `cut`."""
    chunk = chunks(path)[index]
    cut.write_bytes(path.read_bytes()[:chunk.chunk_start_offset + chunk.chunk_length // 2])
    return cut
