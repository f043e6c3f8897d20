"""Options that several commands share, defined once: the same flag, metavar and help
wherever it appears."""

from __future__ import annotations

from typing import Annotated

import typer

Trust = Annotated[bool, typer.Option("--trust", help="Run FMU files that differ from FMUs built "
                                     "here from our sources (they are native code).")]
AsJson = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")]
Workers = Annotated[int | None, typer.Option(
    "--workers", metavar="N", help="Local worker processes (default: the cores).")]
Scheduler = Annotated[str | None, typer.Option(
    "--scheduler", metavar="ADDRESS", help="Run on an existing Dask cluster, e.g. "
    "tcp://host:8786, instead of local workers.")]
RecycleAfter = Annotated[int, typer.Option(
    "--recycle-after", metavar="K", help="Replace a local worker process after K runs.")]
