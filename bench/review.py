"""What reviewing a run log costs: reading and decoding a paper campaign's numeric channels, and
drawing its figures.

    python bench/review.py

Runs the paper scenario (20 periods) into a temporary log, then reads the channels the figures
use three times with `orchestrator.runlog.read_run(topics=...)` and, side by side, with
the `mcap` package's reader and mcap-protobuf-support's decoder (protobuf's own parser, one
Python object per message). Prints messages/s of each and their ratio, and the seconds
`excosim review --plots` spends drawing.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

# The project root first: bench/planner.py would otherwise shadow the planner package.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from orchestrator.campaign import run_campaign  # noqa: E402
from orchestrator.review.plots import PLOT_TOPICS, write_plots  # noqa: E402
from orchestrator.runlog import read_run  # noqa: E402
from orchestrator.scenario import load_scenario  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
REPEATS = 3


def _ours(path: Path) -> int:
    run = read_run(path, topics=PLOT_TOPICS)
    return sum(len(channel.log_time_ns) for channel in run.channels.values())


def _peer(path: Path) -> int:
    count = 0
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _ in reader.iter_decoded_messages(topics=list(PLOT_TOPICS)):
            count += 1
    return count


def _best(function, path: Path) -> tuple[float, int]:
    times, count = [], 0
    for _ in range(REPEATS):
        start = time.perf_counter()
        count = function(path)
        times.append(time.perf_counter() - start)
    return min(times), count


def main() -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "paper.mcap"
        run_campaign(load_scenario(ROOT / "scenarios" / "paper-2020.toml"), log_path=path)
        print(f"paper campaign log: {path.stat().st_size / 1e6:.1f} MB")
        ours, count = _best(_ours, path)
        peer, peer_count = _best(_peer, path)
        assert count == peer_count, (count, peer_count)
        print(f"read + decode {count} messages on {len(PLOT_TOPICS)} channels "
              f"(best of {REPEATS}):")
        print(f"  excosim read_run(topics=...)      {ours:7.3f} s  "
              f"{count / ours / 1e6:6.2f} M msg/s")
        print(f"  mcap reader + protobuf decoder    {peer:7.3f} s  "
              f"{count / peer / 1e6:6.2f} M msg/s")
        print(f"  ratio (peer / ours)               {peer / ours:7.1f}")
        run = read_run(path, topics=PLOT_TOPICS)
        draws = []
        for _ in range(REPEATS):
            start = time.perf_counter()
            written = write_plots(run, Path(folder) / "figures", period=1)
            draws.append(time.perf_counter() - start)
        print(f"figures: {len(written)} PNG files in {statistics.median(draws):.2f} s (median)")


if __name__ == "__main__":
    main()
