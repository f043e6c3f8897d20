"""The MCAP run log: written as the run goes (`RunLog`), read back tolerantly (`read_run`).

    from orchestrator.runlog import read_run
    run = read_run("run.mcap", topics=("/joints",))
    run.periods, run.channels["/joints"].of_period(2)["measured_stick_rad"]
"""

from orchestrator.runlog.description import LogSettings, RunDescription
from orchestrator.runlog.reader import RunFile, RunLogError, read_run
from orchestrator.runlog.writer import RunLog

__all__ = ["LogSettings", "RunDescription", "RunFile", "RunLog", "RunLogError", "read_run"]
