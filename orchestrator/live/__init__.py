"""Watching a run as it goes: its log's messages served over the Foxglove WebSocket protocol
(`LiveView`), paced at a real-time factor."""

from orchestrator.live.view import LiveError, LiveView

__all__ = ["LiveError", "LiveView"]
