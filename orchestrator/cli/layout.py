"""`excosim layout`: the Foxglove layout of a run, fitted to it (orchestrator.review.layout),
from its log or, before it runs, from its scenario. Exit 0 written, 2 a user's mistake (one
line, nothing written)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.conventions import fail


def layout_command(
    source: Annotated[Path, typer.Argument(
        metavar="RUN.mcap|SCENARIO.toml", help="A run log, or the scenario of a run to come.")],
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="LAYOUT.json",
        help="The file to write (default: print it).")] = None,
    overrides: Annotated[list[str] | None, typer.Option(
        "--set", metavar="KEY=VALUE", help="Override a scenario value (repeatable; with a "
        "scenario only).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing file.")] = False,
) -> None:
    """Write the Foxglove/Lichtblick layout of a run: its weight band and target, a camera
    framing its arm, only the signals it logs ("Layouts" -> "Import from file...")."""
    from orchestrator.review.layout import layout_text

    if output is not None and output.suffix != ".json":
        _stop(f"output {str(output)!r}: a layout file ends in .json")
    if output is not None and output.exists() and not force:
        _stop(f"output {str(output)!r} already exists; remove it or add --force")
    if output is not None and not output.parent.is_dir():
        _stop(f"output {str(output)!r}: its folder does not exist")
    text = layout_text(_facts(source, overrides or []))
    if output is None:
        print(text, end="")
        return
    output.write_text(text, encoding="utf-8")
    print(output)


def _facts(source: Path, overrides: list[str]):
    from orchestrator.review.layout import LayoutFacts

    if source.suffix == ".mcap":
        from orchestrator.runlog import RunLogError, read_run

        if overrides:
            _stop("--set changes a scenario, not a run log")
        try:
            return LayoutFacts.of_run(read_run(source, topics=("/display",)))
        except (RunLogError, ValueError, OSError) as error:
            _stop(str(error).splitlines()[0])
    from orchestrator.scenario import ScenarioError, load_scenario

    try:
        return LayoutFacts.of_scenario(load_scenario(source, overrides))
    except ScenarioError as error:
        _stop(str(error))


def _stop(message: str) -> None:
    fail(message)
    raise typer.Exit(2)
