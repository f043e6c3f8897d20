"""The lab excavator on the command line: `excosim emulate`, and `run --plant lab --emulate`.

`run --plant lab` sets `plant.kind = "lab"`: the campaign drives the excavator over CAN with the
scenario's [plant.lab] link. `--emulate` also starts the emulated device in the same process on
python-can's `virtual` interface (hardware-in-the-loop in one command). Both are --set items, so
the run log's scenario says how the run was made.

`excosim emulate` runs the emulated device alone, as the device side of the protocol on a real
or virtual bus (e.g. socketcan vcan0), until Ctrl-C or --duration. Exit status: 0; 2 for a
user's mistake (scenario, option, fault key); 1 when the bus cannot be opened; 130 for Ctrl-C
before the device started.
"""

from __future__ import annotations

import time
from pathlib import Path

PLANTS = ("sim", "lab")
FAULT_KEYS = ("drop_fraction", "seed", "drop_from_s", "feedback_delay_s", "feedback_delay_from_s",
              "heartbeat_stop_s", "corrupt_from_s", "estop_at_s", "freeze_load_cell_at_s")


def run_overrides(plant: str | None, emulate: bool) -> tuple[list[str] | None, str | None]:
    """The --set items of `run --plant P --emulate`, or (None, one-line mistake)."""
    if plant is not None and plant not in PLANTS:
        return None, f"--plant: unknown plant {plant!r}; use sim or lab"
    if emulate and plant == "sim":
        return None, "--emulate emulates the lab excavator: it does not go with --plant sim"
    items = [f"plant.kind={plant}"] if plant is not None else []
    if emulate:
        items = ["plant.kind=lab", "plant.lab.emulate=true", "plant.lab.interface=virtual"]
    return items, None


def emulate(interface: str, channel: str, bitrate: int, scenario_path: Path | None,
            time_scale: float | None, duration_s: float | None, faults: list[str],
            overrides: list[str], trust: bool = False) -> tuple[str, int] | None:
    """Run the emulated device until Ctrl-C or `duration_s` wall seconds; None on success, else
    (one-line message, exit status; an FMU file that is not ours needs `trust`,
    orchestrator.cli.trust). interface, channel, bitrate: the python-can bus; the
    scenario (default: the `lab` machine preset) gives the simulated machine, the stream rate,
    timeouts and time scale ([plant.lab]); faults: KEY=VALUE items of [plant.lab.faults]."""
    from orchestrator.plants.lab.bus import LabLinkError
    from orchestrator.scenario import ScenarioError

    if duration_s is not None and not duration_s > 0.0:
        return "--duration must be > 0 s", 2
    items = list(overrides)
    for item in faults:
        key = item.partition("=")[0].strip()
        if key not in FAULT_KEYS:
            return f"--fault {item!r}: unknown fault {key!r}; known: {', '.join(FAULT_KEYS)}", 2
        items.append(f"plant.lab.faults.{item}")
    items += [f"plant.lab.interface={interface}", f"plant.lab.channel={channel}",
              f"plant.lab.bitrate={bitrate}", "plant.kind=lab", "plant.lab.emulate=false"]
    if time_scale is not None:
        items.append(f"plant.lab.time_scale={time_scale}")
    try:
        scenario = _scenario(scenario_path, items)
    except ScenarioError as error:
        return str(error), 2
    from orchestrator.cli.trust import trust_problem

    refused = trust_problem(scenario, trust)
    if refused is not None:
        return refused
    settings = scenario.plant.lab.settings()
    from orchestrator.plants.lab.factory import start_emulator

    try:
        emulator = start_emulator(scenario, settings)
    except LabLinkError as error:
        return str(error), 1
    except KeyboardInterrupt:
        return "interrupted before the device started", 130
    where = f"{settings.interface} channel {settings.channel!r}"
    note = " (the virtual interface reaches this process only)" \
        if settings.interface == "virtual" else ""
    print(f"emulating the lab excavator of scenario {scenario.name!r} on {where}{note}: "
          f"{settings.stream_rate_hz:g} Hz stream, time scale {settings.time_scale:g}; "
          "Ctrl-C stops", flush=True)
    try:
        _wait(emulator, duration_s)
    except KeyboardInterrupt:
        pass
    finally:
        emulator.close()
    print(summary(emulator))
    return None


def _scenario(path: Path | None, items: list[str]):
    from orchestrator.scenario import load_scenario
    from orchestrator.scenario.model import scenario_from_dict
    from orchestrator.scenario.overrides import apply_overrides

    if path is not None:
        return load_scenario(path, items)
    data = apply_overrides({"name": "lab-preset", "machine": {"preset": "lab"}}, items,
                           "the lab preset")
    return scenario_from_dict(data, source="the lab preset")


def _wait(emulator, duration_s: float | None) -> None:
    end = None if duration_s is None else time.monotonic() + duration_s
    while end is None or time.monotonic() < end:
        time.sleep(0.1 if end is None else max(0.0, min(0.1, end - time.monotonic())))


def summary(emulator) -> str:
    """One line: frames sent and received, setpoints lost, the device's last state and fault."""
    device = emulator.device
    line = (f"device {device.state.name} (fault {device.fault.name}); frames sent "
            f"{emulator.frames_sent}, received {emulator.frames_received}; periods "
            f"{device.period}")
    if emulator.error is not None:
        line += f"; arm failure: {type(emulator.error).__name__}: {emulator.error}"
    return line
