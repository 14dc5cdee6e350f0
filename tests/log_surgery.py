"""Edit MCAP logs for tests: re-write a log through the ``mcap`` library's writer (fresh, valid CRCs) with its
metadata or messages changed, or damage its bytes. Independent of :mod:`analysis.mcap_verify`, the reader under
test."""

from __future__ import annotations

import json
import struct
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import orjson
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

MessageEdit = Callable[[str, int, Any], Any]  # (topic, index of the message on its topic, message) -> message,
# DROP to leave it out, or Twice(message) to write it twice
DROP = object()


class Twice:
    """A message edit's answer: write this message twice (same log time)."""

    def __init__(self, msg: Any) -> None:
        self.msg = msg


def rewrite(src: Path, dst: Path, *, metadata: Callable[[dict[str, str]], dict[str, str]] | None = None,
            message: MessageEdit | None = None, compression: CompressionType = CompressionType.ZSTD,
            schemas: Mapping[str, tuple[str, str] | None] | None = None) -> Path:
    """Copy ``src`` to ``dst`` record by record: ``metadata(run_metadata)`` returns the new ``fuzzynav.run``
    record, ``message(topic, index, msg)`` the new message (any JSON value; DROP leaves it out, Twice repeats it),
    ``schemas[topic]`` the (name, encoding) of the schema that topic's channel declares instead of its own (the
    schema's text is kept), None for no schema record (schema id 0)."""
    with open(src, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        records = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        messages = [(channel, m) for _s, channel, m in reader.iter_messages(log_time_order=False)]
    counts: dict[str, int] = {}
    with open(dst, "wb") as out:
        writer = Writer(out, compression=compression)
        writer.start()
        ids = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {}
        for cid, c in summary.channels.items():
            sid = ids.get(c.schema_id, 0)
            if schemas is not None and c.topic in schemas:
                new = schemas[c.topic]
                sid = 0 if new is None else writer.register_schema(new[0], new[1], summary.schemas[c.schema_id].data)
            channels[cid] = writer.register_channel(c.topic, c.message_encoding, sid)
        for name, meta in records:
            writer.add_metadata(name, metadata(dict(meta)) if metadata and name == "fuzzynav.run" else meta)
        for channel, m in messages:
            data = m.data
            if message is not None:
                index = counts.get(channel.topic, 0)
                counts[channel.topic] = index + 1
                edited = message(channel.topic, index, orjson.loads(data))
                if edited is DROP:
                    continue
                if isinstance(edited, Twice):
                    edited = edited.msg
                    writer.add_message(channels[channel.id], m.log_time, _dumps(edited), m.publish_time)
                data = _dumps(edited)
            writer.add_message(channels[channel.id], m.log_time, data, m.publish_time)
        writer.finish()
    return dst


def _dumps(value: Any) -> bytes:
    """JSON as the writer's orjson writes it; integers beyond 64 bits (which orjson refuses) and NaN through the
    standard library (NaN then becomes the non-JSON token ``NaN``, as a broken writer would write it)."""
    try:
        return orjson.dumps(value)
    except TypeError:
        return json.dumps(value, separators=(",", ":")).encode()


def record_offsets(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, offset, body length) of each top-level record of an intact MCAP file."""
    out, pos = [], 8
    while pos + 9 <= len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        out.append((opcode, pos, length))
        pos += 9 + length
    return out


def chunk_payloads(data: bytes) -> list[tuple[int, int, int]]:
    """(chunk record offset, first byte, end) of each top-level chunk's compressed records in an intact MCAP file
    (after the chunk's start and end times, uncompressed size, CRC, compression name and records length)."""
    out = []
    for opcode, offset, length in record_offsets(data):
        if opcode == 0x06:
            name_length = int.from_bytes(data[offset + 9 + 28:offset + 9 + 32], "little")
            out.append((offset, offset + 9 + 32 + name_length + 8, offset + 9 + length))
    return out


def message_paths(node: Any, last_item: bool = False, prefix: tuple = ()) -> list[tuple]:
    """Paths (keys and list indices) to every value in a JSON message; of each list, its first item and, with
    ``last_item``, its last."""
    out = []
    if isinstance(node, dict):
        for k, v in node.items():
            out.append((*prefix, k))
            out.extend(message_paths(v, last_item, (*prefix, k)))
    elif isinstance(node, list) and node:
        for i in sorted({0, len(node) - 1}) if last_item else (0,):
            if last_item:
                out.append((*prefix, i))
            out.extend(message_paths(node[i], last_item, (*prefix, i)))
    return out
