"""The lab excavator of the paper (section 3.3) over CAN, and its emulator.

    protocol.py   the DBC (excavator.dbc) and the frame helpers (cantools, CRC-8, counters)
    settings.py   link settings and the emulator's fault plan (machine time, time scale)
    safety.py     the master's check of a period's setpoints before anything is sent
    driver.py     LabExcavator: the Plant protocol over CAN (master side, watchdog)
    link.py       the master's view of the device from received frames
    measurement.py  a period's PeriodMeasurement with the bus statistics
    device.py     the device's state machine (the firmware side of docs/can-protocol.md)
    sim_arm.py    the simulated excavator stepped cycle by cycle (the emulated device's arm)
    emulator.py   LabEmulator: device + arm on a bus, in a thread
    faults.py     fault injection on the emulator's side
    factory.py    plant and emulator from a scenario

Nothing here is imported by `orchestrator.plants` itself: python-can and cantools load only when
a lab plant is used.
"""
