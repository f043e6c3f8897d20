"""The `excosim` command line (`orchestrator.cli.app:main`); one module per command group."""

from orchestrator.cli import signals as _signals  # light: no third-party import

if _signals.is_program():  # a stop while the command line's modules load says one line
    _signals.at_start()
