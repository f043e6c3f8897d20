"""What the figure modules (orchestrator/review/plots_*.py) share: the pyplot handle, the joint
colours, the period record and its via-point times, and when the bucket is in the soil."""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np

from orchestrator.runlog import RunFile
from plant_models.plant import JOINTS

COLOURS = {"boom": "tab:blue", "stick": "tab:orange", "bucket": "tab:green"}
# Limits and via-points are drawn in colours no joint uses, so that a reader never takes a limit
# line for a joint's curve.
LIMIT_COLOUR = "tab:red"
VIA_COLOUR = "0.55"
SOIL_COLOUR = "tan"
PA_PER_BAR = 1e5

__all__ = ["COLOURS", "JOINTS", "LIMIT_COLOUR", "PA_PER_BAR", "SOIL_COLOUR", "VIA_COLOUR",
           "pyplot", "record", "soil_spans", "via_times"]


def pyplot() -> ModuleType:
    """matplotlib.pyplot on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")  # files only; never needs a display
    import matplotlib.pyplot as plt

    return plt


def record(run: RunFile, k: int) -> dict[str, Any]:
    """The /period record of period k (from 1)."""
    return run.periods[k - 1]


def via_times(period_record: dict[str, Any]) -> np.ndarray:
    """Times of the five via-points from the period's start (s): 0 and the cumulated segment
    durations (the last one is the period's end)."""
    return np.concatenate([[0.0], np.cumsum(period_record["segment_durations_s"])])


def soil_spans(run: RunFile, k: int) -> list[tuple[float, float]]:
    """Time spans (s from the period's start) of period k in which the bucket is in the soil:
    its tip lies below the pile surface at the tip (/pile/bucket tip_z_m < surface_z_at_tip_m).

    The geometric test, not a nonzero soil force (F_y_N, F_z_N): the Pile FMU computes the force
    from the surface 1.5 cells ahead of the tip and ramps it to zero at rest, so it is nonzero
    while the tip skims just above a trench (the face ahead is higher) and zero while a buried
    bucket stands still; "in the soil" is where the tip is, which is what the test reads.
    Empty when the log has no /pile/bucket samples. Each span widens by half a sample step at
    both ends, so that a single sample below the surface still has a width."""
    channel = run.channels.get("/pile/bucket")
    if channel is None:
        return []
    samples = channel.of_period(k)
    if not len(samples["t_s"]):
        return []
    t = samples["t_s"] - record(run, k)["t0_s"]
    inside = samples["tip_z_m"] < samples["surface_z_at_tip_m"]
    edges = np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    half = 0.5 * float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    return [(float(t[a]) - half, float(t[b]) + half) for a, b in zip(starts, ends, strict=True)]
