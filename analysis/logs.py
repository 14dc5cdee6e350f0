"""Reading fuzzynav MCAP logs (the analysis reads logs only, never the simulator's memory)."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import orjson
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

T = TypeVar("T")

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


class LogFile:
    """One log opened once: metadata, schemas and messages from the same reader (the MCAP summary of a
    complete log is parsed once). A truncated log (no summary) is read linearly instead. Use as a context
    manager; every reading error becomes a :class:`LogError` naming the file."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.complete = is_complete(self.path)
        self._file = open(self.path, "rb") if self.complete else None  # noqa: SIM115 - closed in close()
        try:
            self._reader = make_reader(self._file) if self._file is not None else None
        except Exception as err:  # ends like an MCAP but does not start like one
            self.close()
            raise LogError(f"{self.path}: not an MCAP file ({type(err).__name__}: {err})") from None

    def __enter__(self) -> LogFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()

    def _fail(self, err: Exception, what: str) -> LogError:
        return err if isinstance(err, LogError) else LogError(f"{self.path}: {what} ({type(err).__name__}: {err})")

    def metadata(self) -> dict[str, str]:
        """The ``fuzzynav.run`` metadata record."""
        try:
            records = self._reader.iter_metadata() if self._reader is not None else \
                (r for r in _linear_records(self.path) if isinstance(r, Metadata))
            for record in records:
                if record.name == RUN_METADATA:
                    return dict(record.metadata)
        except Exception as err:  # the mcap reader raises many types on corrupt input
            raise self._fail(err, "not a readable MCAP file") from None
        raise LogError(f"{self.path}: no '{RUN_METADATA}' metadata (not a fuzzynav log)")

    def required_fields(self) -> dict[str, list[str]]:
        """Per topic, the top-level fields its embedded JSON schema requires (topics without one: none)."""
        schemas: dict[int, Any] = {}
        channels: dict[int, tuple[str, int]] = {}
        try:
            if self._reader is not None:
                summary = self._reader.get_summary()
                if summary is not None:
                    schemas = dict(summary.schemas)
                    channels = {cid: (c.topic, c.schema_id) for cid, c in summary.channels.items()}
            else:
                for record in _linear_records(self.path):
                    if isinstance(record, Schema):
                        schemas[record.id] = record
                    elif isinstance(record, Channel):
                        channels[record.id] = (record.topic, record.schema_id)
        except Exception as err:
            raise self._fail(err, "not a readable MCAP file") from None
        out: dict[str, list[str]] = {}
        for topic, schema_id in channels.values():
            schema = schemas.get(schema_id)
            if schema is None or schema.encoding != "jsonschema":
                continue
            try:
                out[topic] = list(json.loads(schema.data).get("required", []))
            except (ValueError, AttributeError):
                raise LogError(f"{self.path}: the schema of {topic} is not valid JSON") from None
        return out

    def raw_messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time ns, raw JSON bytes) in file order, which for fuzzynav logs is log-time order
        (the writer appends step after step); a truncated log yields what it has."""
        wanted = set(topics) if topics else None
        try:
            if self._reader is not None:
                for _schema, channel, message in self._reader.iter_messages(
                        topics=list(wanted) if wanted else None, log_time_order=False):
                    yield channel.topic, message.log_time, message.data
                return
            channels: dict[int, str] = {}
            for record in _linear_records(self.path):
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Message):
                    topic = channels.get(record.channel_id, "")
                    if wanted is None or topic in wanted:
                        yield topic, record.log_time, record.data
        except Exception as err:
            raise self._fail(err, "cannot read messages") from None

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
        """(topic, log time ns, decoded JSON message), as :meth:`raw_messages`."""
        for topic, log_time, data in self.raw_messages(topics):
            yield topic, log_time, decode(self.path, topic, data)


def read_metadata(path: Path) -> dict[str, str]:
    """The ``fuzzynav.run`` metadata record of a log (complete or truncated)."""
    with LogFile(path) as log:
        return log.metadata()


def iter_messages(path: Path, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """(topic, log time ns, decoded JSON message) in log-time order; a truncated log yields what it has."""
    with LogFile(path) as log:
        yield from log.messages(topics)


def decode(path: Path, topic: str, data: bytes) -> Any:
    """One JSON message; :class:`LogError` naming the file and topic if it is not JSON."""
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError as err:
        raise LogError(f"{path}: a {topic} message is not valid JSON ({err})") from None


PARALLEL_MIN_LOGS = 200  # fewer logs are read in this process: starting worker processes costs about a second


def read_logs(read: Callable[[list[Path]], T], logs: list[Path], jobs: int = 1) -> list[T]:
    """``read`` applied to consecutive chunks of ``logs``, results in order: in this process, or with ``jobs``
    > 1 (-1: every core) in that many worker processes (joblib's loky backend, whose pool a sweep has already
    started) when there are at least ``PARALLEL_MIN_LOGS`` logs. ``read`` must be a module-level function."""
    if jobs == 1 or len(logs) < PARALLEL_MIN_LOGS:
        return [read(logs)]
    from joblib import Parallel, cpu_count, delayed

    workers = cpu_count() if jobs < 0 else jobs
    size = max(1, -(-len(logs) // (4 * workers)))  # a few chunks per worker balance the load
    # max_nbytes=None as Hydra's joblib launcher sets it: with equal settings loky reuses the sweep's worker
    # pool instead of starting a new one (only paths travel to the workers: nothing to memory-map)
    return Parallel(n_jobs=workers, max_nbytes=None)(delayed(read)(logs[i:i + size])
                                                     for i in range(0, len(logs), size))


def episode_summary(path: Path) -> dict[str, Any]:
    """One row: run parameters from the metadata and the ``/episode`` outcome (``incomplete`` if missing)."""
    with LogFile(path) as log:
        meta = log.metadata()
        row: dict[str, Any] = {"log": str(path), "scenario": meta.get("scenario"), "strategy": meta.get("strategy"),
                               "h_wait": _int(meta.get("h_wait")), "controller": meta.get("controller"),
                               "perception": meta.get("perception"), "seed": _int(meta.get("seed")),
                               "outcome": "incomplete", "steps": None, "time_s": None, "contacts": None}
        for _topic, _t, msg in log.messages(["/episode"]):
            row.update(outcome=msg["outcome"], steps=msg["steps"], time_s=msg["time_s"], contacts=msg["contacts"])
    return row


def _int(value: str | None) -> int | None:
    try:
        return None if value is None else int(value)
    except ValueError:
        return None
