"""The review figures show what a reviewer needs, checked on the matplotlib objects the plot_*
functions return: the tracking error is measured minus reference from the log, the lowest tip
point is the lowest tip sample, limits are not drawn in a joint's colour, the pressure figure
has one legend, via-point lines and soil spans where the tip is below the surface, a stretched
pile profile says so, and the compare figure has whole-period ticks, resets, m* and labels that
name what differs between the runs."""

from pathlib import Path

import matplotlib
import numpy as np
import pytest
from matplotlib.colors import same_color

from orchestrator.campaign import run_campaign
from orchestrator.review.plots import (
    PLOT_TOPICS,
    lowest_tip_point,
    plot_cylinder_pressures,
    plot_error_overlay,
    plot_joints,
    plot_pile_profiles,
    plot_tip_paths,
    plot_weight_error,
    run_labels,
    soil_spans,
    vertical_stretch,
    via_times,
    write_plots,
)
from orchestrator.review.plots_common import COLOURS, JOINTS
from orchestrator.review.summary import load
from orchestrator.scenario import load_scenario

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Three-period paper runs without and with load-cell noise, read with the plot topics."""
    folder = tmp_path_factory.mktemp("figures")
    paths = {}
    for name, overrides in (("quiet", []), ("noisy", ["plant.load_cell_noise_kg=0.5"])):
        paths[name] = folder / f"{name}.mcap"
        run_campaign(load_scenario(PAPER, ["periods=3", *overrides]), log_path=paths[name])
    return paths


@pytest.fixture(scope="module")
def run(logs):
    return load(logs["quiet"], PLOT_TOPICS)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def _line(ax, label):
    (line,) = [line for line in ax.get_lines() if line.get_label() == label]
    return line


def _legend_count(fig) -> int:
    return len(fig.legends) + sum(ax.get_legend() is not None for ax in fig.axes)


def test_tracking_error_axis_is_measured_minus_reference_from_the_log(run):
    fig = plot_joints(run, 2)
    error_ax = fig.axes[1]
    samples = run.channels["/joints"].of_period(2)
    t0 = run.periods[1]["t0_s"]
    assert "tracking error" in error_ax.get_ylabel()
    for joint in JOINTS:
        line = _line(error_ax, f"{joint} tracking error")
        expected = np.degrees(samples[f"measured_{joint}_rad"] - samples[f"reference_{joint}_rad"])
        assert np.array_equal(line.get_ydata(), expected)
        assert np.allclose(line.get_xdata(), samples["t_s"] - t0)
        assert same_color(line.get_color(), COLOURS[joint])
    # The servo does track: errors are small but not zero, which an angle axis could not show.
    assert 0 < np.abs(_line(error_ax, "boom tracking error").get_ydata()).max() < 5


def test_joint_limits_are_not_in_a_joint_colour_and_the_legend_is_outside(run):
    fig = plot_joints(run, 2)
    limits = run.scenario["limits"]
    for ax, key in zip(fig.axes[2:], ("velocity_deg_s", "acceleration_deg_s2", "jerk_deg_s3"),
                       strict=True):
        bounds = {abs(line.get_ydata()[0]) for line in ax.get_lines()
                  if len(set(line.get_ydata())) == 1 and line.get_ydata()[0] != 0}
        assert bounds == set(map(float, limits[key]))
        for line in ax.get_lines():
            if len(set(line.get_ydata())) == 1 and line.get_ydata()[0] != 0:
                assert not any(same_color(line.get_color(), c) for c in COLOURS.values())
    assert [ax.get_legend() for ax in fig.axes] == [None] * len(fig.axes)
    (legend,) = fig.legends
    fig.canvas.draw()
    box = legend.get_window_extent()
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent()), "the legend covers an axes"


def test_tip_paths_show_the_lowest_tip_sample_beside_the_planned_d(run):
    fig = plot_tip_paths(run)
    ax = fig.axes[0]
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "D: planned deepest point" in labels and "lowest tip point reached" in labels
    for k in (1, 3):  # tip_path_periods(3)
        samples = run.channels["/pile/bucket"].of_period(k)
        lowest = _line(ax, f"lowest tip, period {k}")
        i = np.argmin(samples["tip_z_m"])
        assert lowest.get_ydata()[0] == samples["tip_z_m"].min()
        assert lowest.get_xdata()[0] == samples["tip_y_m"][i]
        assert lowest_tip_point(run, k) == (samples["tip_y_m"][i], samples["tip_z_m"].min())
        planned = _line(ax, f"D, period {k}")
        assert [planned.get_xdata()[0], planned.get_ydata()[0]] == \
            run.periods[k - 1]["deepest_point_m"]
        assert lowest.get_marker() != planned.get_marker()


def test_a_stretched_pile_profile_says_by_how_much(run):
    fig = plot_pile_profiles(run)
    ax = fig.axes[0]
    stretch = ax.get_aspect()
    surface = run.channels["/pile/profile"].of_period(3)
    assert stretch == vertical_stretch(surface["y_m"][-1], surface["z_m"][-1])
    assert stretch > 1  # three periods dig a shallow trench into an 11 m wide pile
    assert f"vertical scale × {stretch:g}" in ax.get_ylabel()
    # A surface as deep as it is wide is drawn at equal scales, and says that instead.
    assert vertical_stretch(np.array([0.0, 4.0]), np.array([0.0, -4.0])) == 1


def test_pressures_have_one_legend_via_point_lines_and_soil_spans(run):
    fig = plot_cylinder_pressures(run, 2)
    assert _legend_count(fig) == 1
    record = run.periods[1]
    vias = np.concatenate([[0.0], np.cumsum(record["segment_durations_s"])])
    assert np.allclose(via_times(record), vias)
    spans = soil_spans(run, 2)
    assert spans, "the bucket digs in period 2"
    samples = run.channels["/pile/bucket"].of_period(2)
    t = samples["t_s"] - record["t0_s"]
    below = samples["tip_z_m"] < samples["surface_z_at_tip_m"]
    inside = np.zeros_like(below)
    for start, end in spans:
        inside |= (t >= start) & (t <= end)
    assert np.array_equal(inside, below)
    for ax in fig.axes:
        vertical = sorted(line.get_xdata()[0] for line in ax.get_lines()
                          if len(set(line.get_xdata())) == 1)
        assert np.allclose(vertical, vias)
        shaded = ax.patches  # the axvspan rectangles: the figure draws no other patch
        drawn = sorted((p.get_x(), p.get_x() + p.get_width()) for p in shaded)
        assert np.allclose(drawn, sorted(spans))
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any(label.startswith("bucket in the soil") for label in labels)
    assert "via-point" in labels


def test_compare_labels_name_the_differing_key_not_the_file(logs):
    runs = [load(logs[name]) for name in ("quiet", "noisy")]
    assert run_labels(runs) == ["paper-2020, plant.load_cell_noise_kg=0",
                                "paper-2020, plant.load_cell_noise_kg=0.5"]
    # What `excosim compare` passes (its names of the runs) does not put paths in the legend.
    fig = plot_error_overlay(runs, [str(logs["quiet"]), str(logs["noisy"])])
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    for label in labels:
        assert "/" not in label
    assert sum("plant.load_cell_noise_kg" in label for label in labels) == 2


def test_same_scenario_runs_get_their_file_names(logs, tmp_path):
    copy = tmp_path / "again.mcap"
    copy.write_bytes(logs["quiet"].read_bytes())
    labels = run_labels([load(logs["quiet"]), load(copy)])
    assert labels == ["paper-2020 (quiet.mcap)", "paper-2020 (again.mcap)"]
    # The same file name in two folders: the caller's names (or numbers) tell them apart.
    (tmp_path / "b").mkdir()
    other = tmp_path / "b" / "quiet.mcap"
    other.write_bytes(copy.read_bytes())
    runs = [load(logs["quiet"]), load(other)]
    assert run_labels(runs, ["a/quiet", "b/quiet"]) == ["paper-2020 (quiet.mcap) a/quiet",
                                                         "paper-2020 (quiet.mcap) b/quiet"]
    assert run_labels(runs) == ["paper-2020 (quiet.mcap) #1", "paper-2020 (quiet.mcap) #2"]


def test_compare_has_whole_period_ticks_resets_and_the_target(logs):
    runs = [load(logs[name]) for name in ("quiet", "noisy")]
    runs[1].periods[1]["reset"] = True  # pretend a reset in period 2 of the second run
    fig = plot_error_overlay(runs)
    ax = fig.axes[0]
    fig.canvas.draw()
    ticks = [tick for tick in ax.get_xticks() if ax.get_xlim()[0] <= tick <= ax.get_xlim()[1]]
    assert ticks == [1.0, 2.0, 3.0]
    assert "m* = 30 kg" in ax.get_title()
    rings = [line for line in ax.get_lines() if line.get_marker() == "o"
             and line.get_markerfacecolor() == "none"]
    assert [(list(r.get_xdata()), list(r.get_ydata())) for r in rings] == \
        [([2], [runs[1].periods[1]["error_kg"]])]
    assert "reset (D moved)" in [t.get_text() for t in fig.legends[0].get_texts()]
    single = plot_weight_error(runs[1])
    single.canvas.draw()
    assert all(float(t).is_integer() for t in single.axes[0].get_xticks())


def test_every_figure_is_written_and_not_blank_for_a_short_run(run, tmp_path):
    import matplotlib.image

    written = write_plots(run, tmp_path, period=3)
    assert sorted(p.name for p in written) == [
        "period_03_cylinder_pressures.png", "period_03_joints.png", "pile_profiles.png",
        "productivity.png", "tip_paths.png", "weight_error.png"]
    for path in written:
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 400 and image.shape[1] > 700
        assert image[..., :3].std() > 0.05, path.name
