"""The one exception a scenario mistake raises, kept apart so every scenario module can raise it."""

from __future__ import annotations


class ScenarioError(ValueError):
    """A mistake in a scenario; str() is one line: `<source>: <field>: <reason>`."""

    def __init__(self, source: str, field: str, reason: str) -> None:
        self.source, self.field, self.reason = source, field, reason
        super().__init__(f"{source}: {field}: {reason}" if field else f"{source}: {reason}")
