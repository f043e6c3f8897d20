"""foxglove/excavator-layout.json, the Foxglove layout for excosim run logs, checked against a
real run log so that renaming a topic, a field or a frame breaks this test, not the layout.

The layout's shape follows the layouts Foxglove exports and imports ("Layouts" menu, "Import from
file..."): "configById" (panel id "<Type>!<suffix>" -> panel config), "layout" (a mosaic tree of
panel ids with direction, first, second, splitPercentage), "globalVariables", "userNodes",
"playbackConfig"; see Foxglove's own examples in foxglove/foxglove-sdk
(python/foxglove-sdk-examples/so101-visualization/foxglove/lerobot_layout.json). Message-path
functions are the ones Foxglove documents for the Plot panel
(docs.foxglove.dev/docs/visualization/panels/plot, "Message path functions").

Topics, schemas and fields come from a 2-period run of scenarios/paper-2020.toml, read with the
`mcap` package: protobuf fields from the FileDescriptorSets stored in the file, JSON fields from
the stored JSON schema and the /period messages themselves, frames from /tf decoded with
mcap-protobuf-support and composed with scipy's rotations.
"""

import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from google.protobuf import descriptor_pb2
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from scipy.spatial.transform import Rotation

from orchestrator.campaign import run_campaign
from orchestrator.review.layout import LayoutFacts, layout_text
from orchestrator.review.layout import layout as make_layout
from orchestrator.review.summary import WITHIN_KG, band_kg
from orchestrator.runlog import read_run
from orchestrator.scenario import load_scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
LAYOUT_PATH = ROOT / "foxglove" / "excavator-layout.json"
SCENARIO = ROOT / "scenarios" / "paper-2020.toml"
PANEL_TYPES = {"3D", "Plot", "RawMessages", "StateTransitions"}
# docs.foxglove.dev/docs/visualization/panels/plot, "Message path functions" (scalar, operand,
# vector, struct and time-series functions).
PATH_FUNCTIONS = {
    "abs", "acos", "asin", "atan", "ceil", "cos", "degrees", "log", "log1p", "log2", "log10",
    "negative", "radians", "round", "sign", "sin", "sqrt", "tan", "trunc", "add", "sub", "mul",
    "div", "norm", "rpy", "quat", "delta", "derivative", "timedelta",
}
PATH = re.compile(r"^(?P<topic>/[A-Za-z0-9_/]+)(?P<fields>(\.[A-Za-z_]\w*(\[-?\d+\])?)*)"
                  r"(?P<functions>(\.@[a-z0-9]+(\([^)]*\))?)*)$")
# What a field's unit suffix becomes after the path's functions (SI name -> axis unit).
UNIT_SUFFIXES = {"_rad": "rad", "_Pa": "Pa", "_kg": "kg", "_N": "N", "_deg": "deg", "_bar": "bar",
                 "_kN": "kN"}
CONVERSIONS = {("rad", "degrees", None): "deg", ("Pa", "div", 1e5): "bar"}


@dataclass
class RunLogFacts:
    schemas: dict          # topic -> schema name
    fields: dict           # topic -> resolver of a field path: list[(name, index)] -> bool
    frames: set            # every frame id in /tf
    root_frames: set       # frames that are never a child
    points_world_m: np.ndarray  # (n, 3): frame origins over the run, pile surfaces


def _protobuf_resolver(schema) -> Callable:
    files = descriptor_pb2.FileDescriptorSet.FromString(schema.data).file
    types = {f"{file.package}.{message.name}": message
             for file in files for message in file.message_type}

    def resolve(path) -> bool:
        message = types[schema.name]
        for position, (name, _index) in enumerate(path):
            found = [field for field in message.field if field.name == name]
            if not found:
                return False
            if position < len(path) - 1:
                if found[0].type != descriptor_pb2.FieldDescriptorProto.TYPE_MESSAGE:
                    return False
                message = types[found[0].type_name.lstrip(".")]
        return True
    return resolve


def _json_resolver(schema, messages: list[dict]) -> Callable:
    json_schema = json.loads(schema.data)

    def resolve(path) -> bool:
        node, values = json_schema, messages
        for name, index in path:
            node = node.get("properties", {}).get(name)
            if node is None or not all(name in value for value in values):
                return False
            values = [value[name] for value in values]
            if index is not None:
                if node.get("type") != "array":
                    return False
                node, values = node.get("items", {}), [value[index] for value in values]
        return True
    return resolve


def _frame_origins(transforms) -> dict:
    """Frame -> origin (3,) m in the root frame, composing parent -> child transforms."""
    poses = {}
    for transform in transforms:
        parent_xyz, parent_rotation = poses.get(transform.parent_frame_id,
                                                (np.zeros(3), Rotation.identity()))
        t, q = transform.translation, transform.rotation
        rotation = Rotation.from_quat([q.x, q.y, q.z, q.w])
        poses[transform.child_frame_id] = (parent_xyz + parent_rotation.apply([t.x, t.y, t.z]),
                                           parent_rotation * rotation)
    return {frame: xyz for frame, (xyz, _) in poses.items()}


@pytest.fixture(scope="module")
def run_log(tmp_path_factory) -> RunLogFacts:
    path = tmp_path_factory.mktemp("foxglove") / "run.mcap"
    result = run_campaign(load_scenario(SCENARIO, ["periods=2"]), log_path=path)
    assert result.termination == "periods", result
    return run_log_facts(path)


def run_log_facts(path: Path) -> RunLogFacts:
    """What the layout may refer to in the run log at `path` (test_lab_log_tools.py checks a
    lab run's log with it too)."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {channel.topic: summary.schemas[channel.schema_id]
                   for channel in summary.channels.values()}
        periods = [json.loads(message.data)
                   for _, _, message in reader.iter_messages(topics=["/period"])]
        parents, children, points = set(), set(), []
        for _, _, _, tf in reader.iter_decoded_messages(topics=["/tf"]):
            parents |= {transform.parent_frame_id for transform in tf.transforms}
            children |= {transform.child_frame_id for transform in tf.transforms}
            points += list(_frame_origins(tf.transforms).values())
        for _, _, _, profile in reader.iter_decoded_messages(topics=["/pile/profile"]):
            # world x = -y_machine (orchestrator.runlog.scene)
            points += [[-y, 0.0, z] for y, z in zip(profile.y_m, profile.z_m, strict=True)]
    fields = {topic: (_json_resolver(schema, periods) if schema.encoding == "jsonschema"
                      else _protobuf_resolver(schema))
              for topic, schema in schemas.items()}
    return RunLogFacts({topic: schema.name for topic, schema in schemas.items()}, fields,
                       parents | children, parents - children, np.array(points))


@pytest.fixture(scope="module")
def layout() -> dict:
    return json.loads(LAYOUT_PATH.read_text(encoding="utf-8"))


def mosaic_leaves(node) -> list[str]:
    """Panel ids of a mosaic tree, left to right; ValueError naming a malformed node."""
    if isinstance(node, str):
        return [node]
    if not (isinstance(node, dict) and set(node) == {"direction", "first", "second",
                                                     "splitPercentage"}):
        raise ValueError(f"mosaic node must be a panel id or a split, got {node!r}")
    if node["direction"] not in ("row", "column") or not 0 < node["splitPercentage"] < 100:
        raise ValueError(f"bad split {node['direction']!r} at {node['splitPercentage']!r}")
    return mosaic_leaves(node["first"]) + mosaic_leaves(node["second"])


def parse_path(value: str):
    """(topic, [(field, index or None)], [(function, operand or None)]) of a message path."""
    match = PATH.match(value)
    if match is None:
        raise ValueError(f"not a message path: {value!r}")
    fields = [(name, None if index == "" else int(index)) for name, index in
              re.findall(r"\.([A-Za-z_]\w*)(?:\[(-?\d+)\])?", match["fields"])]
    functions = [(name, None if operand == "" else float(operand)) for name, operand in
                 re.findall(r"\.@([a-z0-9]+)(?:\(([^)]*)\))?", match["functions"])]
    return match["topic"], fields, functions


def is_reference_line(value: str) -> bool:
    try:
        float(value)
    except ValueError:
        return False
    return True


def message_paths(layout: dict) -> list[str]:
    """Every message path or topic the panels read (reference lines left out)."""
    out = []
    for panel_id, config in layout["configById"].items():
        kind = panel_id.split("!")[0]
        if kind in ("Plot", "StateTransitions"):
            out += [path["value"] for path in config["paths"]
                    if not is_reference_line(path["value"])]
        elif kind == "RawMessages":
            out.append(config["topicPath"])
        elif kind == "3D":
            out += list(config["topics"])
    return out


def unresolved(layout: dict, facts: RunLogFacts) -> list[str]:
    """The layout's references that the run log does not have: topics, fields, frames."""
    missing = []
    for value in message_paths(layout):
        topic, fields, _ = parse_path(value)
        if topic not in facts.schemas:
            missing.append(f"topic {topic} ({value})")
        elif fields and not facts.fields[topic](fields):
            missing.append(f"field of {facts.schemas[topic]} ({value})")
    for panel_id, config in layout["configById"].items():
        if panel_id.startswith("3D!"):
            frames = [config["followTf"], config["fixedFrame"]]
            frames += [layer["frameId"] for layer in config["layers"].values()]
            missing += [f"frame {frame}" for frame in frames if frame not in facts.frames]
    return missing


def plots(layout: dict) -> dict:
    return {key: value for key, value in layout["configById"].items() if key.startswith("Plot!")}


def test_layout_has_the_shape_foxglove_imports(layout):
    assert set(layout) == {"configById", "layout", "globalVariables", "userNodes",
                           "playbackConfig"}
    assert layout["globalVariables"] == {} and layout["userNodes"] == {}
    assert layout["playbackConfig"]["speed"] > 0
    for panel_id, config in layout["configById"].items():
        kind, _, suffix = panel_id.partition("!")
        assert kind in PANEL_TYPES and re.fullmatch(r"[A-Za-z0-9_]+", suffix), panel_id
        assert isinstance(config["foxglovePanelTitle"], str) and config["foxglovePanelTitle"]
    for panel_id, config in plots(layout).items():
        assert config["xAxisVal"] == "timestamp" and config["isSynced"], panel_id
        for path in config["paths"]:
            assert path["enabled"] is True and path["timestampMethod"] == "receiveTime", path
            assert path["label"] and re.fullmatch(r"#[0-9a-f]{6}", path["color"]), path


def test_every_panel_in_the_tree_has_a_config_and_every_config_is_placed(layout):
    leaves = mosaic_leaves(layout["layout"])
    assert len(leaves) == len(set(leaves)), leaves
    assert set(leaves) == set(layout["configById"])


def test_every_topic_field_and_frame_exists_in_a_run_log(layout, run_log):
    assert unresolved(layout, run_log) == []


@pytest.mark.parametrize("old, new", [
    ("/display.measured_boom_deg", "/display.measured_boom"),  # a renamed protobuf field
    ("/display.p_B_stick_bar", "/displays.p_B_stick_bar"),     # a renamed topic
    ("/period.error_kg", "/period.weight_error_kg"),          # a renamed JSON field
    ('"followTf": "world"', '"followTf": "map"'),             # a frame /tf does not have
    ('"/scene/pile": {', '"/scene/piles": {'),                # a 3D topic
])
def test_a_renamed_topic_field_or_frame_is_caught(layout, run_log, old, new):
    text = json.dumps(layout)
    assert old in text
    assert unresolved(json.loads(text.replace(old, new)), run_log) != []


def test_3d_panel_draws_the_arm_and_pile_in_the_root_frame(layout, run_log):
    (config,) = [c for key, c in layout["configById"].items() if key.startswith("3D!")]
    assert config["followTf"] == config["fixedFrame"] == "world"
    assert run_log.root_frames == {"world"}
    assert {"boom", "stick", "bucket", "bucket_tip"} <= run_log.frames
    shown = {topic for topic, settings in config["topics"].items() if settings["visible"]}
    assert {run_log.schemas[topic] for topic in shown} == {"foxglove.FrameTransforms",
                                                           "foxglove.SceneUpdate"}
    assert shown == {"/tf", "/scene/arm", "/scene/pile", "/scene/plan", "/scene/tip_trail"}


def camera_pose(camera: dict):
    """Camera position (3,) and unit view direction (3,) in the display frame, as Foxglove's 3D
    panel places it: spherical (distance, phi, -thetaOffset) turned +90 deg about x, about
    targetOffset (foxglove/studio, ThreeDeeRender/renderables/CameraStateSettings.ts)."""
    r, phi = camera["distance"], math.radians(camera["phi"])
    theta = -math.radians(camera["thetaOffset"])
    target = np.array(camera["targetOffset"], dtype=float)
    position = target + r * np.array([math.sin(phi) * math.sin(theta),
                                       -math.sin(phi) * math.cos(theta), math.cos(phi)])
    return position, (target - position) / r


def test_camera_sees_the_whole_run_from_the_side(layout, run_log):
    camera = layout["configById"]["3D!arm"]["cameraState"]
    position, forward = camera_pose(camera)
    # The arm moves in the world x-z plane: look along +y, at most 20 deg off it.
    assert forward @ np.array([0.0, 1.0, 0.0]) >= math.cos(math.radians(20))
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    relative = run_log.points_world_m - position
    depth = relative @ forward
    assert np.all((depth > camera["near"]) & (depth < camera["far"]))
    # Every frame origin and pile surface point inside the view of a square panel.
    half_fov = math.radians(camera["fovy"]) / 2
    assert np.max(np.abs(relative @ right) / depth) <= math.tan(half_fov)
    assert np.max(np.abs(relative @ up) / depth) <= math.tan(half_fov)


def displayed_unit(value: str) -> str:
    _, fields, functions = parse_path(value)
    name = fields[-1][0]
    (unit,) = [unit for suffix, unit in UNIT_SUFFIXES.items() if name.endswith(suffix)]
    for function, operand in functions:
        unit = CONVERSIONS[(unit, function, operand)]
    return unit


def test_every_series_is_in_the_unit_its_axis_names(layout):
    for panel_id, config in plots(layout).items():
        units = {displayed_unit(path["value"]) for path in config["paths"]
                 if not is_reference_line(path["value"])}
        assert units == {config["yAxisLabel"]}, panel_id


def test_the_layout_reads_the_same_in_foxglove_and_lichtblick(layout):
    """Lichtblick has no message-path functions (`.@div(...)` is a syntax error there, and
    `.@degrees` is ignored) and ignores `lineStyle`: the layout uses neither, plotting /display,
    which is logged in the units the axes name."""
    used = {function for value in message_paths(layout)
            for function, _ in parse_path(value)[2]}
    assert used == set() and used <= PATH_FUNCTIONS
    assert "lineStyle" not in json.dumps(layout)


def test_measured_is_drawn_over_reference(layout):
    # Both viewers draw a plot's series with Chart.js, which paints the first dataset last (on
    # top): the measured angle comes first, the reference under it, wider and light.
    for joint in ("boom", "stick", "bucket"):
        paths = [p["value"] for p in layout["configById"][f"Plot!{joint}"]["paths"]]
        assert paths.index(f"/display.measured_{joint}_deg") \
            < paths.index(f"/display.reference_{joint}_deg")


def reference_lines(layout: dict, panel_id: str) -> list[float]:
    return sorted(float(path["value"]) for path in layout["configById"][panel_id]["paths"]
                  if is_reference_line(path["value"]))


def test_reference_lines_are_the_review_band_and_the_paper_target(layout):
    assert reference_lines(layout, "Plot!error") == [-WITHIN_KG, WITHIN_KG]
    assert reference_lines(layout, "Plot!mass") == [load_scenario(SCENARIO).target_mass_kg]
    others = [reference_lines(layout, panel_id) for panel_id in plots(layout)
              if panel_id not in ("Plot!error", "Plot!mass")]
    assert others and all(found == [] for found in others)


def test_legends_sit_above_the_plots_not_over_the_data(layout):
    assert {config["legendDisplay"] for config in plots(layout).values()} == {"top"}


def test_the_shipped_layout_is_the_paper_scenarios_generated_one(layout):
    facts = LayoutFacts.of_scenario(load_scenario(SCENARIO))
    assert LAYOUT_PATH.read_text(encoding="utf-8") == layout_text(facts)


# -- a layout per run: generated from a fresh log of each kind of machine ----------------------

@pytest.fixture(scope="module")
def full_scale_log(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("foxglove-20t") / "run.mcap"
    scenario = load_scenario(ROOT / "scenarios" / "excavator-20t.toml", ["periods=1"])
    result = run_campaign(scenario, log_path=path)
    assert result.termination == "periods", result
    return path


@pytest.fixture(scope="module")
def paper_log(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("foxglove-paper") / "run.mcap"
    result = run_campaign(load_scenario(SCENARIO, ["periods=1"]), log_path=path)
    assert result.termination == "periods", result
    return path


MACHINES = {"paper": "paper_log", "20 t": "full_scale_log", "lab (emulated, over CAN)":
            "lab_hil_run"}


@pytest.fixture(params=list(MACHINES), scope="module")
def machine_log(request) -> Path:
    found = request.getfixturevalue(MACHINES[request.param])
    path = found[1] if isinstance(found, tuple) else found
    return Path(path)


def test_each_machines_layout_fits_its_own_log(machine_log):
    run = read_run(machine_log, topics=("/display",))
    facts = LayoutFacts.of_run(run)
    generated = make_layout(facts)
    assert unresolved(generated, run_log_facts(machine_log)) == []
    # Every /display series is a field the log holds: none would draw as a line of zeros.
    logged = run.channels["/display"].fields
    for value in message_paths(generated):
        topic, fields, _ = parse_path(value)
        if topic == "/display":
            assert not np.isnan(logged[fields[0][0]]).any(), value
    # The band and the target are the run's, from its header.
    target = float(run.metadata["excosim.run"]["target_mass_kg"])
    band = band_kg(target)
    assert reference_lines(generated, "Plot!error") == [-band, band]
    assert reference_lines(generated, "Plot!mass") == [target]
    # The layout of a scenario before its run is the layout of its log after it.
    scenario = scenario_from_dict(run.scenario)
    assert LayoutFacts.of_scenario(scenario) == facts


def test_each_machines_camera_sees_its_arm_and_workspace(machine_log):
    generated = make_layout(LayoutFacts.of_run(read_run(machine_log, topics=("/display",))))
    camera = generated["configById"]["3D!arm"]["cameraState"]
    facts = run_log_facts(machine_log)
    run = read_run(machine_log)
    geometry = json.loads(run.metadata["excosim.geometry"]["json"])
    reach = geometry["boom_length_m"] + geometry["stick_length_m"] + geometry["bucket_length_m"]
    # The arm's workspace, not the whole pile: surface points beyond the reach need not show.
    workspace = facts.points_world_m[facts.points_world_m[:, 0]
                                     <= -geometry["boom_foot_m"][0] + reach]
    position, forward = camera_pose(camera)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    relative = workspace - position
    depth = relative @ forward
    assert np.all((depth > camera["near"]) & (depth < camera["far"]))
    tan_half = math.tan(math.radians(camera["fovy"]) / 2)
    assert np.max(np.abs(relative @ right) / depth) <= tan_half
    assert np.max(np.abs(relative @ up) / depth) <= tan_half
    # ... and the arm fills a good part of the view, not a speck: its frames span more than
    # a third of the view's width.
    across = relative @ right / depth
    assert across.max() - across.min() > 2 * tan_half / 3
