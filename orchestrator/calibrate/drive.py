"""The simulated plant driven with what the measured run was driven with: each logged period's
spline, sampled on the plant's communication grid, in the logged order, on one plant (the pile
keeps what each period dug). No adaptation decides anything: the references are the log's.
The simulated joint angles are read at the log's sample times (linear interpolation)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from orchestrator.calibrate.measured import MeasuredRun


@dataclass(frozen=True)
class SimulatedPeriod:
    """What the simulated plant did in one logged period: its weighed mass (kg) and its joint
    angles at the log's sample times ((m, 3) rad)."""

    k: int
    mass_kg: float
    joints_rad: np.ndarray


def drive(scenario, measured: MeasuredRun) -> list[SimulatedPeriod]:
    """Run the scenario's simulated plant on the measured run's references, period by period."""
    from orchestrator.campaign.loop import build_plant
    from plant_models.plant import communication_step_s

    out = []
    with threadpool_limits(limits=1, user_api="blas"):
        plant = build_plant(scenario)
        try:
            step_s = communication_step_s(plant, scenario.plant.communication_step_s)
            for period in measured.periods:
                got = plant.run_period(period.reference(step_s))
                t_s, joints = np.asarray(got.t_s), np.asarray(got.joints_rad)
                at_log = np.stack([np.interp(period.t_s, t_s, joints[:, j])
                                   for j in range(joints.shape[1])], axis=1)
                out.append(SimulatedPeriod(period.k, float(got.weighed_mass_kg), at_log))
        finally:
            plant.close()
    return out
