"""`excosim export RUN.mcap --parquet DIR --csv DIR`: every numeric channel of a run log as one
table per channel, and the period table, for pandas, R, DuckDB or a spreadsheet without an
MCAP reader (the tables of orchestrator.cli.export).

Each folder gets `<topic>.parquet` / `<topic>.csv` per numeric channel (`/cylinder/boom` ->
cylinder_boom.csv: t_s in s, period, one column per field with its unit) and `period.parquet` /
`period.csv` (one row per period, index k). Exit status 2, with one line and nothing written,
for a file that is not a readable run log or a folder that cannot hold the tables.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.conventions import fail


def export(
    run_log: Annotated[Path, typer.Argument(metavar="RUN.mcap", help="Run log written by "
                                            "`excosim run`.")],
    parquet: Annotated[Path | None, typer.Option(
        "--parquet", metavar="DIR", help="Write one Parquet file per channel and "
        "period.parquet into DIR (made if its parent exists).")] = None,
    csv: Annotated[Path | None, typer.Option(
        "--csv", metavar="DIR", help="Write one CSV file per channel and period.csv into DIR "
        "(made if its parent exists).")] = None,
) -> None:
    """Write a run log's numeric channels and period table as Parquet and/or CSV tables.

    One table per channel: t_s (s), period, one column per field named with its unit; the
    period table has one row per period. Prints the files written.
    """
    problem = export_run(run_log, {"parquet": parquet, "csv": csv})
    if problem is not None:
        fail(problem)
        raise typer.Exit(2)


def folder_problem(option: str, folder: Path) -> str | None:
    """Why `folder` cannot take the tables (one line), or None: it is a folder, or it can be
    made as one in a folder that exists (a mistyped parent is refused, not created)."""
    if folder.exists():
        return None if folder.is_dir() else f"{option} {folder}: not a folder"
    parent = folder.absolute().parent
    if not parent.is_dir():
        return f"{option} {folder}: the folder {folder.parent} does not exist"
    return None


def export_run(path: Path, folders: dict[str, Path | None]) -> str | None:
    """Write the tables of the run log at `path` as each format in `folders` ("csv",
    "parquet" -> folder; None: not that format) and print the paths; the one-line problem
    instead (nothing written), or None."""
    from orchestrator.cli.export import numeric_channels, write_tables
    from orchestrator.review import summary
    from orchestrator.runlog import RunLogError

    wanted = {suffix: folder for suffix, folder in folders.items() if folder is not None}
    if not wanted:
        return "export: give --parquet DIR and/or --csv DIR"
    for suffix, folder in wanted.items():
        problem = folder_problem(f"--{suffix}", folder)
        if problem is not None:
            return problem
    try:
        topics = numeric_channels(summary.load(path))
        run = summary.load(path, tuple(topics))
    except RunLogError as error:
        return str(error)
    written: list[Path] = []
    for suffix, folder in wanted.items():
        try:
            folder.mkdir(exist_ok=True)
            written += write_tables(run, folder, suffix)
        except (OSError, ValueError) as error:
            reason = getattr(error, "strerror", None) or str(error).splitlines()[0]
            return f"--{suffix} {folder}: cannot write the tables: {reason}"
    print("\n".join(str(p) for p in written), file=sys.stdout)
    return None
