"""excosim orchestrator: co-simulation master, simulated excavator, campaign, MCAP log, CLI."""
