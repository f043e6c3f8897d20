"""What a run log says about its campaign, read from the file alone: the summary `excosim review`
prints (and gives as JSON) and the per-run figures `excosim compare` sets side by side.

A reviewer may hold only the MCAP file: no scenario file, no FMUs. Everything here comes from
the file's metadata and /period records (`orchestrator.runlog.reader`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from orchestrator.review.productivity import power_limit_kw, run_productivity
from orchestrator.runlog import RunFile, RunLogError, read_run
from orchestrator.runlog.records import loads, runs_problem

WITHIN_KG = 3.0  # the band the paper's Figure 9 holds after period 1 (section 3.2), at m* = 30 kg
BAND_FRACTION = WITHIN_KG / 30.0  # the same band for any target: 10 % of m*


def band_kg(target_mass_kg: float) -> float:
    """Half-width (kg) of the band around the target that counts as on target: 10 % of m*,
    i.e. the paper's +-3 kg at its 30 kg (a lab bucket's 1.2 kg gets +-0.12 kg)."""
    return BAND_FRACTION * float(target_mass_kg)


def load(path: str | Path, topics: tuple[str, ...] = ()) -> RunFile:
    """The run log at `path`, read tolerantly (a killed run gives its complete periods);
    RunLogError (one line) if it is not an excosim run log or a period record lacks what the
    figures read (orchestrator.runlog.records). topics: numeric channels to decode."""
    run = read_run(path, tolerant=True, topics=topics)
    problem = runs_problem(run.periods)
    if problem is not None:
        raise RunLogError(f"{run.path}: {problem}")
    return run


def target_mass_kg(run: RunFile) -> float:
    """The campaign's target dug mass m* (kg)."""
    return float(run.metadata["excosim.run"]["target_mass_kg"])


def run_figures(records: list[dict[str, Any]], band_kg: float = WITHIN_KG) -> dict[str, Any]:
    """Per-run figures from the period records, errors counted after period 1 (period 1 digs at
    the default D before any weighing, as in the paper's Figure 9):

    band_kg: half-width of the on-target band (`band_kg(m*)`; 3 kg for the paper's 30 kg).
    periods, resets (periods whose D came from a reset), mean_abs_error_kg and
    max_abs_error_kg (None without a period after the first), within_band (periods 2.. with
    |error| <= band_kg), counted (periods 2..), band_kg, mean_duration_s, max_duration_s,
    peak_jerk_deg_s3 (largest |jerk| of any joint in any period); and the run's productivity
    totals (orchestrator.review.productivity.RUN_KEYS: total_payload_kg, digging_time_s,
    productivity_t_h, mean_fill_factor, energy_kj, throttled_energy_kj,
    energy_per_tonne_kj_t, throttled_share, peak_power_kw, mean_power_kw; None where the
    records lack what they need).
    """
    after = [abs(r["error_kg"]) for r in records if r["k"] >= 2]
    durations = [r["duration_s"] for r in records]
    jerks = [max(r["max_abs_jerk_deg_s3"]) for r in records]
    return {
        "periods": len(records),
        "resets": sum(bool(r.get("reset")) for r in records),
        "mean_abs_error_kg": math.fsum(after) / len(after) if after else None,
        "max_abs_error_kg": max(after) if after else None,
        "within_band": sum(e <= band_kg for e in after),
        "counted": len(after),
        "band_kg": band_kg,
        "mean_duration_s": math.fsum(durations) / len(durations) if durations else None,
        "max_duration_s": max(durations) if durations else None,
        "peak_jerk_deg_s3": max(jerks) if jerks else None,
        **run_productivity(records),
    }


def summary(run: RunFile) -> dict[str, Any]:
    """The review of a run as plain, JSON-able data (the `excosim review --json` object).

    Keys: path, scenario (name), description, plant ("sim" or "lab"), target_mass_kg (kg),
    termination ("periods", "workspace_limit", "error"; None when the run did not finish),
    message (the end record's line), finished, truncated (the file ends early: a killed run),
    damage (where the file is damaged, "damaged at byte N (chunk CRC)"; None if it is not: the
    periods are those before the damage),
    periods (the /period records as the campaign wrote them), figures (`run_figures`),
    versions (package versions the run used), fmus (component -> file sha256), roles (component
    -> {"fmu", "file", "sha256", "content_sha256", "parameters", "ports"}: which model filled
    each role; content_sha256, the FMU's identity, is absent in older logs), overrides
    (the `--set` items applied to the scenario file), resumed_after_period (the period after
    which `excosim run --resume` last took the run over; None if it never did),
    power_limit_kw (the pump's hydraulic power limit, kW: the scenario's [plant.supply]
    engine_power_w x pump_efficiency; None when it sets none), numerics (the scenario's
    plant.communication_step_s, servo_sample_s, coupling_tolerance_rad_s2 and
    coupling_max_iterations where it sets them: what a comparison must not mix up silently).
    """
    description = run.metadata["excosim.run"]
    try:
        scenario = run.scenario
    except (KeyError, ValueError):
        scenario = {}
    text = scenario.get("description", "")
    return {
        "path": str(run.path),
        "scenario": description.get("scenario_name", ""),
        "description": text,
        "plant": description.get("plant_kind", ""),
        "target_mass_kg": target_mass_kg(run),
        "termination": run.termination,
        "message": run.termination_message,
        "finished": run.finished,
        "truncated": run.truncated,
        "damage": run.damage,
        "periods": run.periods,
        "figures": run_figures(run.periods, band_kg(target_mass_kg(run))),
        "versions": dict(run.metadata.get("excosim.versions", {})),
        "fmus": dict(run.metadata.get("excosim.fmus", {})),
        "roles": roles(run),
        "overrides": _json_list(description.get("overrides", "[]")),
        "resumed_after_period": _resumed(run),
        "power_limit_kw": power_limit_kw(scenario),
        "numerics": numerics(scenario),
    }


NUMERICS = ("communication_step_s", "servo_sample_s", "coupling_tolerance_rad_s2",
            "coupling_max_iterations")


def numerics(scenario: dict[str, Any]) -> dict[str, Any]:
    """The scenario's numerical settings of the plant (NUMERICS) that it sets (as numbers:
    an edited record's other values are left out)."""
    plant = scenario.get("plant", {}) if isinstance(scenario, dict) else {}
    plant = plant if isinstance(plant, dict) else {}
    return {key: plant[key] for key in NUMERICS if isinstance(plant.get(key), int | float)
            and not isinstance(plant[key], bool)}


def differing_numerics(reviews: list[dict[str, Any]]) -> dict[str, list[Any]]:
    """setting -> its value per run, for the numerical settings (NUMERICS) that differ."""
    values = {key: [r.get("numerics", {}).get(key) for r in reviews] for key in NUMERICS}
    return {key: v for key, v in values.items() if len({json.dumps(x) for x in v}) > 1}


def _resumed(run: RunFile) -> int | None:
    try:
        return int(run.metadata["excosim.resumed"]["after_period"])
    except (KeyError, ValueError):
        return None


def _json_list(text: str) -> list:
    try:
        value = loads(text, "overrides")
    except ValueError:
        return []
    return value if isinstance(value, list) else []


def roles(run: RunFile) -> dict[str, dict[str, Any]]:
    """component -> {"fmu", "file", "sha256", "parameters", "ports"} from the log's
    `excosim.roles` record, or for logs written before it, from the scenario and FMU hashes."""
    out: dict[str, dict[str, Any]] = {}
    for role, text in run.metadata.get("excosim.roles", {}).items():
        try:
            value = loads(text, f"role {role}")
        except ValueError:
            continue
        if isinstance(value, dict):
            out[role] = value
    if out:
        return out
    try:
        plant = run.scenario.get("plant", {})
    except (KeyError, ValueError):
        plant = {}
    for role, digest in run.metadata.get("excosim.fmus", {}).items():
        table = plant.get(role, {}) if isinstance(plant, dict) else {}
        table = table if isinstance(table, dict) else {}
        out[role] = {"fmu": table.get("fmu", ""), "file": "", "sha256": digest,
                     "parameters": table.get("parameters", {}), "ports": table.get("ports", {})}
    return out


def differing_roles(reviews: list[dict[str, Any]]) -> dict[str, list[str]]:
    """component -> what differs in it between the runs: "FMU (A | B)" (another model: its
    content hash differs, or for logs without one its file sha256), "FMU name (same content)",
    "ports", and the parameters that every run sets but to different values; only roles that
    differ."""
    out: dict[str, list[str]] = {}
    names = sorted({role for review in reviews for role in review["roles"]})
    for role in names:
        tables = [review["roles"].get(role, {}) for review in reviews]
        what = []
        names = [Path(str(t.get("fmu", ""))).name for t in tables]
        key = "content_sha256" if all(t.get("content_sha256") for t in tables) else "sha256"
        if len({t.get(key) for t in tables}) > 1:
            what.append(f"FMU ({' | '.join(dict.fromkeys(names))})")
        elif len(set(names)) > 1:
            what.append("FMU name (same content)")
        versions = [t.get("fmi_version") for t in tables]
        if all(versions) and len(set(versions)) > 1:
            what.append(f"FMI version ({' | '.join(versions)})")
        if len({json.dumps(t.get("ports", {}), sort_keys=True) for t in tables}) > 1:
            what.append("ports")
        # Parameters set to different values (or left to the FMU's default in some runs); where
        # the FMU itself differs, only those every run sets: another model's own are not news.
        sets = [set(t.get("parameters", {})) for t in tables]
        keys = set.intersection(*sets) if what and what[0].startswith("FMU (") \
            else set.union(*sets)
        what += [k for k in sorted(keys) if len({json.dumps(t.get("parameters", {}).get(k))
                                                 for t in tables}) > 1]
        if what:
            out[role] = what
    return out


def _count(n: int, noun: str) -> str:
    return f"{n} {noun if n == 1 else noun + 's'}"


# The end message of a campaign stopped by Ctrl-C (orchestrator.campaign.loop.INTERRUPTED; not
# imported: reviewing a file must not load the planner and plant).
_INTERRUPTED = "interrupted"


def ending(review: dict[str, Any]) -> str:
    """One line on how the campaign ended, for a person (e.g. "dug all 20 planned periods")."""
    n = len(review["periods"])
    damage = review.get("damage")
    if damage is not None and not review["finished"]:
        return f"the file is {damage}; it holds {_count(n, 'complete period')} before the damage"
    line = _ended(review, n)
    return line if damage is None else f"{line}; but the file is {damage}"


def _ended(review: dict[str, Any], n: int) -> str:
    if not review["finished"]:
        cut = " (the file ends early)" if review["truncated"] else ""
        return f"did not finish: the log holds {_count(n, 'complete period')}{cut}; a killed run?"
    termination, message = review["termination"], review["message"]
    if termination == "periods":
        return f"dug all {n} planned periods" if n != 1 else "dug the 1 planned period"
    if termination == "workspace_limit":
        # The log's message ("workspace limit after k period(s)") says no more than this.
        return (f"stopped at the workspace limit after {_count(n, 'period')} (the next D was "
                "out of reach after a reset)")
    if termination == "error" and message == _INTERRUPTED:
        return f"interrupted after {_count(n, 'period')}"
    line = f"failed after {_count(n, 'period')}" if termination == "error" else (
        f"ended ({termination}) after {_count(n, 'period')}")
    return f"{line}: {message}" if message else line
