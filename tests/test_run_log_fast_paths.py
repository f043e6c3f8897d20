"""orchestrator.runlog's encoders (rows.c, orchestrator.runlog.native) against the
straightforward ones they replaced (tests/run_log_reference.py, the oracle), byte for byte:
chunk records and message indexes for batches of any field layout and single messages added in
any time order; /tf records for any joints and times among other messages; the sample channels
of any set of signals; package versions."""

from importlib import metadata

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from run_log_reference import ChunkBuilder as ReferenceBuilder
from run_log_reference import DoubleBatch as ReferenceBatch
from run_log_reference import encode_frame_transforms as reference_transforms
from run_log_reference import sample_channels as reference_channels

from orchestrator.runlog.chunk import BufferPool, ChunkBuilder, DoubleBatch
from orchestrator.runlog.metadata import _PACKAGES, package_versions
from orchestrator.runlog.samples import CheckedPeriod, double_tag, sample_channels
from orchestrator.runlog.scene import link_transforms, transform_records
from plant_models import presets

PREFIXES = st.sampled_from([double_tag(1), double_tag(7), double_tag(16), double_tag(33),
                            b"\x12\x18", b""])


@st.composite
def chunk_content(draw):
    """A list of additions: ("batches", [(prefixes, seed)], times), ("message", time, size)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    additions = []
    for _ in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(["batches", "message"]))
        n = draw(st.integers(1, 30))
        times = np.sort(rng.integers(0, 20, n)).astype(np.uint64) if draw(st.booleans()) \
            else rng.integers(0, 20, n).astype(np.uint64)
        if kind == "batches":
            channels = [tuple(draw(st.lists(PREFIXES, min_size=0, max_size=6)))
                        for _ in range(draw(st.integers(1, 4)))]
            batches = [(p, rng.normal(size=(n, len(p)))) for p in channels]
            # One array as every batch's first column, as the sample times are in a run.
            shared = rng.normal(size=n) if draw(st.booleans()) and all(channels) else None
            for _, values in batches if shared is not None else ():
                values[:, 0] = shared
            additions.append((kind, (batches, shared), times))
        else:
            additions.append((kind, int(times[0]), rng.bytes(int(rng.integers(0, 50)))))
    return additions


def build(builder, additions):
    channel = 0
    for kind, content, extra in additions:
        channel += 1
        if kind == "batches":
            batches = []
            content, shared = content
            for prefixes, values in content:
                columns = tuple(values.T) if shared is None else (shared, *values.T[1:])
                batches.append(ReferenceBatch(channel, 3 * channel, prefixes, values)
                               if isinstance(builder, ReferenceBuilder)
                               else DoubleBatch(channel, 3 * channel, prefixes, columns))
                channel += 1
            builder.add_batches(batches, extra)
        else:
            builder.add_message(channel, channel, content, extra)
    return builder


@settings(max_examples=200, deadline=None)
@given(chunk_content())
def test_records_and_indexes_equal_the_reference_builder(additions):
    """Records asked for before or after the message indexes (the writer thread asks after)."""
    reference = build(ReferenceBuilder(), additions)
    pool = BufferPool()
    # without a pool, then twice from one pool: the second chunk reuses the first's buffers
    for index, chunk_pool in enumerate((None, pool, pool)):
        fast = build(ChunkBuilder(chunk_pool), additions)
        if index == 1:
            assert fast.message_indexes() == reference.message_indexes()
        assert bytes(fast.records()) == reference.records()
        assert fast.message_indexes() == reference.message_indexes()
        assert (fast.start_time, fast.end_time, fast.size, dict(fast.counts)) == (
            reference.start_time, reference.end_time, reference.size, dict(reference.counts))
        fast.release()


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 60),
       st.sampled_from([0, 10**9 - 5 * 10**6, 127 * 10**9, 10**13]), st.booleans())
def test_transform_records_equal_the_reference_encoding(seed, n, start_ns, ties):
    """/tf records from rows.c (scene.transform_records, written when the records are made,
    among other messages) against the reference's payloads through its add_grouped; times
    across varint sizes (nanoseconds of 1 to 5 bytes, seconds of 1 or more), ties in order."""
    rng = np.random.default_rng(seed)
    times = (start_ns + np.sort(rng.integers(0, 3 * 10**9, n))).astype(np.uint64)
    if ties:
        times[n // 2:] = times[n // 2]  # equal times keep sample order
    transforms = link_transforms(presets.get("paper"), rng.uniform(-3, 3, (n, 3)))
    reference, chunk = ReferenceBuilder(), ChunkBuilder()
    for builder in (reference, chunk):
        builder.add_message(1, 0, int(times[0]), b"before")
    reference.add_grouped(4, 17, times, reference_transforms(transforms, times))
    for index, width, rows in transform_records(transforms, times, 4, 17):
        chunk.add_rows(4, times[index], width, rows)
    for builder in (reference, chunk):
        builder.add_message(2, 0, int(times[-1]), b"after")
    assert chunk.message_indexes() == reference.message_indexes()
    assert bytes(chunk.records()) == reference.records()


SIGNALS = ["boom.x", "boom.v", "boom.p_A", "boom.u", "stick.F", "bucket.x", "pile.bucket_mass",
           "pile.F_y", "tip.y", "supply.p_pump", "supply.p_LS", "extra", "pile.other"]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.sampled_from(SIGNALS), unique=True), st.integers(1, 20))
def test_sample_channels_equal_the_reference_layout(names, m):
    rng = np.random.default_rng(m)
    period = CheckedPeriod(np.arange(m) * 0.01, rng.normal(size=(m, 3)), rng.normal(size=(m, 3)),
                           {name: rng.normal(size=m) for name in names}, None, None)
    times = period.t_s + 100.0
    fast, reference = sample_channels(period, times), reference_channels(period, times)
    assert [(c.topic, c.message, c.metadata, c.prefixes) for c in fast] == [
        (c.topic, c.message, c.metadata, c.prefixes) for c in reference]
    for channel, expected in zip(fast, reference, strict=True):
        assert np.array_equal(np.column_stack(channel.columns), expected.values)


def test_package_versions_equal_importlib_metadata():
    versions = package_versions()
    for name, distribution in _PACKAGES:
        try:
            expected = metadata.version(distribution)
        except metadata.PackageNotFoundError:
            expected = "not installed"
        assert versions[name] == expected
