"""excosim orchestrator: the command line now; the co-simulation master and campaign next."""
