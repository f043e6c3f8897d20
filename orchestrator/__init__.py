"""excosim orchestrator: the campaign and everything around it, one subpackage per part.

- `campaign`: the period loop (adapt D, plan, dig, weigh, log) and its records: `run_campaign`.
- `scenario`: TOML -> typed, validated scenario; `--set` overrides; FMU resolution.
- `plants`: the co-simulation master and the simulated excavator (FMUs + arm coupling + servo).
- `runlog`: the MCAP run log: writer, reader, schemas, Foxglove scene.
- `review`: review, compare and replay of run logs, and their figures.
- `cli`: the `excosim` command.
"""
