"""The measured run a calibration fits: per period, the reference the plant was driven with
(the planned spline of its /period record), the measured joint angles (/joints) and the weighed
mass (the record's mass_kg), read from any run log: a simulated run or a lab run.

The log must hold at least one complete period with its spline and mass, and the /joints
channel with the measured and reference angles of the three joints; its machine preset must be
the scenario's (a log of another machine is refused).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orchestrator.calibrate.errors import CalibrationError
from plant_models.plant import JOINTS, JointReference

NEEDED_FIELDS = ("t_s", *(f"measured_{j}_rad" for j in JOINTS),
                 *(f"reference_{j}_rad" for j in JOINTS))
RECORD_KEYS = ("k", "t0_s", "mass_kg", "duration_s", "spline")


@dataclass(frozen=True)
class MeasuredPeriod:
    """One logged period: k, the spline (knots s, coefficients (n, 3) rad, degree), its
    duration (s), the log's sample times from the period's start (s), the measured and the
    reference joint angles there ((m, 3) rad) and the weighed mass (kg)."""

    k: int
    knots_s: np.ndarray
    coefficients_rad: np.ndarray
    degree: int
    duration_s: float
    t_s: np.ndarray
    measured_rad: np.ndarray
    reference_rad: np.ndarray
    mass_kg: float

    def reference(self, step_s: float) -> JointReference:
        """The spline on the grid 0, h, 2h, ... to the first sample at or after its end, at rest
        after it (as orchestrator.campaign.loop.sample_reference samples a planned one)."""
        from scipy.interpolate import BSpline

        spline = BSpline(self.knots_s, self.coefficients_rad, self.degree)
        n = math.ceil(self.duration_s / step_s - 1e-9) + 1
        t_s = np.arange(n) * step_s
        inside = np.clip(t_s, 0.0, self.duration_s)
        velocity, acceleration = spline(inside, nu=1), spline(inside, nu=2)
        velocity[t_s > self.duration_s] = 0.0
        acceleration[t_s > self.duration_s] = 0.0
        return JointReference(t_s=t_s, position_rad=spline(inside), velocity_rad_s=velocity,
                              acceleration_rad_s2=acceleration)

    @property
    def own_tracking_rms_deg(self) -> float:
        """RMS over the period and the joints of measured minus reference angle (deg)."""
        return math.degrees(float(np.sqrt(np.mean((self.measured_rad - self.reference_rad)**2))))


@dataclass(frozen=True)
class MeasuredRun:
    """The periods of a run log, its plant kind ("sim", "lab"), preset and target mass (kg)."""

    path: Path
    plant_kind: str
    preset: str
    target_mass_kg: float
    periods: tuple[MeasuredPeriod, ...]

    @property
    def own_tracking_rms_deg(self) -> float:
        """The log's own tracking RMS (deg): measured vs reference over every period."""
        return float(np.sqrt(np.mean([p.own_tracking_rms_deg**2 for p in self.periods])))


def read_measured(path: Path, preset: str) -> MeasuredRun:
    """The measured run at `path`, checked (module docstring); CalibrationError (one line)."""
    from orchestrator.campaign.record import joint_columns
    from orchestrator.runlog import RunLogError, read_run

    if not path.is_file():
        raise CalibrationError(f"--against {path}: no such file")
    try:
        run = read_run(path, topics=("/joints",))
        data = run.scenario
    except (RunLogError, OSError) as error:
        raise CalibrationError(f"--against {path}: not a readable run log ({error})") from None
    except (KeyError, ValueError):
        raise CalibrationError(f"--against {path}: holds no scenario record") from None
    logged = data.get("machine", {}).get("preset") if isinstance(data, dict) else None
    if logged != preset:
        raise CalibrationError(f"--against {path}: a run of the {logged!r} machine preset, the "
                               f"scenario's is {preset!r}: calibrate with a scenario of the "
                               "same machine")
    joints = run.channels.get("/joints")
    missing = [f for f in NEEDED_FIELDS if joints is None or f not in joints.fields]
    if missing:
        raise CalibrationError(f"--against {path}: no /joints channel with "
                               f"{', '.join(missing)}: the fit needs the measured and reference "
                               "joint angles")
    periods = []
    for record in run.periods:
        if any(key not in record for key in RECORD_KEYS):
            absent = [key for key in RECORD_KEYS if key not in record]
            raise CalibrationError(f"--against {path}: period {record.get('k')}'s record has "
                                   f"no {', '.join(absent)}: the fit needs the spline the "
                                   "period was driven with and its weighed mass")
        samples = joints.of_period(int(record["k"]))
        if len(samples["t_s"]) < 2:
            raise CalibrationError(f"--against {path}: period {record['k']} has no /joints "
                                   "samples")
        spline = record["spline"]
        periods.append(MeasuredPeriod(
            k=int(record["k"]), knots_s=np.asarray(spline["knots_s"], dtype=float),
            coefficients_rad=joint_columns(spline["coefficients_rad"]),
            degree=int(spline["degree"]), duration_s=float(record["duration_s"]),
            t_s=np.asarray(samples["t_s"], dtype=float) - float(record["t0_s"]),
            measured_rad=np.stack([samples[f"measured_{j}_rad"] for j in JOINTS], axis=1),
            reference_rad=np.stack([samples[f"reference_{j}_rad"] for j in JOINTS], axis=1),
            mass_kg=float(record["mass_kg"])))
    if not periods:
        raise CalibrationError(f"--against {path}: holds no complete period to fit")
    kind = run.metadata.get("excosim.run", {}).get("plant_kind", "?")
    return MeasuredRun(path, kind, preset, float(data.get("target_mass_kg", math.nan)),
                       tuple(periods))
