"""A campaign moves the heap it starts with out of the cyclic collector's sight while it digs
and puts it back afterwards (orchestrator.campaign.heap); a process's own freeze is kept."""

import gc
from pathlib import Path

from orchestrator.campaign import run_campaign
from orchestrator.scenario import load_scenario

PAPER = Path(__file__).resolve().parents[1] / "scenarios" / "paper-2020.toml"


def campaign_freeze_counts() -> list[int]:
    """gc.get_freeze_count() after each period of a two-period campaign, and after it."""
    seen = []
    result = run_campaign(load_scenario(PAPER, ["periods=2"]),
                          progress=lambda record: seen.append(gc.get_freeze_count()))
    assert result.termination == "periods", result.message
    return seen + [gc.get_freeze_count()]


def test_the_starting_heap_is_frozen_while_the_campaign_digs_and_thawed_after():
    assert gc.get_freeze_count() == 0
    *during, after = campaign_freeze_counts()
    assert all(count > 10_000 for count in during)  # modules, numpy, scipy: far more
    assert after == 0


def test_a_process_that_froze_its_heap_keeps_its_freeze():
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        counts = campaign_freeze_counts()
        # Not thawed (0) nor frozen again (thousands more): only frozen objects freed since.
        assert all(0.99 * frozen < count <= frozen for count in counts), (frozen, counts)
    finally:
        gc.unfreeze()
