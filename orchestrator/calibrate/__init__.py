"""Calibration: fit scenario parameters so the simulated plant reproduces a logged run.

    from orchestrator.calibrate import calibrate
    result = calibrate("scenarios/paper-2020.toml", "runs/measured.mcap",
                       ["plant.pile.parameters.density=1500:2000"], out_dir="runs/fit")
    result.best_values, result.best_fit.score

The parts: the parameters and their ranges (orchestrator.calibrate.parameters), the measured
run read from its log (measured), the simulated plant driven on the logged references period
by period (drive), the score and its weighting (objective), the search (study: Optuna's TPE
then Nelder-Mead, on a local pool or a Dask cluster), what is written (outputs) and the whole
(run).
"""

from orchestrator.calibrate.errors import CalibrationError
from orchestrator.calibrate.run import CalibrationResult, calibrate

__all__ = ["CalibrationError", "CalibrationResult", "calibrate"]
