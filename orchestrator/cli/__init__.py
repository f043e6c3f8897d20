"""The `excosim` command line (`orchestrator.cli.app:main`); one module per command group."""
