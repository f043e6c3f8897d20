"""Test helper: copies of our HydraulicCylinder changed as another tool's FMU would differ,
built into their own FMU folder (under `root`)."""

import shutil
from pathlib import Path

import pytest

import fmus


def own_supply_cylinder(root: Path) -> Path:
    """HydraulicCylinder whose p_pump is a parameter (its own supply setting), not an input."""
    folder = root / "HydraulicCylinder"
    shutil.copytree(Path(fmus.__file__).parent / "HydraulicCylinder", folder)
    table = folder / "variables.toml"
    text = table.read_text()
    start = text.index('name = "p_pump"')
    end = text.index("[[variable]]", start)
    entry = text[start:end].replace('causality = "input"', 'causality = "parameter"').replace(
        'variability = "continuous"', 'variability = "fixed"')
    table.write_text(text[:start] + entry + text[end:])
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("EXCOSIM_FMU_DIR", str(root / "fmu"))
        return fmus.build_model(folder)
