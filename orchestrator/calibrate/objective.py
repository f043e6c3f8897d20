"""The calibration's score: how far the simulated plant, driven on the logged references, is
from the measured run (lower is better).

Per period k of N: the mass residual r_k = simulated - weighed mass (kg), and the tracking
residual e_k = RMS over the period's log samples and the three joints of simulated minus
measured joint angle (deg). Each is divided by a scale that says how large a residual is still
"as good as the data":

- mass scale s_m (kg): default 2 % of the log's target mass (0.6 kg for the paper's 30 kg, about
  a load cell's scatter and the model's own step-size error of 0.4 kg);
- joint scale s_j (deg): default 0.05 deg, five steps of the lab machine's angle feedback
  (0.01 deg, FbPosition in docs/can-protocol.md), well below the arm's own tracking error. A
  stated scale rather than the log's own tracking RMS (measured vs reference, 0.3 deg on the
  paper's run): that one says how far the arm strays from its reference, not how precisely its
  angles are known, and with it the joint term was so weak that 0.5 kg of weighing noise moved
  the fitted repose angle by up to 1.3 deg (5 noise seeds); with 0.05 deg, by at most 0.04 deg.

    score = sqrt(w * mean_k (r_k / s_m)^2 + (1 - w) * mean_k (e_k / s_j)^2),  w = 0.5

an RMS of dimensionless residuals (1: off by one scale on average). Equal weights, because the
two terms inform different parameters (the masses the soil's: density, repose; the tracking
the arm's: valve flow, friction, and the soil's force on the arm) and neither should drown the
other once each is in units of its own scatter. A run that fails scores inf.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.calibrate.drive import SimulatedPeriod, drive
from orchestrator.calibrate.measured import MeasuredRun

MASS_SCALE_FRACTION = 0.02  # of the target mass
JOINT_SCALE_DEG = 0.05


@dataclass(frozen=True)
class Weighting:
    """mass_weight w (0..1), mass_scale_kg s_m, joint_scale_deg s_j (module docstring)."""

    mass_weight: float
    mass_scale_kg: float
    joint_scale_deg: float

    @classmethod
    def default(cls, measured: MeasuredRun, mass_weight: float = 0.5,
                mass_scale_kg: float | None = None,
                joint_scale_deg: float | None = None) -> Weighting:
        target = measured.target_mass_kg if math.isfinite(measured.target_mass_kg) else \
            float(np.mean([p.mass_kg for p in measured.periods]))
        return cls(mass_weight,
                   mass_scale_kg if mass_scale_kg is not None else MASS_SCALE_FRACTION * target,
                   joint_scale_deg if joint_scale_deg is not None else JOINT_SCALE_DEG)


@dataclass
class Fit:
    """A trial's result: score, per period the simulated mass (kg) and tracking RMS against the
    measured angles (deg); error: why the run failed (score inf)."""

    score: float
    masses_kg: list[float] = field(default_factory=list)
    tracking_rms_deg: list[float] = field(default_factory=list)
    error: str = ""
    periods: list[SimulatedPeriod] = field(default_factory=list, repr=False)


def fit_of(measured: MeasuredRun, simulated: list[SimulatedPeriod], weighting: Weighting) -> Fit:
    masses = [s.mass_kg for s in simulated]
    rms = [math.degrees(float(np.sqrt(np.mean((s.joints_rad - p.measured_rad) ** 2))))
           for s, p in zip(simulated, measured.periods, strict=True)]
    mass_term = np.mean([((m - p.mass_kg) / weighting.mass_scale_kg) ** 2
                         for m, p in zip(masses, measured.periods, strict=True)])
    joint_term = np.mean([(e / weighting.joint_scale_deg) ** 2 for e in rms])
    w = weighting.mass_weight
    score = math.sqrt(w * mass_term + (1.0 - w) * joint_term)
    return Fit(score if math.isfinite(score) else math.inf, masses, rms, periods=simulated)


@dataclass(frozen=True)
class Problem:
    """Everything a trial needs, as plain data a worker process can take: the resolved scenario
    (Scenario.to_dict(), the simulated plant, noise as the calibration sets it), where relative
    FMU paths resolve, the fitted keys, the measured run and the weighting."""

    scenario: dict[str, Any]
    source: str
    base_dir: str
    keys: tuple[str, ...]
    measured: MeasuredRun
    weighting: Weighting

    def scenario_at(self, values: dict[str, float]):
        from orchestrator.scenario import scenario_from_dict
        from orchestrator.scenario.overrides import apply_overrides

        items = [f"{key}={float(values[key])!r}" for key in self.keys]
        data = apply_overrides(self.scenario, items, self.source)
        # The FMUs were found and probed when the calibration was checked (both ends of every
        # range); a trial skips the probe (a third of its time): an FMU that does not
        # initialise with a value inside the range fails that trial.
        return scenario_from_dict(data, source=self.source, base_dir=Path(self.base_dir),
                                  check_fmus=False)

    def evaluate(self, values: dict[str, float], keep_periods: bool = False) -> Fit:
        """The Fit of the parameter values {key: value}; never raises for a failing run."""
        try:
            fit = fit_of(self.measured, drive(self.scenario_at(values), self.measured),
                         self.weighting)
        except Exception as failure:  # noqa: BLE001 - a failing trial scores inf
            return Fit(math.inf, error=f"{type(failure).__name__}: {failure}".splitlines()[0])
        if not keep_periods:
            fit.periods = []
        return fit
