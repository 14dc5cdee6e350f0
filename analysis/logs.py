"""Reading fuzzynav MCAP logs (the analysis reads logs only, never the simulator's memory)."""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import orjson
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

RUN_METADATA = "fuzzynav.run"
MCAP_MAGIC = b"\x89MCAP0\r\n"


class LogError(Exception):
    """A log cannot be read as a fuzzynav episode; the message names the file and what is wrong."""


def is_complete(path: Path) -> bool:
    """A finished MCAP ends with the magic bytes (a killed run's file does not)."""
    try:
        with open(path, "rb") as f:
            f.seek(-len(MCAP_MAGIC), 2)
            return f.read() == MCAP_MAGIC
    except OSError:
        return False


def find_logs(paths: Iterable[str | Path]) -> list[Path]:
    """All ``.mcap`` files under the given files or directories, sorted."""
    out: list[Path] = []
    for p in map(Path, paths):
        out.extend(sorted(p.rglob("*.mcap")) if p.is_dir() else [p])
    return out


def _linear_records(path: Path) -> Iterator[Any]:
    """Records of a possibly truncated MCAP, in file order, up to the last readable chunk (a killed run's
    log has no summary, so it cannot be read through the index)."""
    with open(path, "rb") as f:
        reader = StreamReader(f)
        records = iter(reader.records)
        try:
            first = next(records)
        except Exception as err:  # empty file, wrong magic, garbage
            raise LogError(f"{path}: not an MCAP file ({type(err).__name__}: {err})") from None
        yield first
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except Exception:  # the truncated tail: stop at what was fully written
                return
            yield record


def required_fields(path: Path) -> dict[str, list[str]]:
    """Per topic, the top-level fields its embedded JSON schema requires (topics without a schema: none)."""
    schemas: dict[int, Any] = {}
    channels: dict[int, tuple[str, int]] = {}
    try:
        if is_complete(path):
            with open(path, "rb") as f:
                summary = make_reader(f).get_summary()
            if summary is not None:
                schemas = dict(summary.schemas)
                channels = {cid: (c.topic, c.schema_id) for cid, c in summary.channels.items()}
        else:
            for record in _linear_records(path):
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, record.schema_id)
    except LogError:
        raise
    except Exception as err:
        raise LogError(f"{path}: not a readable MCAP file ({type(err).__name__}: {err})") from None
    out: dict[str, list[str]] = {}
    for topic, schema_id in channels.values():
        schema = schemas.get(schema_id)
        if schema is None or schema.encoding != "jsonschema":
            continue
        try:
            out[topic] = list(json.loads(schema.data).get("required", []))
        except (ValueError, AttributeError):
            raise LogError(f"{path}: the schema of {topic} is not valid JSON") from None
    return out


def read_metadata(path: Path) -> dict[str, str]:
    """The ``fuzzynav.run`` metadata record of a log (complete or truncated)."""
    try:
        if is_complete(path):
            with open(path, "rb") as f:
                for record in make_reader(f).iter_metadata():
                    if record.name == RUN_METADATA:
                        return dict(record.metadata)
        else:
            for record in _linear_records(path):
                if isinstance(record, Metadata) and record.name == RUN_METADATA:
                    return dict(record.metadata)
    except LogError:
        raise
    except Exception as err:  # the mcap reader raises many types on corrupt input
        raise LogError(f"{path}: not a readable MCAP file ({type(err).__name__}: {err})") from None
    raise LogError(f"{path}: no '{RUN_METADATA}' metadata (not a fuzzynav log)")


def iter_raw_messages(path: Path, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time ns, raw JSON bytes) in file order, which for fuzzynav logs is log-time order (the
    writer appends step after step); a truncated log yields what it has."""
    wanted = set(topics) if topics else None
    try:
        if is_complete(path):
            with open(path, "rb") as f:
                reader = make_reader(f)
                for _schema, channel, message in reader.iter_messages(topics=list(wanted) if wanted else None,
                                                                      log_time_order=False):
                    yield channel.topic, message.log_time, message.data
            return
        channels: dict[int, str] = {}
        for record in _linear_records(path):
            if isinstance(record, Channel):
                channels[record.id] = record.topic
            elif isinstance(record, Message):
                topic = channels.get(record.channel_id, "")
                if wanted is None or topic in wanted:
                    yield topic, record.log_time, record.data
    except LogError:
        raise
    except Exception as err:
        raise LogError(f"{path}: cannot read messages ({type(err).__name__}: {err})") from None


def iter_messages(path: Path, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """(topic, log time ns, decoded JSON message) in log-time order; a truncated log yields what it has."""
    for topic, log_time, data in iter_raw_messages(path, topics):
        yield topic, log_time, decode(path, topic, data)


def decode(path: Path, topic: str, data: bytes) -> Any:
    """One JSON message; :class:`LogError` naming the file and topic if it is not JSON."""
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError as err:
        raise LogError(f"{path}: a {topic} message is not valid JSON ({err})") from None


def episode_summary(path: Path) -> dict[str, Any]:
    """One row: run parameters from the metadata and the ``/episode`` outcome (``incomplete`` if missing)."""
    meta = read_metadata(path)
    row: dict[str, Any] = {"log": str(path), "scenario": meta.get("scenario"), "strategy": meta.get("strategy"),
                           "h_wait": _int(meta.get("h_wait")), "controller": meta.get("controller"),
                           "perception": meta.get("perception"), "seed": _int(meta.get("seed")),
                           "outcome": "incomplete", "steps": None, "time_s": None, "contacts": None}
    for _topic, _t, msg in iter_messages(path, ["/episode"]):
        row.update(outcome=msg["outcome"], steps=msg["steps"], time_s=msg["time_s"], contacts=msg["contacts"])
    return row


def _int(value: str | None) -> int | None:
    try:
        return None if value is None else int(value)
    except ValueError:
        return None
