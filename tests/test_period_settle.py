"""An arm that ends a period off its path's last pose (a bucket slowed in a heap) is held on that
pose before the weighing (orchestrator.plants.simulated_excavator, SETTLE_MAX_S), so that the
next period, which starts there, can start. The case is one of the robustness sweep's random
piles (sweeps/robustness.toml, fuzzy rule, seed 16), whose run ended in period 6 with "reference
starts 3.46 deg from the arm's bucket angle" before the hold; the same campaign without the hold
must still end so, or the test would not show the hold at work."""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator.campaign import run_campaign
from orchestrator.plants import simulated_excavator
from orchestrator.scenario import load_scenario

PAPER = Path(__file__).resolve().parent.parent / "scenarios" / "paper-2020.toml"
HEAP = ["periods=7", "plant.load_cell_noise_kg=0.5", "seed=16",
        "plant.pile.parameters.density=1365.7866862381854",
        "plant.pile.parameters.heap_height=0.5804615714962059",
        "plant.pile.parameters.heap_center_y=-9.647396508753626",
        "plant.pile.parameters.heap_half_width=2.9533993039743525",
        "plant.pile.parameters.ground_slope=-0.010759533566522185"]
H_S = 0.01  # the paper scenario's communication step


def test_a_lagging_arm_is_held_until_the_next_period_can_start():
    result = run_campaign(load_scenario(PAPER, HEAP))
    assert result.termination == "periods", result.message
    records = result.records
    # A period's samples span its planned duration (one step more for the grid's end); a held
    # period's, more.
    held = [r["k"] for r, after in zip(records, records[1:], strict=False)
            if after["t0_s"] - r["t0_s"] > r["duration_s"] + 2 * H_S]
    assert held, "no period was held: the case no longer shows the hold"
    assert all(after["t0_s"] - r["t0_s"] <= r["duration_s"] + simulated_excavator.SETTLE_MAX_S
               + 2 * H_S for r, after in zip(records, records[1:], strict=False))


def test_without_the_hold_the_same_campaign_cannot_start_its_next_period(monkeypatch):
    monkeypatch.setattr(simulated_excavator, "SETTLE_MAX_S", 0.0)
    result = run_campaign(load_scenario(PAPER, HEAP))
    assert result.termination == "error"
    assert "reference starts" in result.message and "bucket angle" in result.message


@pytest.mark.parametrize("scenario", ["paper-2020.toml"])
def test_the_paper_campaign_is_never_held(scenario):
    """Its arm ends every period within half the start tolerance: the hold changes nothing."""
    result = run_campaign(load_scenario(PAPER.parent / scenario, ["periods=20"]))
    assert all(after["t0_s"] - r["t0_s"] <= r["duration_s"] + 2 * H_S
               for r, after in zip(result.records, result.records[1:], strict=False))
