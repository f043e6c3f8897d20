"""A whole calibration: check the input, read the measured run, search, write the outputs.

The simulated plant of every trial is the scenario's (with its --set items) with plant.kind
"sim" (a lab scenario's simulated machine) and, unless it is fitted, no load-cell noise: the
noise is in the measured weighings, and a noisy model would only add scatter to the score.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.calibrate.errors import CalibrationError
from orchestrator.calibrate.executors import Trials
from orchestrator.calibrate.measured import MeasuredRun, read_measured
from orchestrator.calibrate.objective import Fit, Problem, Weighting
from orchestrator.calibrate.parameters import Parameter, check_parameters
from orchestrator.calibrate.study import STUDY_FILE, best, complete, open_study, search, study_name

NOISE_KEY = "plant.load_cell_noise_kg"


@dataclass
class CalibrationResult:
    """parameters (with their start values), best_values {key: value}, the start's and the
    calibrated plant's Fit (with their simulated periods), the weighting, trials in the study
    (run now: ran), the mean wall time of a trial (s), and the files written."""

    parameters: list[Parameter]
    best_values: dict[str, float]
    start_fit: Fit
    best_fit: Fit
    weighting: Weighting
    measured: MeasuredRun
    trials: int
    ran: int
    trial_wall_s: float
    files: dict[str, Path] = field(default_factory=dict)


def prepare(scenario_path: Path, against: Path, params: Sequence[str],
            overrides: Sequence[str] = (), weighting: dict | None = None
            ) -> tuple[list[Parameter], Problem]:
    """Every check of the input (CalibrationError, one line) and the trials' Problem."""
    from orchestrator.scenario import ScenarioError, load_scenario

    scenario_path = Path(scenario_path)
    parameters = check_parameters(scenario_path, overrides, params)
    forced = ["plant.kind=\"sim\""]
    if NOISE_KEY not in {p.key for p in parameters}:
        forced.append(f"{NOISE_KEY}=0.0")
    try:
        scenario = load_scenario(scenario_path, [*overrides, *forced])
    except ScenarioError as error:
        raise CalibrationError(str(error)) from None
    measured = read_measured(Path(against), scenario.machine.preset)
    problem = Problem(scenario.to_dict(), scenario_path.name,
                      str(scenario_path.resolve().parent), tuple(p.key for p in parameters),
                      measured, Weighting.default(measured, **(weighting or {})))
    return parameters, problem


def calibrate(scenario_path: str | Path, against: str | Path, params: Sequence[str],
              out_dir: str | Path, *, overrides: Sequence[str] = (), trials: int = 60,
              workers: int = 1, scheduler: str | None = None, seed: int = 0,
              weighting: dict | None = None,
              progress: Callable[[int, float | None], None] | None = None,
              on_start: Callable[[int, int], None] | None = None) -> CalibrationResult:
    """Fit `params` ("KEY=LOW:HIGH") so the scenario's simulated plant reproduces the run
    logged at `against`; the study and the outputs go to out_dir (orchestrator.calibrate.
    outputs). weighting: Weighting.default's keywords. progress(done, best score) after each
    trial; on_start(trials held, budget) once the study is open."""
    from orchestrator.calibrate import outputs

    scenario_path, out_dir = Path(scenario_path), Path(out_dir)
    parameters, problem = prepare(scenario_path, against, params, overrides, weighting)
    signature = {"scenario": str(scenario_path.resolve()), "text": scenario_path.read_text(),
                 "overrides": list(overrides), "log": str(Path(against).resolve()),
                 "params": list(params), "weighting": vars(problem.weighting), "seed": seed}
    with Trials(problem, workers, scheduler) as executor:  # a scheduler is reached first
        out_dir.mkdir(parents=True, exist_ok=True)
        study = open_study(out_dir, study_name(signature), seed)
        held = len(complete(study))
        if on_start is not None:
            on_start(held, trials)
        began = time.perf_counter()
        search(study, parameters, executor, trials, progress)
    ran = len(complete(study)) - held
    wall = (time.perf_counter() - began) / ran if ran else float("nan")
    found = best(study)
    if found is None:
        raise RuntimeError("every trial failed: "
                           + str(complete(study)[-1].user_attrs.get("error", "?")))
    values = {p.key: float(found[0][p.key]) for p in parameters}
    start_fit = problem.evaluate({p.key: p.start for p in parameters}, keep_periods=True)
    best_fit = problem.evaluate(values, keep_periods=True)
    header = (f"Calibrated against {Path(against).name} by excosim calibrate: score "
              f"{best_fit.score:.4g} (start {start_fit.score:.4g}), {len(complete(study))} "
              f"trials\n(study {study.study_name} in {STUDY_FILE})")
    name = problem.scenario.get("name", scenario_path.stem)
    files = {
        "toml": outputs.write_toml(out_dir, scenario_path, name, overrides, values, header),
        "csv": outputs.write_csv(out_dir, outputs.fit_rows(problem.measured, start_fit,
                                                           best_fit)),
        "figure": outputs.write_figure(out_dir, problem.measured, start_fit, best_fit),
        "study": out_dir / STUDY_FILE}
    return CalibrationResult(parameters, values, start_fit, best_fit, problem.weighting,
                             problem.measured, len(complete(study)), ran, wall, files)
