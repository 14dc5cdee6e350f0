"""The compiled chunk record loop (analysis._mcap_chunk) reads what analysis.mcap_verify's Python loop reads.

Each test reads the same bytes twice, with the kernel and with the Python loop (``mcap_verify._mcap_chunk`` set
to None), and compares everything: the McapContent, or the McapError's text. Chunks drawn at random (schema,
channel and message records, wanted and unwanted topics, other record types) and then damaged (flipped bytes,
cuts, lengths made huge or off by a little, opcodes and channel ids changed), a real log's first chunk damaged
the same way, and every committed log under datasets/. In CI (CI=true) the kernel must have been built.
"""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from analysis import mcap_verify
from analysis.episode_log import METRIC_TOPICS
from analysis.mcap_verify import CHANNEL, CHUNK, HEADER, MAGIC, MESSAGE, SCHEMA, McapError, read_mcap
from tests.conftest import require_compiled

require_compiled(mcap_verify._mcap_chunk, "_mcap_chunk")

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def _kernel_on(monkeypatch) -> None:
    """These tests compare the kernel with the Python loop: even under FUZZYNAV_KERNEL=python."""
    monkeypatch.delenv("FUZZYNAV_KERNEL", raising=False)

TOPICS = ("/a", "/b", "/c")
RUN = settings(max_examples=400, deadline=None, derandomize=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _string(s: str) -> bytes:
    raw = s.encode()
    return struct.pack("<I", len(raw)) + raw


def _record(opcode: int, body: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(body)) + body


def _schema(sid: int, name: str) -> bytes:
    return _record(SCHEMA, struct.pack("<H", sid) + _string(name) + _string("jsonschema") + _string("{}"))


def _channel(cid: int, sid: int, topic: str) -> bytes:
    return _record(CHANNEL, struct.pack("<HH", cid, sid) + _string(topic) + _string("json") + struct.pack("<I", 0))


def _message(cid: int, seq: int, log_time: int, data: bytes) -> bytes:
    return _record(MESSAGE, struct.pack("<HIQQ", cid, seq, log_time, log_time ^ 1) + data)


def _file(prefix: bytes, chunks: list[bytes]) -> bytes:
    """An unclosed MCAP file (a killed run's: no summary needed) holding ``chunks`` (each a chunk's records,
    stored uncompressed with no CRC) after the top-level records ``prefix``."""
    out = MAGIC + _record(HEADER, _string("") + _string("test"))
    out += prefix
    for records in chunks:
        out += _record(CHUNK, struct.pack("<QQQI", 0, 0, len(records), 0) + _string("")
                       + struct.pack("<Q", len(records)) + records)
    return out


class _Content(mcap_verify.McapContent):
    """Remembers the last one made: what a read had found when it failed."""

    last: mcap_verify.McapContent | None = None

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        _Content.last = self


def _read(data: bytes, topics, kernel: bool) -> object:
    """What read_mcap gives with or without the kernel: its content, or its error's type and text and the
    messages read before it."""
    saved = mcap_verify._mcap_chunk, mcap_verify.McapContent
    if not kernel:
        mcap_verify._mcap_chunk = None
    mcap_verify.McapContent = _Content
    try:
        return read_mcap(data, topics)
    except McapError as err:
        return type(err), str(err), _Content.last.messages
    finally:
        mcap_verify._mcap_chunk, mcap_verify.McapContent = saved


def _same(data: bytes, topics=None) -> object:
    with_kernel, python = _read(data, topics, True), _read(data, topics, False)
    assert with_kernel == python
    return with_kernel


def _misframed(opcode: int, body: bytes, change: int) -> bytes:
    """A record whose length field is not its body's: ``change`` more (huge: that length)."""
    length = change if change > 2**31 else max(0, len(body) + change)
    return struct.pack("<BQ", opcode, length) + body


_huge = st.sampled_from([2**64 - 1, 2**64 - 10, 2**63, 2**63 - 1, 2**32, 0, 1, 21, 22, 23])
_ids = st.integers(0, 5) | st.sampled_from([0xFFFF, 0x8000, 256])
_record_kinds = st.one_of(
    st.builds(_schema, st.integers(1, 3), st.sampled_from(["s1", "s2"])),
    st.builds(_channel, _ids, st.integers(0, 3), st.sampled_from(TOPICS)),
    st.builds(_message, _ids, st.integers(0, 2**32 - 1),
              st.sampled_from([0, 2**56, 2**63, 2**64 - 1]) | st.integers(0, 2**64 - 1), st.binary(max_size=40)),
    st.builds(_record, st.integers(0, 255), st.binary(max_size=30)),  # any type, also ones a chunk cannot hold
    st.builds(_misframed, st.sampled_from([SCHEMA, CHANNEL, MESSAGE, 0, CHUNK]), st.binary(max_size=30),
              st.integers(-30, 3) | _huge),
)


@st.composite
def _damage(draw, records: bytes) -> bytes:
    """``records`` with a few changes, each at a random place, and most often at a record's start."""
    out = bytearray(records)
    starts = _starts(records)
    for _ in range(draw(st.integers(0, 3))):
        if not out:
            break
        at = draw(st.sampled_from(starts) if starts and draw(st.booleans()) else st.integers(0, len(out) - 1))
        at = min(at, len(out) - 1)
        kind = draw(st.sampled_from(["flip", "cut", "length", "length_near", "opcode", "channel", "insert"]))
        if kind == "flip":
            out[at] ^= 1 << draw(st.integers(0, 7))
        elif kind == "cut":
            del out[draw(st.integers(0, len(out))):]
        elif kind == "length" and at + 9 <= len(out):
            out[at + 1:at + 9] = struct.pack("<Q", draw(_huge))
        elif kind == "length_near" and at + 9 <= len(out):  # just past, at or before what is left
            length = max(0, len(out) - at - 9 + draw(st.integers(-3, 3)))
            out[at + 1:at + 9] = struct.pack("<Q", length)
        elif kind == "opcode":
            out[at] = draw(st.sampled_from([0, 1, 2, SCHEMA, CHANNEL, MESSAGE, CHUNK, 0x80, 0xFF]))
        elif kind == "channel" and at + 11 <= len(out):
            out[at + 9:at + 11] = struct.pack("<H", draw(_ids))
        elif kind == "insert":
            out[at:at] = draw(st.binary(min_size=1, max_size=12))
    return bytes(out)


def _starts(records: bytes) -> list[int]:
    """Where the records of an undamaged chunk start (bytes)."""
    starts, pos = [], 0
    while pos + 9 <= len(records):
        starts.append(pos)
        pos += 9 + struct.unpack_from("<Q", records, pos + 1)[0]
    return starts


_topics = st.none() | st.frozensets(st.sampled_from(TOPICS))


@RUN
@given(prefix=st.lists(st.builds(_channel, _ids, st.just(0), st.sampled_from(TOPICS)), max_size=2),
       chunks=st.lists(st.lists(_record_kinds, max_size=12), min_size=1, max_size=3),
       topics=_topics, data=st.data())
@example(prefix=[], chunks=[[]], topics=None, data=None)
def test_random_chunks_read_the_same(prefix, chunks, topics, data) -> None:
    # the first chunk declares channels 0..2 most of the time, so that messages get past the channel check
    declared = b"".join(_channel(c, 0, t) for c, t in enumerate(TOPICS))
    records = [b"".join(chunk) for chunk in chunks]
    if data is not None and data.draw(st.booleans()):
        records[0] = declared + records[0]
    if data is not None:  # a chunk's last record is where most of the loop's bounds checks decide
        records[-1] += data.draw(st.just(b"") | st.builds(_misframed, st.sampled_from([SCHEMA, MESSAGE, CHUNK]),
                                                          st.binary(max_size=24), st.integers(-3, 3) | _huge))
        records = [data.draw(_damage(r)) for r in records]
    _same(_file(b"".join(prefix), records), topics)


# the loop's edge cases, each once: at the chunk's end a message header shorter than 31 bytes is read as a
# record header only; every error the loop has; a length of 2**64 - 1
_CH = _channel(1, 0, "/a")
_EDGES = [
    _CH + struct.pack("<BQ", MESSAGE, 10) + bytes(10),  # 19 bytes left, too short a message
    _CH + struct.pack("<BQ", MESSAGE, 21) + bytes(21),  # 30 bytes left
    _CH + struct.pack("<BQ", MESSAGE, 22) + bytes(20),  # a message header cut by the chunk's end
    _CH + struct.pack("<BQ", MESSAGE, 22) + b"\x01" + bytes(21),  # an empty message: 31 bytes exactly
    _CH + struct.pack("<BQ", MESSAGE, 2**64 - 1) + bytes(30),
    _CH + struct.pack("<BQ", SCHEMA, 2**64 - 1) + bytes(30),
    _CH + struct.pack("<BQ", MESSAGE, 2**64 - 10) + bytes(30),  # pos + 9 + length wraps around 2**64
    _CH + bytes(8),  # a record header cut
    _CH + struct.pack("<BQ", MESSAGE, 10) + bytes(5),  # too short, but first: runs past the chunk's end
    _CH + struct.pack("<BQ", CHUNK, 0),  # a whole record of 9 bytes at the end
    _CH + struct.pack("<BQ", SCHEMA, 0),
    _CH + _message(7, 0, 5, b"x"),  # undeclared channel
    _CH + _message(1, 0, 5, b"x") + _record(CHUNK, b""),  # cannot be in a chunk
    _CH + _message(1, 0, 5, b"x") + _channel(1, 0, "/b"),  # declared twice differently: Python's _inner
    _message(1, 0, 5, b"x") + _CH,  # message before its channel
    _CH + _channel(2, 0, "/b") + _message(2, 0, 2**64 - 1, b"yz") + _message(1, 9, 3, b"") + _channel(3, 0, "/c")
    + _message(3, 0, 0, b"{}"),
]


@pytest.mark.parametrize("records", _EDGES, ids=range(len(_EDGES)))
@pytest.mark.parametrize("topics", [None, ("/a", "/c")])
def test_edge_cases_read_the_same(records, topics) -> None:
    _same(_file(b"", [records]), topics)


_BASE = (_schema(1, "s1") + _channel(1, 1, "/a") + _message(1, 0, 2**64 - 1, b"{}") + _channel(2, 0, "/b")
         + _message(2, 1, 7, b"") + _message(1, 2, 2**56, b"[1, 2]") + _channel(3, 0, "/c")
         + _message(3, 3, 0, b"x" * 9) + _message(2, 4, 8, b"ab"))


def _lengths(records: bytes, at: int) -> list[int]:
    """Length fields worth trying for the record at byte ``at``: around what is left, the message header's size,
    the largest, and ones that wrap a 64-bit at + 9 + length around."""
    left = len(records) - at - 9
    return sorted({n for n in (0, 1, 8, 21, 22, 23, left - 1, left, left + 1, 2**31, 2**63 - 1, 2**63,
                               2**64 - 1, 2**64 - 9, 2**64 - at - 9, 2**64 - at - 10) if 0 <= n < 2**64})


@pytest.mark.parametrize("topics", [None, ("/a", "/c")])
def test_every_cut_length_and_opcode_reads_the_same(topics) -> None:
    """Systematically: the chunk cut at every byte, and each record's length and opcode set to each of a few
    values (what random damage hits only now and then)."""
    for cut in range(len(_BASE) + 1):
        _same(_file(b"", [_BASE[:cut]]), topics)
    for at in _starts(_BASE):
        for cut in (len(_BASE), at + 31, at + 30, at + 12):  # the record last in the chunk, or not
            records = _BASE[:cut]
            for length in _lengths(records, at):
                _same(_file(b"", [records[:at + 1] + struct.pack("<Q", length) + records[at + 9:]]), topics)
        for opcode in (*range(9), 0x10, 0xFF):
            _same(_file(b"", [_BASE[:at] + bytes([opcode]) + _BASE[at + 1:]]), topics)


def test_edge_case_results() -> None:
    """Not only the same: the errors are the ones meant, and the messages those of the wanted channels."""
    at = len(MAGIC) + len(_record(HEADER, _string("") + _string("test")))
    expected = {0: "a message record is too short", 1: "a message record is too short",
                2: "a record runs past the chunk's end", 4: "a record runs past the chunk's end",
                5: "a record runs past the chunk's end", 6: "a record runs past the chunk's end",
                7: "a record header is cut at the chunk's end", 8: "a record runs past the chunk's end",
                9: "record type 0x06 cannot be in a chunk", 11: "message on undeclared channel 7",
                12: "record type 0x06 cannot be in a chunk", 14: "message on undeclared channel 1"}
    for i, text in expected.items():
        assert _same(_file(b"", [_EDGES[i]]))[:2] == (McapError, f"chunk at byte {at}: {text}"), i
    assert _same(_file(b"", [_EDGES[3]])).messages == [(1, 0, b"")]
    assert _same(_file(b"", [_EDGES[-1]]), ("/b", "/c")).messages == [(2, 2**64 - 1, b"yz"), (3, 0, b"{}")]


def _committed_logs() -> list[Path]:
    names = subprocess.run(["git", "ls-files", "*.mcap"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    return [ROOT / name for name in names]


def _first_chunk(data: bytes) -> bytes:
    """The decompressed records of a log's first chunk."""
    pos = len(MAGIC)
    while True:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if opcode == CHUNK:
            body = pos + 9
            size = struct.unpack_from("<Q", data, body + 16)[0]
            (n,) = struct.unpack_from("<I", data, body + 28)
            compression = data[body + 32:body + 32 + n].decode()
            start = body + 32 + n + 8
            return mcap_verify._decompress(memoryview(data)[start:body + length], compression, size, pos)
        pos += 9 + length


LOGS = _committed_logs()  # the datasets' logs, and the damaged ones of tests/bad_inputs
DATASET_LOGS = [path for path in LOGS if path.relative_to(ROOT).parts[0] == "datasets"]
FIRST_CHUNK = _first_chunk(DATASET_LOGS[0].read_bytes()) if DATASET_LOGS else b""


def test_committed_logs_read_the_same() -> None:
    assert DATASET_LOGS, "no committed .mcap logs under datasets/"
    for path in LOGS:
        data = path.read_bytes()
        for topics in (None, METRIC_TOPICS):
            content = _same(data, topics)
            if path in DATASET_LOGS:
                assert not isinstance(content, tuple), (path, content)
                assert content.messages, path


@settings(RUN, max_examples=150)
@given(data=st.data(), topics=_topics | st.just(frozenset(METRIC_TOPICS)))
def test_damaged_real_chunk_reads_the_same(data, topics) -> None:
    assert FIRST_CHUNK
    _same(_file(b"", [data.draw(_damage(FIRST_CHUNK))]), topics)


def test_environment_switches_the_kernel_off(monkeypatch) -> None:
    class Refuse:
        @staticmethod
        def scan(*args):
            raise AssertionError("the kernel ran")

    data = _file(b"", [_CH + _message(1, 0, 5, b"x")])
    monkeypatch.setattr(mcap_verify, "_mcap_chunk", Refuse)
    with pytest.raises(AssertionError, match="the kernel ran"):
        read_mcap(data)
    monkeypatch.setenv("FUZZYNAV_KERNEL", "python")
    assert read_mcap(data).messages == [(1, 5, b"x")]


def test_scan_arguments() -> None:
    scan = mcap_verify._mcap_chunk.scan
    out: list = []
    assert scan(b"", 0, {}, out) == (0, 0, 0, 0) and out == []
    for pos in (-1, 1):
        with pytest.raises(ValueError):
            scan(b"", pos, {}, out)
    with pytest.raises(TypeError):
        scan(bytearray(), 0, {}, out)
    records = _message(1, 0, 7, b"ab") + _channel(2, 0, "/b")
    assert scan(records, 0, {1: True}, out) == (1, 33, CHANNEL, len(records)) and out == [(1, 7, b"ab")]
    assert scan(records, len(records), {}, out) == (0, len(records), 0, 0)
