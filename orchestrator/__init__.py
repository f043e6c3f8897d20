"""excosim orchestrator: the command line today; the co-simulation master, campaign and logs next."""
