"""The --trust rule of the commands that run a scenario's FMUs (`run`, `scenario show`,
`emulate`), the same as `replay`'s (docs/reliability.md).

An FMU is native code that runs inside this process. Our models, named by name, always run: the
FMUs built with the package from this tree's sources (fmus.packaged; built here with gcc where
the sources were edited). An FMU file a scenario names runs without --trust only when its content
(fmus.identity.content_hash) is that of one of our builds, FMI 2.0 or 3.0 (a copy of our FMU,
say), or of an FMU this machine built from earlier sources and its build cache still holds
(fmus.cached_content_hashes); any other file is refused with its sha256, and with --trust it runs
and the command says so on stderr, with the file's full sha256 (which the run log records too).
Comparing needs no compiler while the sources are the package's (fmus.local_content_hashes).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orchestrator.cli.conventions import fail

SHORT_HASH = 12  # hex digits of a sha256 shown in a refusal


@dataclass(frozen=True)
class ForeignFmu:
    """An FMU file of a scenario role whose content is none of our builds."""

    role: str
    path: Path
    sha256: str


def foreign_fmus(scenario: Any) -> list[ForeignFmu]:
    """The scenario's FMU files that are not our builds, in role order. Raises UnsafeArchive
    for a file that is not a safe archive, BuildError when our FMUs cannot be had (sources
    edited on a machine without gcc)."""
    import fmus
    from fmus.identity import content_hash

    files = {role: spec.fmu for role, spec in scenario.fmu_specs().items()
             if spec.fmu not in fmus.MODELS}
    if not files:
        return []
    ours = fmus.local_content_hashes()
    fmi3_checked = False
    out = []
    for role, name in files.items():
        path = Path(name)
        data = path.read_bytes()
        digest = content_hash(data, f"plant.{role}.fmu: {path}")
        if digest not in ours and not fmi3_checked:  # our FMI 3.0 builds are ours too,
            ours = {**fmus.cached_content_hashes(), **ours, **fmus.local_content_hashes(3)}
            fmi3_checked = True  # and what this machine built from earlier sources
        if digest not in ours:
            out.append(ForeignFmu(role, path, hashlib.sha256(data).hexdigest()))
    return out


def trust_problem(scenario: Any, trust: bool, quiet: bool = False) -> tuple[str, int] | None:
    """None when every FMU of `scenario` may run; else (one line, exit status): 2 for an FMU
    file that is not ours without --trust or not a safe archive, 1 when our FMUs cannot be
    built to compare with. With --trust, each foreign FMU is named on stderr (unless quiet)."""
    import fmus

    try:
        foreign = foreign_fmus(scenario)
    except fmus.UnsafeArchive as error:
        return str(error), 2
    except OSError as error:
        return f"cannot read an FMU file of the scenario: {error.strerror or error}", 2
    except fmus.BuildError as error:
        return f"cannot build our FMUs to check the scenario's FMU files against: {error}", 1
    if foreign and not trust:
        first = foreign[0]
        more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
        return (f"plant.{first.role}.fmu: {first.path} (sha256 {first.sha256[:SHORT_HASH]}) is "
                f"not an FMU built from this version's sources{more}; an FMU is native code: "
                "check where the file comes from, then --trust runs it"), 2
    if not quiet:
        for item in foreign:
            fail(f"--trust: plant.{item.role}.fmu runs {item.path} (sha256 {item.sha256})")
    return None
