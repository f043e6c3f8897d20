"""The documentation site: it builds with warnings as errors, its reference pages hold every
scenario key, CLI option and run-log field, and an item without a meaning fails the suite
(docs/gen_reference.py's `undocumented`, shown failing on mutated copies of the code)."""

from __future__ import annotations

import copy
import importlib.util
import subprocess
import sys
from pathlib import Path

import click
import pytest
import typer

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("gen_reference", ROOT / "docs" / "gen_reference.py")
gen_reference = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = gen_reference
_spec.loader.exec_module(gen_reference)


def test_every_scenario_key_cli_option_and_channel_field_has_a_meaning():
    assert gen_reference.undocumented() == []


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site as `make docs` builds it (mkdocs build --strict: a warning fails)."""
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**__import__("os").environ, "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stderr[-3000:]
    return out


def _page(site: Path, name: str) -> str:
    return (site / name / "index.html").read_text()


def test_the_site_builds_strict_with_every_page_of_the_nav(site):
    import yaml

    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)

    def pages(items):
        for item in items:
            for value in item.values():
                yield from (pages(value) if isinstance(value, list) else [value])

    listed = set(pages(config["nav"]))
    on_disk = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert listed == on_disk  # no page left out of the navigation, none missing
    for page in listed:
        built = site / ("" if page == "index.md" else page.removesuffix(".md")) / "index.html"
        assert built.is_file(), page
    assert "<!-- reference:" not in _page(site, "reference/scenario")


def test_the_reference_pages_hold_every_item(site):
    scenario, cli, runlog = (_page(site, f"reference/{name}") for name in
                             ("scenario", "cli", "runlog"))
    for row in gen_reference.scenario_keys():
        assert row["key"].replace("<", "&lt;").replace(">", "&gt;") in scenario, row["key"]
    for path, _, rows in gen_reference.cli_commands():
        assert path in cli
        for row in rows:
            assert row["name"] in cli, (path, row["name"])
    for entry in gen_reference.channels():
        for row in entry["fields"]:
            assert row["field"].replace("<", "&lt;").replace(">", "&gt;") in runlog, row
    assert "run_campaign" in _page(site, "reference/api")
    # The models' pages carry the models' own heads.
    assert "Valve-controlled asymmetric hydraulic cylinder" in _page(site, "models/cylinder")


# --- an item without a meaning fails: mutated copies of the code ---------------------------------

def test_a_new_scenario_key_without_a_meaning_is_found(monkeypatch):
    from pydantic import create_model

    from orchestrator.scenario import model

    mutated = create_model("Scenario", __base__=model.Scenario, dig_depth_bonus_m=(float, 0.0))
    monkeypatch.setattr(model, "Scenario", mutated)
    assert gen_reference.undocumented() == ["scenario key dig_depth_bonus_m"]


def test_a_removed_scenario_description_is_found():
    text = gen_reference.descriptions()
    del text["scenario"]["plant.supply.margin_pa"]
    assert gen_reference.undocumented(text) == ["scenario key plant.supply.margin_pa"]


def test_a_cli_option_without_help_is_found(monkeypatch):
    original = typer.main.get_command

    def with_an_undocumented_option(app):
        command = original(app)
        run = command.get_command(click.Context(command), "run")
        run.params.append(click.Option(["--undocumented-flag"], is_flag=True))
        return command

    monkeypatch.setattr(typer.main, "get_command", with_an_undocumented_option)
    assert gen_reference.undocumented() == ["option --undocumented-flag of excosim run"]


def test_a_channel_field_without_a_meaning_is_found(monkeypatch):
    from orchestrator.runlog import schemas

    joints = schemas.JOINT_STATE
    mutated = type(joints)(joints.name, joints.fields + ("new_angle_rad",))
    monkeypatch.setattr(schemas, "MESSAGES", tuple(mutated if m is joints else m
                                                   for m in schemas.MESSAGES))
    summary = copy.deepcopy(schemas.PERIOD_SUMMARY_SCHEMA)
    summary["properties"]["new_figure_kj"] = {"type": "number"}
    monkeypatch.setattr(schemas, "PERIOD_SUMMARY_SCHEMA", summary)
    assert gen_reference.undocumented() == [
        "field new_angle_rad of /joints (excosim.JointState)",
        "field new_figure_kj of /period (excosim.PeriodSummary)"]
