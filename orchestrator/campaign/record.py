"""The record of one digging period: plain, JSON-able data for the log and for analysis.

Keys (angles in the record's own units, per-joint lists in the order boom, stick, bucket):

    k                          period index, from 1
    t0_s                       campaign time at the period's start (s)
    deepest_point_m            [y_D, z_D] the period dug through (m): the planned D
    lowest_tip_m               [y, z] of the lowest measured tip sample (m; absent when the plant
                               measures no tip). Stage 3 closes the bucket with boom and stick
                               held, so the tip swings on its arc about the bucket pin, below D:
                               this is the deepest spot the bucket really reached (paper 2.1)
    dz_m, eps_m, flag, reset   eq. 5's step dz(k) (m); the correction eps (m) that led to it
                               (absent in period 1: no weighing came before it); Fig. 5's flag;
                               True when D came from the reset-and-shift
    mass_kg, error_kg          weighed mass m_k (kg); error m* - m_k (kg)
    predicted_mass_kg          the mass the strategy predicted for the period (kg); with
    mass_per_area_kg_m2,       its estimate of the mass per swept area and that estimate's
    mass_per_area_sigma_kg_m2  standard deviation (kg/m^2) when it chose D (planner.terrain
                               only; absent for the rule strategies and in period 1)
    duration_s                 duration of the period's trajectory (s)
    max_abs_velocity_deg_s, max_abs_acceleration_deg_s2, max_abs_jerk_deg_s3
                               exact peaks of the planned spline per joint
    tracking_rms_deg           RMS of measured minus reference angle per joint (deg)
    planner_ms                 wall time of the trajectory optimisation (ms)
    cycle_time_s, rated_payload_kg, fill_factor, productivity_t_h, energy_kj,
    throttled_energy_kj, throttled_share, energy_per_tonne_kj_t, peak_power_kw, mean_power_kw
                               the period's productivity figures: its measured duration (s,
                               the settle included), payload / rated payload, t/h, hydraulic
                               energy (kJ) and its throttled part, kJ/t, supply power (kW)
                               (formulas: orchestrator.campaign.productivity); each absent
                               when the plant does not measure what it needs (no rating, a
                               cylinder without E_supply, a payload below 1 g for kJ/t)
    via_points_rad             {joint: (5,)} joint via-points (rad)
    segment_durations_s        (4,) durations between via-points (s)
    spline                     {"degree", "knots_s", "coefficients_rad": {joint: (n,)}}: the
                               planned reference (`reference_spline(record)` rebuilds it)

Per-joint arrays are objects of flat lists, not nested lists, so that every field has a JSON
schema the viewers can parse (Foxglove's and Lichtblick's readers take arrays of scalars or of
objects only). Records of logs written before that (nested lists) are read as well.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orchestrator.campaign.productivity import PERIOD_KEYS, period_productivity
from planner.adaptation import AdaptationState, Decision
from planner.trajectory import JointTrajectory
from plant_models.plant import JOINTS, PeriodMeasurement

ESTIMATE_KEYS = ("predicted_mass_kg", "mass_per_area_kg_m2", "mass_per_area_sigma_kg_m2")
PER_JOINT = ("max_abs_velocity_deg_s", "max_abs_acceleration_deg_s2", "max_abs_jerk_deg_s3",
             "tracking_rms_deg")


def period_record(state: AdaptationState, decision: Decision, trajectory: JointTrajectory,
                  measurement: PeriodMeasurement, target_mass_kg: float,
                  t0_s: float, rated_payload_kg: float | None = None) -> dict[str, Any]:
    """The record of period `state.k` (keys: module docstring). rated_payload_kg: the plant's
    rated payload (kg; orchestrator.campaign.productivity.rated_payload_kg), None: no fill
    factor."""
    mass = float(measurement.weighed_mass_kg)
    record = {
        "k": state.k,
        "t0_s": float(t0_s),
        "deepest_point_m": [state.y_D, state.z_D],
        "dz_m": state.dz,
        "eps_m": decision.eps_m,
        "flag": state.flag,
        "reset": decision.reset,
        "mass_kg": mass,
        "error_kg": float(target_mass_kg) - mass,
        "duration_s": trajectory.duration,
        "max_abs_velocity_deg_s": _degrees(trajectory.peak_velocity),
        "max_abs_acceleration_deg_s2": _degrees(trajectory.peak_acceleration),
        "max_abs_jerk_deg_s3": _degrees(trajectory.peak_jerk),
        "tracking_rms_deg": _degrees(measurement.tracking_rms_rad),
        "planner_ms": trajectory.solve_time_ms,
        "via_points_rad": per_joint(trajectory.via_points),
        "segment_durations_s": np.asarray(trajectory.segment_durations).tolist(),
        "spline": {"degree": int(trajectory.spline.k),
                   "knots_s": np.asarray(trajectory.spline.t).tolist(),
                   "coefficients_rad": per_joint(trajectory.spline.c)},
    }
    tip_y, tip_z = (measurement.signals.get(name) for name in ("tip.y", "tip.z"))
    if tip_y is not None and tip_z is not None and len(tip_z):
        lowest = int(np.argmin(tip_z))
        record["lowest_tip_m"] = [float(tip_y[lowest]), float(tip_z[lowest])]
    if decision.eps_m is None:  # a JSON null has no type the viewers' schema readers take
        del record["eps_m"]
    for key in ESTIMATE_KEYS:
        value = getattr(decision, key)
        if value is not None:
            record[key] = float(value)
    record.update(period_productivity(measurement.t_s, measurement.signals, mass,
                                      rated_payload_kg))
    return record


def per_joint(values) -> dict[str, list[float]]:
    """(n, 3) values -> {"boom": [n], "stick": [n], "bucket": [n]}."""
    columns = np.asarray(values, dtype=float).reshape(-1, len(JOINTS)).T
    return {joint: column.tolist() for joint, column in zip(JOINTS, columns, strict=True)}


def joint_columns(value) -> np.ndarray:
    """(n, 3) array of a per-joint record field ({joint: [n]}, or a nested list (n, 3) as
    older logs have it)."""
    if isinstance(value, dict):
        return np.stack([np.asarray(value[joint], dtype=float) for joint in JOINTS], axis=1)
    return np.asarray(value, dtype=float)


def reference_spline(record: dict[str, Any]):
    """The planned reference of a period record as a scipy BSpline: q(t) (rad), t in s."""
    from scipy.interpolate import BSpline

    spline = record["spline"]
    return BSpline(np.asarray(spline["knots_s"], dtype=float),
                   joint_columns(spline["coefficients_rad"]), int(spline["degree"]))


def _degrees(values_rad) -> list[float]:
    return np.degrees(np.asarray(values_rad, dtype=float)).tolist()


def records_dataframe(records: list[dict[str, Any]]):
    """pandas DataFrame of records, index k: scalars as they are, D as y_D_m and z_D_m, per-joint
    lists as <name>_<joint>; the strategy's estimates (ESTIMATE_KEYS) and the productivity
    figures (orchestrator.campaign.productivity.PERIOD_KEYS) when a record has them; via-points,
    segment durations and the spline are left out."""
    import pandas as pd

    # The terrain strategy's estimates and the productivity figures (absent from older logs,
    # the energies from plants that measure none), in the frame of a run that has them only.
    estimates = [key for key in ESTIMATE_KEYS if any(key in record for record in records)]
    figures = [key for key in PERIOD_KEYS if any(key in record for record in records)]
    rows = []
    for record in records:
        row = {key: record.get(key) for key in ("k", "t0_s", "mass_kg", "error_kg", "reset",
                                                "flag", "dz_m", "eps_m", "duration_s",
                                                "planner_ms", *ESTIMATE_KEYS, *PERIOD_KEYS)}
        row["y_D_m"], row["z_D_m"] = record["deepest_point_m"]
        for key in PER_JOINT:
            for joint, value in zip(JOINTS, record[key], strict=True):
                row[f"{key}_{joint}"] = value
        rows.append(row)
    columns = ["k", "t0_s", "y_D_m", "z_D_m", "dz_m", "eps_m", "flag", "reset", "mass_kg",
               "error_kg", *estimates, "duration_s", "planner_ms",
               *(f"{key}_{joint}" for key in PER_JOINT for joint in JOINTS), *figures]
    return pd.DataFrame(rows, columns=columns).set_index("k")
