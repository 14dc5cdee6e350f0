"""Reading fuzzynav MCAP logs (the analysis reads logs only, never the simulator's memory).

A log is verified before anything in it is believed (:mod:`analysis.mcap_verify`: framing, chunk, data-section
and summary CRCs; a truncated log is read up to the chunk that was being written). Only regular files are
opened: a FIFO, device or directory named ``*.mcap`` is refused without being opened (opening a FIFO blocks
until someone writes to it). Every problem is a :class:`LogError` whose message names the file.
"""

from __future__ import annotations

import contextlib
import gc
import os
import stat
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import orjson

from analysis.log_check import TOPIC_SCHEMAS, CheckError, check_message
from analysis.mcap_verify import MAX_FILE_BYTES, McapContent, McapError, read_mcap

T = TypeVar("T")

RUN_METADATA = "fuzzynav.run"
MCAP_MAGIC = b"\x89MCAP0\r\n"


LEFT_OUT_KINDS = {
    # the log was not read, on purpose
    "not-regular-file": "a FIFO, device, socket or directory named *.mcap: never opened",
    "bad-name": "a file name that is not UTF-8 text (the tables could not name it): never opened",
    "duplicate": "a copy of another log of the same episode: counted once",
    "conflict": "the same episode as another log, with different content: none of them counted",
    # the log could not be read or believed
    "cannot-read": "missing, no permission, or a directory that cannot be listed",
    "too-large": "larger than any episode log",
    "not-mcap": "not an MCAP file",
    "crc": "a chunk, data-section or summary CRC does not match: damaged content",
    "damaged": "the MCAP structure is broken (records, sizes, compression)",
    "metadata": "the fuzzynav.run metadata is missing or fails its checks",
    "schema": "a message is not JSON, or a field the analysis reads is missing, mistyped or out of range",
    "episode": "the messages disagree with each other (steps, times, positions, counts)",
    # the log was read, its episode did not finish
    "truncated": "the file ends before the MCAP summary (a killed run or a cut copy)",
    "incomplete": "no /episode outcome",
    "error": "the episode raised",
    "interrupted": "the episode was stopped",
}
"""Why a log is left out of the statistics: the ``kind`` of each row of the report's *Logs left out* table."""
SKIPPED_KINDS = ("not-regular-file", "bad-name", "duplicate", "conflict")  # left out without being read



class LogError(Exception):
    """A log cannot be read as a fuzzynav episode; the message names the file and what is wrong, ``kind`` says
    which check failed (a key of :data:`LEFT_OUT_KINDS`)."""

    def __init__(self, message: str, kind: str = "damaged") -> None:
        super().__init__(message)
        self.kind = kind

    def __reduce__(self):  # type: ignore[override]  # keep the kind across processes (Exception pickles args)
        return LogError, (str(self), self.kind)


def mcap_error_kind(message: str) -> str:
    """The :data:`LEFT_OUT_KINDS` key of an :class:`analysis.mcap_verify.McapError` message."""
    if message.startswith("not an MCAP file"):
        return "not-mcap"
    if "CRC mismatch" in message:
        return "crc"
    return "too-large" if "larger than any episode log" in message else "damaged"


class RejectedLog(type(Path())):  # type: ignore[misc]  # the concrete Path class of this platform
    """A path that :func:`analysis.log_inputs.find_logs` will not let the analysis read (not a regular file, the
    same episode as another log, ...), with the reason and its ``kind`` (:data:`LEFT_OUT_KINDS`); opening it raises
    :class:`LogError` with both. It survives pickling (the analysis's worker processes receive paths)."""

    reason: str
    kind: str
    copy_of: str | None  # a duplicate: the log counted in its place

    @classmethod
    def with_reason(cls, path: str | Path, reason: str, kind: str = "cannot-read",
                    copy_of: str | None = None) -> RejectedLog:
        rejected = cls(path)
        rejected.reason = reason
        rejected.kind = kind
        rejected.copy_of = copy_of
        return rejected

    def __reduce__(self):  # type: ignore[override]
        return RejectedLog.with_reason, (str(self), self.reason, self.kind, self.copy_of)


def file_kind(mode: int) -> str:
    """What a non-regular file is, from its ``st_mode``."""
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def regular_file_problem(path: Path) -> str | None:
    """Why ``path`` cannot be read as a log without opening it (missing, not a regular file), or None."""
    problem = _file_problem(path)
    return problem[1] if problem else None


def _file_problem(path: Path) -> tuple[str, str] | None:
    """(kind, reason) of :func:`regular_file_problem`, or None."""
    try:
        st = os.stat(path)
    except OSError as err:
        return "cannot-read", f"cannot read: {err.strerror or err}"
    if not stat.S_ISREG(st.st_mode):
        return "not-regular-file", f"{file_kind(st.st_mode)}, not a regular file: skipped, not opened"
    return None


def read_log_bytes(path: Path) -> bytes:
    """The whole file, after checking that it is a regular file of a plausible size; :class:`LogError`."""
    if isinstance(path, RejectedLog):
        raise LogError(f"{path}: {path.reason}", path.kind)
    problem = _file_problem(path)
    if problem:
        raise LogError(f"{path}: {problem[1]}", problem[0])
    try:
        # O_NONBLOCK: should the path have become a FIFO since the check, opening it still returns at once
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise LogError(f"{path}: cannot read: {err.strerror or err}", "cannot-read") from None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise LogError(f"{path}: {file_kind(st.st_mode)}, not a regular file: skipped", "not-regular-file")
        if st.st_size > MAX_FILE_BYTES:
            raise LogError(f"{path}: {st.st_size / 2**20:.0f} MB, larger than any episode log "
                           f"({MAX_FILE_BYTES // 2**20} MB)", "too-large")
        try:
            # the size first: a read of MAX_FILE_BYTES + 1 allocates that much up front (7x the time of reading
            # a 200 KB log); a file that has grown since fstat is read on, to the same limit
            data = f.read(st.st_size + 1)
            if len(data) > st.st_size:
                data += f.read(MAX_FILE_BYTES + 1 - len(data))
            return data
        except OSError as err:
            raise LogError(f"{path}: cannot read: {err.strerror or err}", "cannot-read") from None


def is_complete(path: Path) -> bool:
    """A finished MCAP ends with the magic bytes (a killed run's file does not). Only regular files are looked
    at (never a FIFO: opening one blocks)."""
    if regular_file_problem(Path(path)):
        return False
    try:
        with open(path, "rb") as f:
            f.seek(-len(MCAP_MAGIC), 2)
            return f.read() == MCAP_MAGIC
    except OSError:
        return False


class LogFile:
    """One log, read and verified when opened: metadata, channels and the messages of ``topics`` (None: all).
    ``complete``: the file has its MCAP summary (a killed run's has not; what it has is read). A context manager
    for compatibility (nothing stays open). Every problem is a :class:`LogError` naming the file."""

    def __init__(self, path: str | Path, topics: Iterable[str] | None = None) -> None:
        self.path = path if isinstance(path, Path) else Path(path)
        data = read_log_bytes(self.path)
        try:
            self._content: McapContent = read_mcap(data, None if topics is None else frozenset(topics))
        except McapError as err:
            damaged = "" if str(err).startswith("not an MCAP file") else "damaged MCAP file: "
            raise LogError(f"{self.path}: {damaged}{err}", mcap_error_kind(str(err))) from None
        self.complete = self._content.complete
        self._topics = {cid: topic for cid, (topic, _sid, _enc) in self._content.channels.items()}
        self._check_channels()

    def __enter__(self) -> LogFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Nothing to release: the file was read whole when opened."""

    def _check_channels(self) -> None:
        """Each of fuzzynav's topics on one channel, JSON-encoded, declaring the JSON schema its name says (the writer
        declares one for every topic)."""
        seen: set[str] = set()
        for topic, sid, encoding in self._content.channels.values():
            if topic in seen:
                raise LogError(f"{self.path}: two channels carry {topic}", "schema")
            seen.add(topic)
            expected = TOPIC_SCHEMAS.get(topic)
            if expected is None:
                continue
            if encoding != "json":
                raise LogError(f"{self.path}: {topic} is encoded as {encoding!r}, not json", "schema")
            if not sid:
                raise LogError(f"{self.path}: {topic} declares no schema, expected {expected!r}", "schema")
            name, schema_encoding = self._content.schemas[sid]
            if name != expected:
                raise LogError(f"{self.path}: {topic} declares schema {name!r}, expected {expected!r}", "schema")
            if schema_encoding != "jsonschema":
                raise LogError(f"{self.path}: {topic} declares a {schema_encoding!r} schema, expected 'jsonschema'",
                               "schema")

    def metadata(self) -> dict[str, str]:
        """The ``fuzzynav.run`` metadata record (exactly one)."""
        records = [m for name, m in self._content.metadata if name == RUN_METADATA]
        if not records and not self.complete:  # the writer puts the metadata first: a cut copy of a fuzzynav log
            raise LogError(f"{self.path}: truncated: the file ends before the MCAP summary, with no '{RUN_METADATA}' "
                           "metadata before that (a fuzzynav log cut short, or not a fuzzynav log)", "truncated")
        if not records:
            raise LogError(f"{self.path}: no '{RUN_METADATA}' metadata (not a fuzzynav log)", "metadata")
        if len(records) > 1:
            raise LogError(f"{self.path}: {len(records)} '{RUN_METADATA}' metadata records (expected one)",
                           "metadata")
        return dict(records[0])

    def raw_messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time ns, raw JSON bytes) in file order, which for fuzzynav logs is log-time order (the
        writer appends step after step); a truncated log yields what it has."""
        wanted = None if topics is None else frozenset(topics)
        names = self._topics
        for channel, log_time, data in self._content.messages:
            topic = names[channel]
            if wanted is None or topic in wanted:
                yield topic, log_time, data

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
        """(topic, log time ns, decoded JSON message), as :meth:`raw_messages`."""
        for topic, log_time, data in self.raw_messages(topics):
            yield topic, log_time, decode(self.path, topic, data)


def read_metadata(path: Path) -> dict[str, str]:
    """The ``fuzzynav.run`` metadata record of a log (complete or truncated), after verifying the file."""
    return LogFile(path, ()).metadata()


def iter_messages(path: Path, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """(topic, log time ns, decoded JSON message) in log-time order; a truncated log yields what it has."""
    yield from LogFile(path, topics).messages(topics)


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """Pause Python's cyclic garbage collector while one log is read (nests: the outermost restores it). A log is
    thousands of small containers (decoded JSON), all acyclic and freed by reference counting; while they are
    being built the collector would otherwise scan them and everything else alive again and again (measured: a
    fifth of the reading time)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def decode(path: Path, topic: str, data: bytes) -> Any:
    """One JSON message; :class:`LogError` naming the file and topic if it is not JSON."""
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError as err:
        raise not_json(path, topic, err) from None


def not_json(path: Path, topic: str, err: orjson.JSONDecodeError) -> LogError:
    """The error of a message that is not JSON (:func:`decode`'s, for a loop that calls ``orjson.loads`` itself)."""
    return LogError(f"{path}: a {topic} message is not valid JSON ({err})", "schema")


PARALLEL_MIN_LOGS = 200
"""With joblib's worker pool (where this process cannot fork), fewer logs are read in this process: starting its
workers costs about a second."""
FORK_MIN_LOGS = 16
"""With workers forked from this process (:mod:`analysis.forked`: a few milliseconds each), fewer logs are read in
this process."""


def read_logs(read: Callable[[list[Path]], T], logs: list[Path], jobs: int = 1,
              meanwhile: Callable[[], object] | None = None,
              pack: Callable[[dict[int, Any]], dict[int, Any]] | None = None) -> list[T]:
    """``read`` applied to consecutive chunks of ``logs``, results in order: in this process, or with ``jobs``
    > 1 (-1: every core) in that many processes: workers forked from this one (:mod:`analysis.forked`) from
    :data:`FORK_MIN_LOGS` logs on, or where this process cannot fork (other threads run: a sweep's launcher)
    joblib's loky pool, which a sweep has already started, from :data:`PARALLEL_MIN_LOGS` logs on. ``read``
    must be a module-level function (the pool pickles it). ``meanwhile``: work of this process's own, done while
    forked workers read (not called without them); ``pack``: applied by each forked worker to its results (chunk
    index -> result) before they travel back (:func:`analysis.forked.run`)."""
    from analysis import forked

    if jobs == 1 or len(logs) < min(FORK_MIN_LOGS, PARALLEL_MIN_LOGS):
        return [read(logs)]
    fork = forked.can_fork() and len(logs) >= FORK_MIN_LOGS
    if not fork and len(logs) < PARALLEL_MIN_LOGS:
        return [read(logs)]
    workers = forked.worker_count(jobs, len(logs))
    size = max(1, -(-len(logs) // (4 * workers)))  # a few chunks per worker balance the load
    chunks = [logs[i:i + size] for i in range(0, len(logs), size)]
    if fork:
        results = forked.run(lambda k: read(chunks[k]), len(chunks), workers, meanwhile, pack)
        error = next((r for r in results if isinstance(r, BaseException)), None)
        if error is not None:
            raise error
        return results
    from joblib import Parallel, delayed

    # max_nbytes=None as Hydra's joblib launcher sets it: with equal settings loky reuses the sweep's worker
    # pool instead of starting a new one (only paths travel to the workers: nothing to memory-map)
    return Parallel(n_jobs=workers, max_nbytes=None)(delayed(read)(chunk) for chunk in chunks)


def episode_summary(path: Path) -> dict[str, Any]:
    """One row: run parameters from the metadata and the ``/episode`` outcome (``incomplete`` if missing), after
    verifying the file and checking the metadata and the ``/episode`` message."""
    from analysis.log_check import check_metadata

    log = LogFile(path, ["/episode"])
    meta = log.metadata()
    try:
        check_metadata(meta)
    except CheckError as err:
        raise LogError(f"{path}: metadata {err}", "metadata") from None
    from analysis.run_parameters import LEGACY_POLICY

    row: dict[str, Any] = {"log": str(path), "scenario": meta["scenario"],
                           "policy": meta.get("policy") or LEGACY_POLICY, "strategy": meta["strategy"],
                           "h_wait": int(meta["h_wait"]), "controller": meta["controller"],
                           "perception": meta["perception"], "seed": int(meta["seed"]),
                           "outcome": "incomplete", "steps": None, "time_s": None, "contacts": None}
    for topic, _t, msg in log.messages(["/episode"]):
        try:
            check_message(topic, msg)
        except CheckError as err:
            raise LogError(f"{path}: /episode message does not match its schema: {err}", "schema") from None
        row.update(outcome=msg["outcome"], steps=msg["steps"], time_s=msg["time_s"], contacts=msg["contacts"])
    return row
