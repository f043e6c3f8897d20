"""The schemas and channels of a run log, each registered once with the file's writer and
then found by topic: protobuf sample channels (`orchestrator.runlog.schemas`), Foxglove's
own messages (`foxglove.messages`) and JSON records."""

from __future__ import annotations

import json

from orchestrator.runlog.mcap_records import McapChunkWriter
from orchestrator.runlog.schemas import DoubleMessage, file_descriptor_set


class ChannelTable:
    """Channel ids of one log by (topic, metadata); the schemas and channels the writer
    already holds (a continued log's) are taken as they are."""

    def __init__(self, writer: McapChunkWriter) -> None:
        self._writer = writer
        self._schemas = {schema.name: schema.id for schema in writer.schemas}
        self._channels = {(channel.topic, tuple(sorted(channel.metadata.items()))): channel.id
                          for channel in writer.channels}

    def _schema(self, name: str, encoding: str, data: bytes) -> int:
        if name not in self._schemas:
            self._schemas[name] = self._writer.add_schema(name, encoding, data)
        return self._schemas[name]

    def proto(self, topic: str, message: DoubleMessage, metadata: dict) -> int:
        """The channel of one of our protobuf messages on `topic` with `metadata`."""
        key = (topic, tuple(sorted(metadata.items())))
        if key not in self._channels:
            schema = self._schema(message.full_name, "protobuf", file_descriptor_set(message))
            self._channels[key] = self._writer.add_channel(topic, "protobuf", schema, metadata)
        return self._channels[key]

    def foxglove(self, topic: str, message_type) -> int:
        """The channel of a foxglove.messages type (e.g. SceneUpdate) on `topic`."""
        key = (topic, ())
        if key not in self._channels:
            schema = message_type.get_schema()
            schema_id = self._schema(schema.name, schema.encoding, schema.data)
            self._channels[key] = self._writer.add_channel(topic, "protobuf", schema_id)
        return self._channels[key]

    def json(self, topic: str, schema: dict) -> int:
        """The channel of JSON records with the JSON schema `schema` (titled) on `topic`."""
        key = (topic, ())
        if key not in self._channels:
            schema_id = self._schema(schema["title"], "jsonschema", json.dumps(schema).encode())
            self._channels[key] = self._writer.add_channel(topic, "json", schema_id)
        return self._channels[key]
