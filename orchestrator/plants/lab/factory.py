"""The lab plant and its emulated device from a scenario (plant kind "lab", [plant.lab])."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from orchestrator.plants.lab.bus import open_bus, private_virtual_channel
from orchestrator.plants.lab.driver import LabExcavator
from orchestrator.plants.lab.emulator import LabEmulator
from orchestrator.plants.lab.settings import LabSettings
from orchestrator.plants.lab.sim_arm import SteppedExcavator


def open_lab_plant(scenario) -> LabExcavator:
    """The LabExcavator of `scenario` (an orchestrator.scenario.Scenario with plant kind "lab").
    With plant.lab.emulate, an emulated device is started first on a private channel of the
    `virtual` interface in this process; the plant owns it and closes it last."""
    section = scenario.plant.lab
    if section is None:
        raise ValueError('the scenario has no [plant.lab] table (plant.kind = "lab")')
    settings = section.settings(private_virtual_channel() if section.emulate else None)
    geometry = scenario.geometry()
    emulator = start_emulator(scenario, settings) if settings.emulate else None
    try:
        return LabExcavator(settings, geometry.joint_limits_rad, scenario.limits_rad(),
                            emulator=emulator)
    except BaseException:
        if emulator is not None:
            emulator.close()
        raise


def start_emulator(scenario, settings: LabSettings, bus=None) -> LabEmulator:
    """A running LabEmulator of `scenario`'s simulated machine (its FMUs, pile and load cell)
    with the arm at rest at the first period's start pose, on `bus` (default: opened from
    settings). The fault plan is settings.faults."""
    arm = SteppedExcavator(simulated_config(scenario), settings.frame_period_s)
    try:
        bus = bus if bus is not None else open_bus(settings)
    except BaseException:
        arm.close()
        raise
    velocity_limits = scenario.limits_rad()[0]
    return LabEmulator(arm, settings, scenario.geometry().joint_limits_rad, velocity_limits,
                       bus=bus, seed=scenario.seed).start()


def simulated_config(scenario):
    """The scenario's SimulatedExcavatorConfig (as orchestrator.campaign.loop.build_plant makes
    it for plant kind "sim"), starting at rest at the first period's start pose: a device has
    an arm before its first setpoint, where the simulated plant starts at its first reference."""
    from plant_models.hydraulics import default_config

    config = default_config(scenario.machine.preset)
    config = replace(config, **scenario.fmu_specs(), seed=scenario.seed,
                     communication_step_s=scenario.plant.communication_step_s,
                     servo_sample_s=scenario.plant.servo_sample_s,
                     coupling_tolerance_rad_s2=scenario.plant.coupling_tolerance_rad_s2,
                     coupling_max_iterations=scenario.plant.coupling_max_iterations,
                     load_cell_noise_kg=scenario.plant.load_cell_noise_kg)
    return replace(config, start_pose_rad=tuple(float(q) for q in first_pose_rad(scenario)))


def first_pose_rad(scenario) -> np.ndarray:
    """(3,) rad: the first sample of the campaign's first reference (its D from the
    adaptation's initial state, the path's start pose)."""
    from planner.adaptation import initial_state

    planner = scenario.period_planner()
    decision = initial_state(scenario.adaptation_defaults(), planner.reachable)
    if decision.terminated:
        raise ValueError("the scenario's first period is out of reach")
    state = decision.next_state
    trajectory = planner.plan(state.y_D, state.z_D)
    return np.asarray(trajectory(np.array([0.0])))[0]
