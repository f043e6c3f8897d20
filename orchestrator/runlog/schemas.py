"""Message schemas of a run log: custom protobuf messages (package `excosim`) and the JSON schema
of the per-period summary.

The protobuf messages are proto2 with explicit presence: a field the plant did not measure is
absent from the message (not a misleading 0). Every high-rate message is a flat list of doubles
(field 1 is always `t_s`, campaign time in s), so the writer can encode a whole period at once
with numpy (`orchestrator.runlog.mcap_records`). Field numbers never change; new fields get new
numbers.
Names carry their SI unit (`_m`, `_m_s`, `_Pa`, `_N`, `_kg`, `_rad`, `_m3`), except on
/display (DisplaySample), whose fields are in the units a person reads (deg, bar, kN), so that a
viewer's plot needs no unit conversion (Lichtblick has no message-path math).

Signal names come from `plant_models.plant.PeriodMeasurement.signals` ("<component>.<variable>")
and the FMU roles of `plant_models.model_spec`.
"""

from __future__ import annotations

from dataclasses import dataclass

from google.protobuf import descriptor_pb2

from plant_models.plant import JOINTS

PACKAGE = "excosim"


@dataclass(frozen=True)
class DoubleMessage:
    """A protobuf message of optional doubles (field numbers 1..n in order) and, optionally,
    packed repeated doubles after them. `signals[i]` is the measurement signal behind
    `fields[i]` ("" where the writer computes the value itself)."""

    name: str
    fields: tuple[str, ...]
    signals: tuple[str, ...] = ()
    repeated: tuple[str, ...] = ()

    @property
    def full_name(self) -> str:
        return f"{PACKAGE}.{self.name}"

    def number(self, field: str) -> int:
        """Protobuf field number of `field` (scalar or repeated)."""
        return (self.fields + self.repeated).index(field) + 1


JOINT_STATE = DoubleMessage(
    "JointState",
    ("t_s",)
    + tuple(f"reference_{joint}_rad" for joint in JOINTS)
    + tuple(f"measured_{joint}_rad" for joint in JOINTS),
)

# Field -> FMU role of a HydraulicCylinder (plant_models.model_spec: outputs, then inputs).
_CYLINDER_ROLES = (
    ("x_m", "x"), ("v_m_s", "v"), ("p_A_Pa", "p_A"), ("p_B_Pa", "p_B"), ("F_N", "F"),
    ("u", "u"), ("F_ext_N", "F_ext"),
)
CYLINDER_STATE = DoubleMessage(
    "CylinderState",
    ("t_s",) + tuple(name for name, _ in _CYLINDER_ROLES),
    ("",) + tuple(role for _, role in _CYLINDER_ROLES),
)


def cylinder_signals(joint: str) -> tuple[str, ...]:
    """Measurement signal names ("boom.p_A", ...) behind CylinderState's fields for `joint`."""
    return tuple(f"{joint}.{role}" if role else "" for role in CYLINDER_STATE.signals)


_PILE_BUCKET = (
    ("bucket_mass_kg", "pile.bucket_mass"),
    ("F_y_N", "pile.F_y"),
    ("F_z_N", "pile.F_z"),
    ("surface_z_at_tip_m", "pile.surface_z_at_tip"),
    ("removed_volume_m3", "pile.removed_volume"),
    ("dumped_mass_kg", "pile.dumped_mass"),
    ("pile_mass_kg", "pile.pile_mass"),
    ("tip_y_m", "tip.y"),
    ("tip_z_m", "tip.z"),
    ("tip_bucket_angle_rad", "tip.bucket_angle"),  # absolute: boom + stick + bucket (geometry)
)
PILE_BUCKET_STATE = DoubleMessage(
    "PileBucketState",
    ("t_s",) + tuple(name for name, _ in _PILE_BUCKET),
    ("",) + tuple(signal for _, signal in _PILE_BUCKET),
)

# Pile surface after a period: cell-centre y (m, machine frame) and surface height z (m).
PILE_PROFILE = DoubleMessage("PileProfile", ("t_s",), repeated=("y_m", "z_m"))

# Any other signals of one component: `values` in the order the channel metadata "names" gives;
# "units" their units (JSON list; older logs lack it: orchestrator.runlog.units derives them).
SIGNAL_SAMPLE = DoubleMessage("SignalSample", ("t_s",), repeated=("values",))

# What a person reads in a viewer, at the /tf rate: angles and tracking error in deg, chamber
# pressures in bar, the soil force in kN (field -> source: a joint angle, or a signal).
_DISPLAY = (
    tuple((f"reference_{joint}_deg", f"reference.{joint}") for joint in JOINTS)
    + tuple((f"measured_{joint}_deg", f"measured.{joint}") for joint in JOINTS)
    + tuple((f"tracking_error_{joint}_deg", f"error.{joint}") for joint in JOINTS)
    + tuple((f"p_{chamber}_{joint}_bar", f"{joint}.p_{chamber}")
            for joint in JOINTS for chamber in ("A", "B"))
    + (("soil_F_y_kN", "pile.F_y"), ("soil_F_z_kN", "pile.F_z"),
       ("bucket_mass_kg", "pile.bucket_mass"))
)
DISPLAY_SAMPLE = DoubleMessage(
    "DisplaySample",
    ("t_s",) + tuple(name for name, _ in _DISPLAY),
    ("",) + tuple(source for _, source in _DISPLAY),
)
DISPLAY_SCALE = {"_deg": 57.29577951308232, "_bar": 1e-5, "_kN": 1e-3, "_kg": 1.0}  # per SI unit

MESSAGES = (JOINT_STATE, CYLINDER_STATE, PILE_BUCKET_STATE, PILE_PROFILE, SIGNAL_SAMPLE,
            DISPLAY_SAMPLE)


def file_descriptor_set(message: DoubleMessage) -> bytes:
    """Serialized google.protobuf.FileDescriptorSet defining `message` (what MCAP and Foxglove
    expect as a protobuf schema's data)."""
    proto = descriptor_pb2.FileDescriptorProto(
        name=f"{PACKAGE}/{message.name}.proto", package=PACKAGE, syntax="proto2"
    )
    body = proto.message_type.add(name=message.name)
    double = descriptor_pb2.FieldDescriptorProto.TYPE_DOUBLE
    for field in message.fields:
        body.field.add(
            name=field, number=message.number(field), type=double,
            label=descriptor_pb2.FieldDescriptorProto.LABEL_OPTIONAL,
        )
    for field in message.repeated:
        added = body.field.add(
            name=field, number=message.number(field), type=double,
            label=descriptor_pb2.FieldDescriptorProto.LABEL_REPEATED,
        )
        added.options.packed = True
    return descriptor_pb2.FileDescriptorSet(file=[proto]).SerializeToString()


def _triple(unit: str) -> dict:
    return {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3,
            "description": f"[boom, stick, bucket], {unit}"}


def _number(description: str) -> dict:
    return {"type": "number", "description": description}


def _per_joint(description: str) -> dict:
    """An object of one flat list per joint (nested arrays have no schema a viewer reads)."""
    return {"type": "object", "description": description,
            "properties": {joint: {"type": "array", "items": {"type": "number"}}
                           for joint in JOINTS},
            "required": list(JOINTS)}


# What the campaign puts in a period record (orchestrator.campaign.record). Every field has a
# type the viewers' JSON-schema readers take (Foxglove and Lichtblick: scalars, objects with
# properties, arrays whose items are scalars or objects); the writer stores any JSON object, so
# a key the schema does not name is kept but not typed.
PERIOD_SUMMARY_SCHEMA: dict = {
    "title": "excosim.PeriodSummary",
    "description": "One digging period: where it dug, what it weighed, how the arm moved.",
    "type": "object",
    "properties": {
        "k": {"type": "integer", "minimum": 1, "description": "period number, 1-based"},
        "t0_s": _number("campaign time at the period's start, s"),
        "deepest_point_m": {"type": "array", "items": {"type": "number"}, "minItems": 2,
                            "maxItems": 2, "description": "deepest point D [y, z], m"},
        "lowest_tip_m": {"type": "array", "items": {"type": "number"}, "minItems": 2,
                         "maxItems": 2,
                         "description": "lowest point [y, z] the measured bucket tip reached, m"},
        "dz_m": _number("depth step dz of eq. 5, m"),
        "eps_m": _number("fuzzy correction eps that led to dz, m (absent in period 1)"),
        "flag": {"type": "boolean", "description": "D has been shifted (paper Fig. 5)"},
        "reset": {"type": "boolean", "description": "D was reset (workspace limit)"},
        "mass_kg": _number("weighed mass, kg"),
        "error_kg": _number("target minus weighed mass, kg"),
        "predicted_mass_kg": _number("mass the strategy predicted for the period, kg (terrain "
                                     "strategy only; absent in period 1)"),
        "mass_per_area_kg_m2": _number("strategy's estimate of the mass per swept area it "
                                       "dug with, kg/m^2 (terrain strategy only)"),
        "mass_per_area_sigma_kg_m2": _number("standard deviation of that estimate, kg/m^2"),
        "duration_s": _number("period duration, s"),
        "max_abs_velocity_deg_s": _triple("deg/s"),
        "max_abs_acceleration_deg_s2": _triple("deg/s^2"),
        "max_abs_jerk_deg_s3": _triple("deg/s^3"),
        "tracking_rms_deg": _triple("deg"),
        "planner_ms": _number("planner wall time, ms"),
        # The productivity figures (orchestrator.campaign.productivity), each absent when the
        # plant does not measure what it needs.
        "cycle_time_s": _number("measured duration of the period (its samples' span, the "
                                "settle included), s"),
        "rated_payload_kg": _number("the bucket's rated payload, kg"),
        "fill_factor": _number("payload / rated payload"),
        "productivity_t_h": _number("payload per hour of digging, t/h"),
        "energy_kj": _number("hydraulic energy from the supply (boom, stick, bucket), kJ"),
        "throttled_energy_kj": _number("part of it the metering edges and checks made heat, kJ"),
        "throttled_share": _number("throttled_energy_kj / energy_kj"),
        "energy_per_tonne_kj_t": _number("hydraulic energy per tonne dug, kJ/t"),
        "peak_power_kw": _number("peak supply power over a communication step, kW"),
        "mean_power_kw": _number("energy_kj / cycle_time_s, kW"),
        "via_points_rad": _per_joint("joint via-points per joint, rad"),
        "segment_durations_s": {"type": "array", "items": {"type": "number"},
                                "description": "durations between via-points, s"},
        "spline": {
            "type": "object", "description": "the planned reference: a B-spline per joint",
            "properties": {
                "degree": {"type": "integer", "description": "spline degree (5)"},
                "knots_s": {"type": "array", "items": {"type": "number"},
                            "description": "knot vector, s"},
                "coefficients_rad": _per_joint("B-spline coefficients per joint, rad"),
            },
        },
    },
    "additionalProperties": True,
}


def _object(description: str, properties: dict) -> dict:
    return {"type": "object", "description": description, "properties": properties,
            "additionalProperties": True}


# What `excosim run --resume` needs to continue after a period (orchestrator.campaign.resume),
# on /resume in the period's own chunk: a period is in the file with its state or not at all.
# The plant part is orchestrator.plants.plant_state's; FMU states are base64 strings of the
# bytes the FMU serialized (its own format; ours carry a checksum and the build's GUID).
RESUME_STATE_SCHEMA: dict = {"title": "excosim.ResumeState", **_object(
    "What a resumed run needs to continue after this period (excosim run --resume)", {
        "format": {"type": "integer", "description": "layout of this record (1)"},
        "k": {"type": "integer", "minimum": 1, "description": "the period this state follows"},
        "t0_next_s": _number("campaign time at the next period's start, s"),
        "adaptation": _object("the adaptation state period k dug with", {
            "y_D": _number("D's y, m"), "z_D": _number("D's z, m"),
            "dz": _number("depth step dz of eq. 5, m"),
            "flag": {"type": "boolean", "description": "D has been shifted"},
            "k": {"type": "integer", "description": "period index"},
        }),
        "weighed_mass_kg": _number("the load cell's reading after period k, kg (the next "
                                   "period's D follows from it)"),
        "strategy": _object("what the terrain strategy learnt up to period k (absent for the "
                            "rule strategies; planner.repose_bank)", {
            "weights": {"type": "array", "items": {"type": "number"},
                        "description": "weight of each repose hypothesis"},
            "hypotheses": {"type": "array", "items": _object("one repose hypothesis", {
                "surface_z_m": {"type": "array", "items": {"type": "number"},
                                "description": "its surface estimate at the cells, m"},
                "mass_per_area_kg_m2": _number("its mass per swept area, kg/m^2"),
                "variance_kg2_m4": _number("variance of that estimate, kg^2/m^4"),
            })},
        }),
        "plant": _object("the simulated plant's state (orchestrator.plants.plant_state)", {
            "format": {"type": "integer", "description": "layout of the plant state (1)"},
            "fmus": _object("component -> its FMU's serialized state, base64", {
                role: {"type": "string", "contentEncoding": "base64"}
                for role in (*JOINTS, "pile")}),
            "servos": _per_joint("each servo's filter state (pressure feedback), N"),
            "load_cell_rng": _object("numpy bit generator state of the load-cell noise", {
                "bit_generator": {"type": "string", "description": "e.g. PCG64"},
                "state": _object("the generator's words", {
                    "state": {"type": "integer"}, "inc": {"type": "integer"}}),
                "has_uint32": {"type": "integer"}, "uinteger": {"type": "integer"},
            }),
            "steps": {"type": "integer", "description": "cylinder communication steps taken"},
            "pile_time_s": _number("the pile FMU's time, s"),
            "start_pose_rad": {"type": "array", "items": {"type": "number"}, "minItems": 3,
                               "maxItems": 3,
                               "description": "pose the FMUs were instantiated at, rad"},
        }),
    })}
