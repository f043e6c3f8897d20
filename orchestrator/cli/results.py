"""Where a run's files go: the log's default name under runs/, a results folder per run
(`run --out-dir`), and the live view that serves a run while it is logged (`run --live`)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import sys
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

RUNS = Path("runs")  # where logs go without -o, relative to the working folder


def default_name(scenario: Any, now: datetime | None = None) -> str:
    """<scenario-name>-<UTC time to the ms>-<6 hex digits of the resolved scenario's hash>: runs
    started in the same millisecond differ when their scenarios (e.g. --set) differ."""
    stamp = (now or datetime.now(UTC)).strftime("%Y%m%dT%H%M%S.%f")[:-3] + "Z"
    resolved = json.dumps(scenario.to_dict(), sort_keys=True).encode()
    digest = hashlib.sha256(resolved).hexdigest()[:6]
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "-", scenario.name).strip("-.") or "run"
    return f"{safe}-{stamp}-{digest}"


def reserve_default_output(scenario: Any, now: datetime | None = None,
                           folder: Path = RUNS) -> Path:
    """Create an empty runs/<default_name>.mcap exclusively and return it; a name taken already
    (the same scenario started in the same millisecond) gets -2, -3, ... OSError if the folder
    cannot be made or written."""
    folder.mkdir(parents=True, exist_ok=True)
    base = default_name(scenario, now)
    for attempt in range(1, 1000):
        path = folder / (f"{base}.mcap" if attempt == 1 else f"{base}-{attempt}.mcap")
        try:
            with open(path, "x"):
                return path
        except FileExistsError:
            continue
    raise FileExistsError(f"{folder / base}.mcap and 998 variants exist")


def results_folder(scenario: Any, parent: Path, now: datetime | None = None) -> Path:
    """Create parent/<default_name>/ exclusively (a name taken already gets -2, -3, ...) and
    return it: the folder of one run's log and results. OSError if it cannot be made."""
    parent.mkdir(parents=True, exist_ok=True)
    base = default_name(scenario, now)
    for attempt in range(1, 1000):
        folder = parent / (base if attempt == 1 else f"{base}-{attempt}")
        try:
            folder.mkdir()
            return folder
        except FileExistsError:
            continue
    raise FileExistsError(f"{parent / base} and 998 variants exist")


def write_results(log_path: Path, scenario: Any) -> list[Path]:
    """Beside the finished run's log: the resolved scenario (scenario.toml, which
    `excosim run` takes back and which digs the same run), its Foxglove layout
    (foxglove-layout.json), the period table (periods.csv, one row per period) and the
    review's figures (figures/*.png)."""
    from orchestrator.campaign.record import records_dataframe
    from orchestrator.review.layout import LayoutFacts, layout_text
    from orchestrator.review.plots import write_plots
    from orchestrator.runlog import read_run
    from orchestrator.scenario.toml_text import toml_text

    folder = log_path.parent
    run = read_run(log_path, topics=("/display",))
    written = [folder / "scenario.toml", folder / "foxglove-layout.json", folder / "periods.csv"]
    header = (f"The resolved scenario of {log_path.name}: every value as the run used it "
              "(excosim run takes it back).")
    written[0].write_text(toml_text(scenario.to_dict(), header), encoding="utf-8")
    written[1].write_text(layout_text(LayoutFacts.of_run(run)), encoding="utf-8")
    if run.periods:
        records_dataframe(run.periods).to_csv(written[2], float_format="%.17g")
        (folder / "figures").mkdir(exist_ok=True)
        written += write_plots(read_run(log_path), folder / "figures")
    else:
        written.pop()
    return written


@contextlib.contextmanager
def serving(settings: Any, scenario: Any, log_path: Path, quiet: bool) -> Iterator[Any]:
    """The run's LiveView (orchestrator.live) while the block runs, or None without
    `settings` (cli.run.LiveSettings). The layout for the run goes beside the log
    (<log>.layout.json) and one line on stderr says where to connect. LiveError (one line)
    when the view cannot start; the view plays out what was logged when the block ends
    normally."""
    if settings is None:
        yield None
        return
    from orchestrator.live import LiveError, LiveView
    from orchestrator.review.layout import LayoutFacts, layout_text

    try:
        view = LiveView(settings.port, settings.host, settings.real_time_factor,
                        name=f"excosim {scenario.name}")
    except LiveError as error:
        raise LiveError(f"--live: {error}") from None
    layout_path = log_path.with_suffix(".layout.json")
    try:
        layout_path.write_text(layout_text(LayoutFacts.of_scenario(scenario)), encoding="utf-8")
        if not quiet:
            print(f"live: {view.url} (Foxglove or Lichtblick: Open connection -> Foxglove "
                  f"WebSocket; layout {layout_path}), x{settings.real_time_factor:g} real "
                  "time", file=sys.stderr, flush=True)
        yield view
    except BaseException:
        view.close(drain=False)
        raise
    view.close(drain=True)
