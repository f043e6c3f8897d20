"""The Foxglove layout of a run: panels fitted to the run's machine, target and signals.

One layout for Foxglove and Lichtblick, the same for a log file and a live run
(orchestrator.live): made from a run's facts (`LayoutFacts`: from its scenario before the run,
or from its log after), so that the weight band and the target line are the run's, the camera
frames the run's arm, and a signal the run does not log (a lab machine's soil force) is left
out instead of drawn as zeros. `excosim layout` writes it; `foxglove/excavator-layout.json` is
the paper scenario's (tests/test_foxglove_layout.py checks it is this module's output).

The layout's shape is the one Foxglove's "Layouts" menu exports and imports: "configById" (panel
id "<Type>!<suffix>" -> panel config), "layout" (a mosaic tree), "globalVariables",
"userNodes", "playbackConfig". Plots read /display, logged in the units their axes name (no
message-path functions: Lichtblick has none); legends sit above the plots, not over the data.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from orchestrator.review.summary import band_kg
from orchestrator.runlog.schemas import DISPLAY_SAMPLE
from plant_models.plant import JOINTS

_JOINT_COLORS = {"boom": ("#1f77b4", "#aec7e8"), "stick": ("#ff7f0e", "#ffbb78"),
                 "bucket": ("#2ca02c", "#98df8a")}
_GREY = "#9e9e9e"
_FOVY_DEG, _PHI_DEG = 45.0, 75.0  # the camera: 15 deg above the ground, looking along +y


@dataclass(frozen=True)
class LayoutFacts:
    """What a layout needs of a run. name: the scenario's; target_mass_kg: m*, kg; plant_kind:
    "sim" or "lab"; boom_foot_m: (y, z) m in the machine frame; reach_m: boom + stick + bucket
    length, m; dig_point_m: (y, z) m, D0; display_fields: the /display fields the run logs."""

    name: str
    target_mass_kg: float
    plant_kind: str
    boom_foot_m: tuple[float, float]
    reach_m: float
    dig_point_m: tuple[float, float]
    display_fields: frozenset[str]

    @classmethod
    def of_scenario(cls, scenario) -> LayoutFacts:
        """Before a run: what its scenario (orchestrator.scenario.Scenario) will log."""
        geometry = scenario.geometry()
        fields = set(DISPLAY_SAMPLE.fields[1:])
        if scenario.plant.kind == "lab":  # a real machine's /display has no pile signals
            fields = {f for f in fields if not f.startswith(("soil_", "bucket_mass"))}
        adaptation = scenario.adaptation
        return cls(scenario.name, float(scenario.target_mass_kg), scenario.plant.kind,
                   tuple(geometry.boom_foot_m), _reach(vars(geometry)),
                   (float(adaptation.y_D0_m), float(adaptation.z_D0_m)), frozenset(fields))

    @classmethod
    def of_run(cls, run) -> LayoutFacts:
        """After a run: from its log (orchestrator.runlog.RunFile read with /display decoded,
        `read_run(path, topics=("/display",))`). ValueError for a log without what a layout
        needs (its header, its geometry, its scenario's D0)."""
        header = run.metadata.get("excosim.run", {})
        try:
            geometry = json.loads(run.metadata["excosim.geometry"]["json"])
            adaptation = run.scenario["adaptation"]
            dig_point = (float(adaptation["y_D0_m"]), float(adaptation["z_D0_m"]))
            target = float(header["target_mass_kg"])
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"{run.path}: the log has no header, arm geometry or D0 to fit a "
                             "layout to (a log of a plant without an arm?)") from None
        display = run.channels.get("/display")
        fields = frozenset() if display is None else frozenset(
            name for name, values in display.fields.items()
            if name != "t_s" and len(values) and not all(math.isnan(v) for v in values))
        return cls(header.get("scenario_name", run.path.stem), target,
                   header.get("plant_kind", "sim"),
                   tuple(geometry["boom_foot_m"]), _reach(geometry), dig_point, fields)


def _reach(geometry: dict) -> float:
    return float(geometry["boom_length_m"] + geometry["stick_length_m"]
                 + geometry["bucket_length_m"])


def _round(value: float) -> float:
    """Three significant digits: a layout a person reads."""
    return float(f"{value:.3g}")


def _series(value: str, label: str, color: str, width: float | None = None) -> dict:
    series = {"value": value, "enabled": True, "timestampMethod": "receiveTime",
              "label": label, "color": color, "showLine": True}
    if width is not None:
        series["lineSize"] = width
    return series


def _plot(title: str, unit: str, paths: list[dict]) -> dict:
    return {"foxglovePanelTitle": title, "paths": paths, "xAxisVal": "timestamp",
            "isSynced": True, "showLegend": True, "legendDisplay": "top",
            "showPlotValuesInLegend": False, "showXAxisLabels": True, "showYAxisLabels": True,
            "yAxisLabel": unit, "sidebarDimension": 240}


def _camera(facts: LayoutFacts) -> tuple[dict, list[float]]:
    """Camera state and the ground grid's centre: the arm's workspace in front of the machine
    (world x = -y_machine from the boom foot to the reach, z around the foot) seen from the
    side, with D0 inside."""
    foot_x, foot_z = -facts.boom_foot_m[0], facts.boom_foot_m[1]
    reach = facts.reach_m
    dig_x, dig_z = -facts.dig_point_m[0], facts.dig_point_m[1]
    x_lo, x_hi = min(foot_x, dig_x) - 0.1 * reach, max(foot_x + reach, dig_x) + 0.05 * reach
    z_lo, z_hi = min(foot_z - 0.65 * reach, dig_z), foot_z + 0.75 * reach
    centre = [_round(0.5 * (x_lo + x_hi)), 0.0, _round(0.5 * (z_lo + z_hi))]
    half = 0.5 * max(x_hi - x_lo, z_hi - z_lo)
    distance = _round(1.15 * half / math.tan(math.radians(_FOVY_DEG / 2)))
    camera = {"distance": distance, "perspective": True, "phi": _PHI_DEG, "target": [0, 0, 0],
              "targetOffset": centre, "targetOrientation": [0, 0, 0, 1], "thetaOffset": 0,
              "fovy": _FOVY_DEG, "near": _round(0.02 * reach), "far": _round(500 * reach)}
    return camera, [centre[0], 0.0, 0.0]


def _scene(facts: LayoutFacts) -> dict:
    camera, grid_centre = _camera(facts)
    cell = 10 ** math.floor(math.log10(facts.reach_m / 5))  # 1 m for a 20 t arm, 0.1 m lab
    divisions = int(math.ceil(2 * facts.reach_m / cell))
    topics = ("/tf", "/scene/arm", "/scene/pile", "/scene/plan", "/scene/tip_trail")
    return {
        "foxglovePanelTitle": f"Arm, plan and pile: {facts.name} (side view, world frame)",
        "cameraState": camera, "followMode": "follow-pose", "followTf": "world",
        "fixedFrame": "world",
        "scene": {"enableStats": False, "transforms": {"editable": False, "showLabel": True,
                                                       "enablePreloading": True}},
        "transforms": {}, "topics": {topic: {"visible": True} for topic in topics},
        "layers": {"grid": {
            "visible": True, "frameLocked": True, "label": "Ground (z = 0)",
            "instanceId": "excosim-ground-grid", "layerId": "foxglove.Grid", "frameId": "world",
            "size": _round(divisions * cell), "divisions": divisions, "lineWidth": 1,
            "color": "#248eff", "position": grid_centre, "rotation": [0, 0, 0], "order": 1}},
        "imageMode": {},
    }


def _plots(facts: LayoutFacts) -> dict:
    have = facts.display_fields
    panels = {}
    for joint in JOINTS:
        dark, _ = _JOINT_COLORS[joint]
        panels[f"Plot!{joint}"] = _plot(
            f"{joint.capitalize()} joint: measured over reference (deg)", "deg",
            [_series(f"/display.measured_{joint}_deg", f"{joint} measured", dark, 1.5),
             _series(f"/display.reference_{joint}_deg", f"{joint} reference", "#bdbdbd", 3)])
    panels["Plot!tracking"] = _plot(
        "Tracking error, measured - reference (deg)", "deg",
        [_series(f"/display.tracking_error_{j}_deg", j, _JOINT_COLORS[j][0]) for j in JOINTS])
    pressures = [_series(f"/display.p_{side}_{j}_bar", f"{j} p_{side}", _JOINT_COLORS[j][i])
                 for j in JOINTS for i, side in enumerate("AB")]
    panels["Plot!pressures"] = _plot(
        "Cylinder chamber pressures (bar): A cap side (dark), B rod side (light)", "bar",
        pressures)
    soil = [_series("/display.soil_F_y_kN", "F_y (horizontal)", "#9467bd"),
            _series("/display.soil_F_z_kN", "F_z (vertical)", "#e377c2")]
    panels["Plot!soil"] = _plot("Soil force on the bucket (kN)", "kN", soil)
    band, target = band_kg(facts.target_mass_kg), facts.target_mass_kg
    panels["Plot!error"] = _plot(
        f"Weight error per period, m* - m (kg): within +/-{band:g} kg is on target", "kg",
        [_series("/period.error_kg", "error m* - m", "#d62728", 2),
         _series(f"{band:g}", f"+{band:g} kg", _GREY),
         _series(f"{-band:g}", f"-{band:g} kg", _GREY)])
    mass = [_series("/period.mass_kg", "weighed, per period", "#17becf", 2),
            _series("/display.bucket_mass_kg", "in bucket", "#8c564b"),
            _series(f"{target:g}", f"target m* = {target:g} kg", _GREY)]
    panels["Plot!mass"] = _plot(f"Dug mass (kg), target {target:g} kg", "kg", mass)
    for panel in panels.values():  # a signal the run does not log is left out, not drawn as 0
        panel["paths"] = [p for p in panel["paths"] if not p["value"].startswith("/display.")
                          or p["value"].removeprefix("/display.") in have]
    return {key: panel for key, panel in panels.items()
            if any(not _is_number(p["value"]) for p in panel["paths"])}


def _is_number(value: str) -> bool:
    try:
        float(value)
    except ValueError:
        return False
    return True


def _split(first, second, direction: str, percent: float) -> dict:
    return {"first": first, "second": second, "direction": direction,
            "splitPercentage": percent}


def _stack(ids: list[str], direction: str) -> str | dict:
    """Panels side by side (row) or one above the other (column), in equal shares."""
    if len(ids) == 1:
        return ids[0]
    return _split(ids[0], _stack(ids[1:], direction), direction, round(100 / len(ids), 1))


def layout(facts: LayoutFacts) -> dict:
    """The Foxglove layout (a JSON-able dict) of a run with these facts."""
    config = {"3D!arm": _scene(facts)}
    config["StateTransitions!periods"] = {
        "foxglovePanelTitle": "Period being played (/period/start.k)",
        "paths": [{"value": "/period/start.k", "timestampMethod": "receiveTime",
                   "label": "period"}], "isSynced": True}
    config["RawMessages!planned"] = {
        "foxglovePanelTitle": "Period being played: its plan (/period/start)",
        "topicPath": "/period/start", "diffEnabled": False, "diffMethod": "custom",
        "diffTopicPath": "", "showFullMessageForDiff": False, "expansion": "none"}
    config["RawMessages!period"] = {
        **config["RawMessages!planned"], "topicPath": "/period",
        "foxglovePanelTitle": "Last weighed period (/period)"}
    plots = _plots(facts)
    config.update(plots)
    joints = ["Plot!boom", "Plot!stick", "Plot!bucket", "Plot!tracking"]
    forces = [key for key in ("Plot!pressures", "Plot!soil") if key in plots]
    weights = [key for key in ("Plot!error", "Plot!mass") if key in plots]
    left = _split("3D!arm", _split("RawMessages!planned", "RawMessages!period", "row", 50),
                  "column", 62)
    right = _split("StateTransitions!periods",
                   _split(_stack(joints, "column"),
                          _split(_stack(forces, "row"), _stack(weights, "row"), "column", 50),
                          "column", 55), "column", 8)
    return {"configById": config, "globalVariables": {}, "userNodes": {},
            "playbackConfig": {"speed": 1}, "layout": _split(left, right, "row", 45)}


def layout_text(facts: LayoutFacts) -> str:
    """The layout as the file Foxglove imports (indented JSON, a newline at the end)."""
    return json.dumps(layout(facts), indent=2) + "\n"
