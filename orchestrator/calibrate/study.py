"""The search: an Optuna study (stored in SQLite beside the outputs, so the same command goes on
where it stopped) that first samples with the seeded TPE sampler, then polishes the best point
with Nelder-Mead (scipy), every evaluation a trial of the same study.

Why both: TPE is a global, derivative-free search that copes with failed trials and runs in
parallel batches (the local pool, the Dask cluster), but it closes in on a smooth optimum
slowly; the score here is smooth near its minimum (a least-squares fit), where Nelder-Mead,
started from TPE's best with steps of 5 % of each range, converges in tens of trials. The
first 60 % of --trials go to TPE (the scenario's own values are its first trial), the rest to
Nelder-Mead; a resumed study counts the trials it holds.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from orchestrator.calibrate.executors import Trials
from orchestrator.calibrate.objective import Fit
from orchestrator.calibrate.parameters import Parameter

TPE_SHARE = 0.6
STUDY_FILE = "study.db"


def study_name(signature: dict) -> str:
    """A study per calibration problem (scenario, overrides, log, parameters, weighting): the
    same command continues it, another one starts its own in the same file."""
    digest = hashlib.sha256(json.dumps(signature, sort_keys=True).encode()).hexdigest()
    return f"calibrate-{digest[:16]}"


def open_study(out_dir: Path, name: str, seed: int):
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = f"sqlite:///{(out_dir / STUDY_FILE).resolve()}"
    sampler = optuna.samplers.TPESampler(seed=seed, multivariate=True,
                                         n_startup_trials=8)
    return optuna.create_study(study_name=name, storage=storage, sampler=sampler,
                               direction="minimize", load_if_exists=True)


def complete(study) -> list:
    import optuna

    return [t for t in study.trials if t.state in (optuna.trial.TrialState.COMPLETE,
                                                    optuna.trial.TrialState.FAIL)]


def best(study) -> tuple[dict[str, float], float] | None:
    done = [t for t in complete(study) if t.value is not None and math.isfinite(t.value)]
    if not done:
        return None
    top = min(done, key=lambda t: t.value)
    return dict(top.params), float(top.value)


def search(study, parameters: Sequence[Parameter], trials: Trials, budget: int,
           progress: Callable[[int, float | None], None] | None = None) -> None:
    """Run the study up to `budget` trials (those it holds count). progress(done, best score)
    after each trial."""
    import optuna

    distributions = {p.key: optuna.distributions.FloatDistribution(p.low, p.high)
                     for p in parameters}
    n_tpe = max(1, min(budget, round(TPE_SHARE * budget)))

    def report() -> None:
        if progress is not None:
            found = best(study)
            progress(len(complete(study)), None if found is None else found[1])

    def run(asked: list) -> list[Fit]:
        fits = trials.map([{k: float(v) for k, v in t.params.items()} for t in asked])
        for trial, fit in zip(asked, fits, strict=True):
            _tell(study, trial, fit)
            report()
        return fits

    def given(points: list[dict[str, float]]) -> list[Fit]:
        """Trials at given points, added to the study once run (none is left waiting in it
        by an interruption, to be taken for another point later)."""
        fits = trials.map(points)
        for point, fit in zip(points, fits, strict=True):
            _add(study, distributions, point, fit)
            report()
        return fits

    if not complete(study):  # the scenario's own values first
        given([{p.key: p.start for p in parameters}])
    while len(complete(study)) < n_tpe:
        batch = min(trials.parallel, n_tpe - len(complete(study)))
        run([study.ask(distributions) for _ in range(batch)])
    left = budget - len(complete(study))
    found = best(study)
    if left <= 0 or found is None:
        return
    _polish(parameters, found[0], left, given)


def _tell(study, trial, fit: Fit) -> None:
    import optuna

    for name, value in _attributes(fit).items():
        trial.set_user_attr(name, value)
    if math.isfinite(fit.score):
        study.tell(trial, fit.score)
    else:
        study.tell(trial, state=optuna.trial.TrialState.FAIL)


def _attributes(fit: Fit) -> dict:
    extra = {"error": fit.error} if fit.error else {}
    return {"masses_kg": fit.masses_kg, "tracking_rms_deg": fit.tracking_rms_deg, **extra}


def _add(study, distributions: dict, point: dict[str, float], fit: Fit) -> None:
    import optuna

    state = optuna.trial.TrialState
    study.add_trial(optuna.trial.create_trial(
        params=point, distributions=distributions, user_attrs=_attributes(fit),
        value=fit.score if math.isfinite(fit.score) else None,
        state=state.COMPLETE if math.isfinite(fit.score) else state.FAIL))


def _polish(parameters: Sequence[Parameter], start: dict, maxfev: int,
            run: Callable[[list], list[Fit]]) -> None:
    """Nelder-Mead in the unit cube of the ranges from `start`, each evaluation a study trial."""
    from scipy.optimize import minimize

    x0 = np.array([p.to_unit(start[p.key]) for p in parameters])
    steps = np.diag([0.05 if v <= 0.5 else -0.05 for v in x0])  # toward the farther bound
    seen: dict[tuple[float, ...], float] = {}

    def score(x: np.ndarray) -> float:
        x = np.clip(x, 0.0, 1.0)
        key = tuple(np.round(x, 12))
        if key not in seen:
            values = {p.key: p.from_unit(float(v)) for p, v in zip(parameters, x, strict=True)}
            fit = run([values])[0]
            seen[key] = fit.score if math.isfinite(fit.score) else 1e9
        return seen[key]

    minimize(score, x0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(parameters),
             options={"maxfev": maxfev, "xatol": 1e-4, "fatol": 1e-6,
                      "initial_simplex": np.vstack([x0, x0 + steps])})
