"""`excosim scenario export-ssp`: a scenario's plant as an SSP 1.0 archive for other masters
(orchestrator.ssp.export). Exit 0 written, 2 a user's mistake (one line, nothing written)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.conventions import fail


def export_ssp_command(
    scenario: Annotated[Path, typer.Argument(metavar="SCENARIO.toml", help="Scenario file.")],
    output: Annotated[Path, typer.Option("-o", "--output", metavar="PLANT.ssp",
                                         help="The archive to write.")],
    overrides: Annotated[list[str] | None, typer.Option(
        "--set", metavar="KEY=VALUE", help="Override a scenario value (repeatable).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing file.")] = False,
) -> None:
    """The plant's FMUs, one parameter set per role ("initialValues") and the port maps' unit
    conversions as SSP linear transformations; libcosim, ecos and FMPy read it."""
    from orchestrator.scenario import ScenarioError, load_scenario
    from orchestrator.ssp.export import export_ssp

    if output.suffix != ".ssp":
        _stop(f"output {str(output)!r}: an SSP archive ends in .ssp")
    if output.exists() and not force:
        _stop(f"output {str(output)!r} already exists; remove it or add --force")
    try:
        written = export_ssp(load_scenario(scenario, overrides or []), output)
    except ScenarioError as error:
        _stop(str(error))
    except (ValueError, OSError) as error:
        _stop(f"cannot export {scenario}: {error}")
    print(written)


def _stop(message: str) -> None:
    fail(message)
    raise typer.Exit(2)
