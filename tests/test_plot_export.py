"""`excosim export` writes every numeric channel and the period table as Parquet and CSV that read
back equal to the log (units in the column names, /signals included, old logs too); `excosim
plot` draws exactly the logged values of the span asked for, one axis per unit; `review --period
all` draws every period; and every mistake is one line, exit status 2, nothing written."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from run_log_files import cut_inside_chunk
from typer.testing import CliRunner

from orchestrator.campaign import run_campaign
from orchestrator.campaign.record import records_dataframe
from orchestrator.cli import export
from orchestrator.cli.app import app
from orchestrator.cli.plot import plot_fields
from orchestrator.runlog import read_run
from orchestrator.runlog.mcap_records import MAGIC
from orchestrator.runlog.units import signal_unit, unit_of, with_unit
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper-2020.toml"
runner = CliRunner()


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory) -> Path:
    """Two periods of the simulated excavator (every numeric channel, /signals included)."""
    path = tmp_path_factory.mktemp("plot-export") / "run.mcap"
    run_campaign(load_scenario(PAPER, ["periods=2"]), log_path=path)
    return path


@pytest.fixture(scope="module")
def logged(sim_log):
    """The log with every numeric channel decoded: what the tables must equal."""
    return read_run(sim_log, topics=read_run(sim_log).numeric_topics)


@pytest.fixture(scope="module")
def exported(sim_log, tmp_path_factory) -> tuple[Path, Path]:
    """(Parquet folder, CSV folder) of `excosim export`."""
    root = tmp_path_factory.mktemp("tables")
    done = runner.invoke(app, ["export", str(sim_log), "--parquet", str(root / "pq"),
                               "--csv", str(root / "csv")])
    assert done.exit_code == 0, done.output
    assert all(Path(line).is_file() for line in done.stdout.splitlines())
    return root / "pq", root / "csv"


def _logged_columns(channel) -> np.ndarray:
    """The channel's values after t_s as (n, columns), in the log's field order."""
    return np.column_stack([v.reshape(len(channel.period), -1)
                            for f, v in channel.fields.items() if f != "t_s"])


def test_every_numeric_channel_is_a_table_equal_to_the_log(logged, exported):
    parquet, csv = exported
    topics = list(logged.channels)
    assert {"/joints", "/cylinder/boom", "/pile/bucket", "/pile/profile", "/display",
            "/signals/boom", "/signals/supply"} <= set(topics)
    expected = sorted([export.channel_file(t, "") for t in topics] + ["period"])
    assert sorted(p.stem for p in csv.iterdir()) == expected
    assert sorted(p.stem for p in parquet.iterdir()) == expected
    for topic, channel in logged.channels.items():
        frame = pd.read_csv(csv / export.channel_file(topic))
        assert list(frame.columns[:2]) == ["t_s", "period"], topic
        assert len(frame) == len(channel.period) == logged.message_counts[topic]
        assert np.array_equal(frame["t_s"], channel.fields["t_s"])
        assert np.array_equal(frame["period"], channel.period)
        assert np.array_equal(frame.drop(columns=["t_s", "period"]).to_numpy(),
                              _logged_columns(channel), equal_nan=True), topic
        back = pq.read_table(parquet / export.channel_file(topic, ".parquet")).to_pandas()
        pd.testing.assert_frame_equal(back, frame, check_exact=True)


def test_the_period_table_is_the_review_csv_in_both_formats(sim_log, logged, exported,
                                                           tmp_path):
    parquet, csv = exported
    read = pd.read_csv(csv / "period.csv", index_col="k")
    pd.testing.assert_frame_equal(read, records_dataframe(logged.periods))
    back = pq.read_table(parquet / "period.parquet").to_pandas()
    pd.testing.assert_frame_equal(back, read, check_exact=True)
    done = runner.invoke(app, ["review", str(sim_log), "--csv", str(tmp_path / "p.csv"),
                               "--csv-channels", "/signals/supply,/cylinder/boom",
                               "--csv-dir", str(tmp_path)])
    assert done.exit_code == 0, done.output
    for name in ("p.csv", "signals_supply.csv", "cylinder_boom.csv"):  # one table builder
        other = csv / ("period.csv" if name == "p.csv" else name)
        assert (tmp_path / name).read_bytes() == other.read_bytes(), name


def test_signal_columns_carry_units_recorded_in_the_log(logged, exported):
    _, csv = exported
    boom = logged.channels["/signals/boom"]
    assert json.loads(boom.metadata["units"]) == ["J", "J", "kg"]
    assert list(pd.read_csv(csv / "signals_boom.csv").columns) == [
        "t_s", "period", "boom.E_supply_J", "boom.E_throttling_J", "boom.mass_load_kg"]
    assert list(pd.read_csv(csv / "signals_supply.csv").columns) == [
        "t_s", "period", "supply.p_pump_Pa", "supply.p_LS_Pa", "supply.sharing_1"]
    assert list(pd.read_csv(csv / "cylinder_boom.csv").columns) == [
        "t_s", "period", "x_m", "v_m_s", "p_A_Pa", "p_B_Pa", "F_N", "u_1", "F_ext_N"]


def test_logs_without_recorded_units_get_them_from_the_signal_names(logged):
    channel = logged.channels["/signals/supply"]
    old = dataclasses.replace(channel, metadata={"names": channel.metadata["names"]})
    assert [c for c, _, _ in export.channel_columns(old)] == [
        "supply.p_pump_Pa", "supply.p_LS_Pa", "supply.sharing_1"]
    recorded = dataclasses.replace(channel, metadata={
        "names": channel.metadata["names"], "units": json.dumps(["bar", "", "1"])})
    assert [c for c, _, _ in export.channel_columns(recorded)] == [
        "supply.p_pump_bar", "supply.p_LS_Pa", "supply.sharing_1"]
    unknown = dataclasses.replace(channel, metadata={"names": '["valve.a", "valve.b", "c"]'})
    assert [c for c, _, _ in export.channel_columns(unknown)] == ["valve.a", "valve.b", "c"]


@pytest.mark.parametrize(("name", "unit"), [
    ("p_A_Pa", "Pa"), ("v_m_s", "m/s"), ("measured_boom_rad", "rad"), ("u_1", "1"),
    ("p_A_boom_bar", "bar"), ("soil_F_y_kN", "kN"), ("removed_volume_m3", "m³"),
    ("z_m[3]", "m"), ("boom.E_supply_J", "J"), ("bus.send_jitter_s", "s"),
    ("error_kg", "kg"), ("tracking_rms_deg_boom", "deg"), ("max_abs_jerk_deg_s3_stick", "deg/s³"),
    ("productivity_t_h", "t/h"), ("energy_per_tonne_kj_t", "kJ/t"), ("peak_power_kw", "kW"),
    ("planner_ms", "ms"), ("fill_factor", None), ("E_supply", None),
])
def test_units_are_read_from_the_names(name, unit):
    assert unit_of(name) == unit


def test_signal_names_give_their_units():
    assert [signal_unit(n) for n in ("boom.E_supply", "stick.p_A", "tip.bucket_angle",
                                     "coupling.iterations", "bus.feedback_latency_s",
                                     "valve.spool")] == ["J", "Pa", "rad", "1", "s", ""]
    assert with_unit("bus.send_jitter_s", "s") == "bus.send_jitter_s"
    assert with_unit("boom.v", "m/s") == "boom.v_m_s" and with_unit("valve.spool", "") == \
        "valve.spool"


FIELDS = ["/cylinder/boom:p_A_Pa", "/cylinder/boom:u", "/display:p_A_boom_bar",
          "/signals/boom:boom.E_supply", "/period:error_kg", "/pile/profile:z_m[3]",
          "/joints:measured_boom_rad"]


@pytest.mark.parametrize("period", [None, 2])
def test_plot_draws_the_logged_values_of_the_span(logged, period):
    figure, series = plot_fields(logged, FIELDS, period)
    units = ["Pa", "1", "bar", "J", "kg", "m", "rad"]
    assert [s.unit for s in series] == units
    assert [axis.get_ylabel() for axis in figure.axes] == units  # one axis per unit
    expected = []
    for topic, field, pick in (("/cylinder/boom", "p_A_Pa", None), ("/cylinder/boom", "u", None),
                               ("/display", "p_A_boom_bar", None),
                               ("/signals/boom", "values", 0), ("/pile/profile", "z_m", 3),
                               ("/joints", "measured_boom_rad", None)):
        channel = logged.channels[topic]
        fields = channel.fields if period is None else channel.of_period(period)
        values = fields[field] if pick is None else fields[field][:, pick]
        expected.append((topic, fields["t_s"], values))
    ends = np.asarray(logged.period_end_ns) / 1e9
    errors = np.array([r["error_kg"] for r in logged.periods])
    expected.insert(4, ("/period", ends if period is None else ends[period - 1:period],
                        errors if period is None else errors[period - 1:period]))
    for s, axis, (topic, times, values) in zip(series, figure.axes, expected, strict=True):
        assert s.topic == topic and len(s.t_s) > 0
        assert np.array_equal(s.t_s, times) and np.array_equal(s.values, values)
        line = axis.get_lines()[0]
        assert np.array_equal(line.get_xdata(), times)
        assert np.array_equal(line.get_ydata(), values)


def test_plot_writes_a_png_named_after_the_run_and_fields(sim_log, tmp_path, monkeypatch):
    import matplotlib.image

    monkeypatch.chdir(tmp_path)
    done = runner.invoke(app, ["plot", str(sim_log), "/cylinder/boom:p_A_Pa",
                               "/period:error_kg", "--period", "1"])
    assert done.exit_code == 0, done.output
    name = "run-cylinder_boom_p_A_Pa+period_error_kg-period1.png"
    assert done.stdout == f"{name}\n" and os.listdir(tmp_path) == [name]
    image = matplotlib.image.imread(tmp_path / name)
    assert image.shape[0] > 300 and image[..., :3].std() > 0.05
    done = runner.invoke(app, ["plot", str(sim_log), "/joints:measured_boom_rad", "-o",
                               str(tmp_path / "boom.svg")])
    assert done.exit_code == 0 and (tmp_path / "boom.svg").read_text().startswith("<?xml")


def test_review_period_all_draws_every_period(sim_log, tmp_path):
    done = runner.invoke(app, ["review", str(sim_log), "--plots", str(tmp_path),
                               "--period", "all"])
    assert done.exit_code == 0, done.output
    names = sorted(p.name for p in tmp_path.iterdir())
    for k in (1, 2):
        assert f"period_{k:02d}_joints.png" in names
        assert f"period_{k:02d}_cylinder_pressures.png" in names
    assert "weight_error.png" in names and len(names) == 8


def _bad_logs(log: Path, folder: Path) -> dict[str, Path]:
    """Files that are not readable run logs: text, an MCAP file of something else, a run log
    whose scenario record is damaged."""
    text = folder / "notes.mcap"
    text.write_text("not a log")
    foreign = folder / "foreign.mcap"
    foreign.write_bytes(MAGIC + b"\x03" + b"\xff" * 40)
    data = log.read_bytes()
    at = data.index(b"{", data.index(b"excosim.scenario"))
    damaged = folder / "damaged.mcap"
    damaged.write_bytes(data[:at] + b"!" + data[at + 1:])
    return {"TEXT": text, "FOREIGN": foreign, "DAMAGED": damaged}


@pytest.mark.parametrize(("args", "expected"), [
    (["plot", "LOG", "/nope:x"], "has no channel /nope (numeric channels: /pile/profile"),
    (["plot", "LOG", "/tf:x"], "/tf: not a numeric channel"),
    (["plot", "LOG", "/resume:k"], "/resume: not a numeric channel"),
    (["plot", "LOG", "/joints:foo"], "/joints has no field foo; fields: reference_boom_rad, "),
    (["plot", "LOG", "/pile/profile:z_m"], "holds 220 values per message; pick one, e.g. z_m[0]"),
    (["plot", "LOG", "/period:flag"], "/period:flag is not a number"),
    (["plot", "LOG", "/period:nope"], "/period has no field nope; fields: t0_s"),
    (["plot", "LOG", "joints"], "'joints': expected TOPIC:FIELD"),
    (["plot", "LOG", "/joints:t_s"], "/joints:t_s is the time axis"),
    (["plot", "LOG", "/joints:measured_boom_rad", "--period", "3"],
     "--period 3: LOG holds periods 1-2"),
    (["plot", "LOG", "/joints:measured_boom_rad", "-o", "nowhere/x.png"],
     "the folder nowhere does not exist"),
    (["plot", "LOG", "/joints:measured_boom_rad", "-o", "x.jpg"], "expected a file name ending"),
    (["plot", "TEXT", "/joints:measured_boom_rad"], "is not an MCAP file"),
    (["plot", "DAMAGED", "/joints:measured_boom_rad"], "the scenario record is not JSON"),
    (["plot", "FOREIGN", "/joints:measured_boom_rad"], "not an excosim run log"),
    (["plot", "missing.mcap", "/joints:measured_boom_rad"], "cannot read missing.mcap"),
    (["export", "LOG"], "give --parquet DIR and/or --csv DIR"),
    (["export", "LOG", "--csv", "nowhere/tables"], "the folder nowhere does not exist"),
    (["export", "LOG", "--parquet", "LOG"], "not a folder"),
    (["export", "DAMAGED", "--csv", "tables"], "the scenario record is not JSON"),
    (["export", "TEXT", "--parquet", "tables"], "is not an MCAP file"),
    (["review", "LOG", "--plots", "figures", "--period", "some"],
     "--period some: expected a period number K or all"),
    (["review", "LOG", "--plots", "figures", "--period", "0"], "--period 0: LOG holds periods"),
])
def test_every_mistake_is_one_line_exit_2_and_writes_nothing(sim_log, tmp_path, monkeypatch,
                                                             args, expected):
    (tmp_path / "logs").mkdir()
    logs = {"LOG": sim_log, **_bad_logs(sim_log, tmp_path / "logs")}
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    args = [str(logs.get(a, a)) for a in args]
    done = runner.invoke(app, args)
    assert done.exit_code == 2, done.output
    assert done.stdout == "" and done.stderr.startswith("excosim: ")
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert expected.replace("LOG", str(sim_log)) in done.stderr
    assert os.listdir(work) == [] and not (sim_log.parent / "tables").exists()


def test_a_killed_run_is_exported_up_to_its_cut(sim_log, tmp_path):
    cut = cut_inside_chunk(sim_log, tmp_path / "killed.mcap")
    done = runner.invoke(app, ["export", str(cut), "--csv", str(tmp_path / "t")])
    assert done.exit_code == 0, done.output
    assert len(pd.read_csv(tmp_path / "t" / "period.csv")) == 1
    joints = pd.read_csv(tmp_path / "t" / "joints.csv")
    assert set(joints["period"]) == {1}
