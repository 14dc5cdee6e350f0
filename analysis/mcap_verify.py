"""Read one MCAP file from its bytes, verifying it before anything in it is believed.

Every record is framed by its length, every field of the records the analysis uses is checked to lie inside its
record, chunks are decompressed with their declared size as a hard limit and checked against their CRC, and a
complete file's data-section CRC (``DataEnd``) and summary CRC (``Footer``) are checked where the writer wrote
them (a CRC of 0 means "not computed": the Python ``mcap`` writer and streams written before the Foxglove SDK
wrote files itself leave the data-section CRC at 0; the chunk CRCs are always there). The MCAP specification:
https://mcap.dev/spec.

A file that ends with the closing magic must be complete and intact to the last byte. A file that does not is
a killed run's log: its records are read up to the first one that runs past the end of the file (the chunk
being written when the run stopped), or up to a last chunk that ends the file but cannot be read (the chunk
whose sizes the writer was filling in); any other record that fits in the file but is damaged is still an error.

Sizes are in bytes, times in nanoseconds.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any, BinaryIO

MAGIC = b"\x89MCAP0\r\n"
MAX_FILE_BYTES = 256 * 2**20  # a 10,000-step episode's log is ~20 MB: anything larger is not a fuzzynav log
MAX_CHUNK_BYTES = 64 * 2**20  # the writer's chunks are ~32 KB uncompressed: a bound against bogus size fields
#: all of a file's chunks decompressed (a log's compress about 4:1): without a bound, a few MB of chunks of zeros
#: declaring 64 MB each kept the analysis decompressing for minutes
MAX_DECOMPRESSED_BYTES = 4 * MAX_FILE_BYTES

# record opcodes (MCAP specification)
HEADER, FOOTER, SCHEMA, CHANNEL, MESSAGE, CHUNK, MESSAGE_INDEX, CHUNK_INDEX = 1, 2, 3, 4, 5, 6, 7, 8
ATTACHMENT, ATTACHMENT_INDEX, STATISTICS, METADATA, METADATA_INDEX, SUMMARY_OFFSET, DATA_END = 9, 10, 11, 12, 13, 14, 15
_KNOWN = frozenset(range(HEADER, DATA_END + 1))
_IN_CHUNK = frozenset({SCHEMA, CHANNEL, MESSAGE})  # the only records a chunk may hold
_DATA_ONLY = frozenset({HEADER, MESSAGE, CHUNK, MESSAGE_INDEX, ATTACHMENT, METADATA, DATA_END})
_SUMMARY_ONLY = frozenset({CHUNK_INDEX, ATTACHMENT_INDEX, STATISTICS, METADATA_INDEX, SUMMARY_OFFSET})

_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_RECORD = struct.Struct("<BQ")  # opcode, body length
_CHUNK_HEAD = struct.Struct("<QQQI")  # message start time, end time, uncompressed size, uncompressed CRC
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
_MESSAGE_START = struct.Struct("<BQH4xQ")  # a record's opcode and length, and if it is a message its channel and time

# the faults of a chunk's record loop (:func:`_chunk_fault`)
_CUT, _PAST_END, _TOO_SHORT, _UNDECLARED, _NOT_IN_CHUNK = range(2, 7)


class McapError(ValueError):
    """The bytes are not an intact MCAP file; the message says what is wrong and at which byte offset."""


@dataclass
class McapContent:
    """What a verified read found. ``complete``: the file has its summary and closing magic; otherwise
    ``stopped_at`` is the offset of the record that ran past the end of the file. ``messages``: (channel id,
    log time ns, JSON bytes) of the wanted topics, in file order."""

    complete: bool
    metadata: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    schemas: dict[int, tuple[str, str]] = field(default_factory=dict)  # id -> (name, encoding)
    channels: dict[int, tuple[str, int, str]] = field(default_factory=dict)  # id -> (topic, schema id, encoding)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)
    stopped_at: int | None = None


class _Cursor:
    """Reads fields of one record body ``data[start:end]``; reading past ``end`` is an :class:`McapError`."""

    __slots__ = ("data", "end", "pos", "what")

    def __init__(self, data: bytes | memoryview, start: int, end: int, what: str) -> None:
        self.data, self.pos, self.end, self.what = data, start, end, what

    def take(self, n: int) -> int:
        """Skip ``n`` bytes; returns where they start."""
        at = self.pos
        if n < 0 or at + n > self.end:
            raise McapError(f"{self.what} at byte {at}: a field runs past the end of its record")
        self.pos = at + n
        return at

    def u16(self) -> int:
        return _U16.unpack_from(self.data, self.take(2))[0]

    def u32(self) -> int:
        return _U32.unpack_from(self.data, self.take(4))[0]

    def u64(self) -> int:
        return _U64.unpack_from(self.data, self.take(8))[0]

    def raw(self, n: int) -> bytes:
        at = self.take(n)
        return bytes(self.data[at:at + n])

    def string(self) -> str:
        n = self.u32()
        try:
            return self.raw(n).decode("utf-8")
        except UnicodeDecodeError:
            raise McapError(f"{self.what} at byte {self.pos - n}: a string is not UTF-8") from None

    def string_map(self) -> dict[str, str]:
        size = self.u32()
        stop = self.take(size) + size
        inner = _Cursor(self.data, stop - size, stop, self.what)
        out: dict[str, str] = {}
        while inner.pos < stop:
            key = inner.string()
            out[key] = inner.string()
        return out


def read_mcap(data: bytes, topics: Collection[str] | None = None) -> McapContent:
    """Verify ``data`` (a whole MCAP file) and return its metadata, schemas, channels and the messages of
    ``topics`` (None: every topic; an empty collection: none, the file is still verified to the end).
    Raises :class:`McapError`."""
    if len(data) > MAX_FILE_BYTES:
        raise McapError(f"{len(data) / 2**20:.0f} MB: larger than any episode log ({MAX_FILE_BYTES // 2**20} MB)")
    if len(data) < len(MAGIC) or data[:len(MAGIC)] != MAGIC:
        raise McapError("not an MCAP file (no MCAP magic at the start)")
    closed = len(data) >= 2 * len(MAGIC) and data[-len(MAGIC):] == MAGIC
    out = McapContent(complete=False)
    reader = _Reader(data, out, topics)
    if closed:
        reader.intact_below = _intact_data_section(data)
    pos = len(MAGIC)
    footer_at = -1
    while pos < len(data):
        if pos + _RECORD.size > len(data):
            if closed:
                raise McapError(f"record header at byte {pos} runs past the end of the file")
            out.stopped_at = pos
            return out
        opcode, length = _RECORD.unpack_from(data, pos)
        body = pos + _RECORD.size
        if body + length > len(data):
            if closed:
                raise McapError(f"record at byte {pos} (opcode 0x{opcode:02x}) runs past the end of the file")
            out.stopped_at = pos
            return out
        if opcode not in _KNOWN:
            raise McapError(f"unknown record type 0x{opcode:02x} at byte {pos}")
        if opcode == FOOTER:
            footer_at = pos
            _check_footer(data, pos, body, length)
            pos = body + length
            break
        try:
            reader.record(opcode, pos, body, body + length)
        except McapError:
            # the writer fills in a chunk's sizes once its records are written: a run killed in between leaves
            # its last chunk whole in length but not yet readable, at the very end of the file
            if closed or opcode != CHUNK or body + length != len(data):
                raise
            out.stopped_at = pos
            return out
        pos = body + length
    if footer_at < 0:
        if closed:
            raise McapError("ends with the MCAP magic but has no footer record")
        out.stopped_at = pos
        return out
    if not reader.data_end_seen:
        raise McapError("no DataEnd record before the footer")
    if not closed and MAGIC.startswith(data[pos:]):  # cut inside the closing magic: a truncated copy
        out.stopped_at = pos
        return out
    if data[pos:] != MAGIC:
        raise McapError(f"{len(data) - pos - len(MAGIC)} unexpected byte(s) after the closing magic"
                        if data[pos:].startswith(MAGIC) else "the footer is not followed by the closing magic")
    out.complete = True
    return out


def peek_metadata(f: BinaryIO, name: str, max_records: int = 10_000) -> dict[str, str] | None:
    """The first metadata record called ``name`` in an open MCAP file, found by skipping from record to record
    without decompressing or verifying anything (None if there is none before the data section ends, or the
    framing is broken). Only for choosing which files to compare: never for believing what they say."""
    if f.read(len(MAGIC)) != MAGIC:
        return None
    for _ in range(max_records):
        head = f.read(_RECORD.size)
        if len(head) < _RECORD.size:
            return None
        opcode, length = _RECORD.unpack(head)
        if opcode in (DATA_END, FOOTER) or opcode not in _KNOWN or length > MAX_FILE_BYTES:
            return None
        if opcode != METADATA:
            f.seek(length, 1)
            continue
        body = f.read(length)
        try:
            cur = _Cursor(body, 0, len(body), "metadata")
            if cur.string() == name:
                return cur.string_map()
        except McapError:
            return None
    return None


def _intact_data_section(data: bytes) -> int:
    """Where the data section's DataEnd record is, if its CRC is there and matches the bytes before it (which
    are then as written), else 0: found from the footer at its fixed place before the closing magic, and the
    summary start it gives (the DataEnd record comes just before the summary, or the footer). Only an
    optimisation: the reader still checks that DataEnd when it reaches it, and every chunk beyond this point,
    or all of them when it is 0, against its own CRC."""
    footer_at = len(data) - len(MAGIC) - _RECORD.size - 20
    if footer_at < len(MAGIC) or _RECORD.unpack_from(data, footer_at) != (FOOTER, 20):
        return 0
    summary_start = _U64.unpack_from(data, footer_at + _RECORD.size)[0]
    at = (summary_start or footer_at) - _RECORD.size - 4
    if not len(MAGIC) <= at <= footer_at - _RECORD.size - 4 or _RECORD.unpack_from(data, at) != (DATA_END, 4):
        return 0
    crc = _U32.unpack_from(data, at + _RECORD.size)[0]
    return at if crc and zlib.crc32(memoryview(data)[:at]) == crc else 0


def _check_footer(data: bytes, at: int, body: int, length: int) -> None:
    """The summary CRC covers the summary section and the footer up to the CRC field (0: not computed)."""
    cur = _Cursor(data, body, body + length, "footer")
    summary_start, _summary_offset_start, crc = cur.u64(), cur.u64(), cur.u32()
    if summary_start > at or (summary_start and summary_start < len(MAGIC)):
        raise McapError(f"footer: summary start {summary_start} is outside the file's summary area")
    if crc:
        start = summary_start or at
        actual = zlib.crc32(memoryview(data)[start:body + 16])
        if actual != crc:
            raise McapError(f"summary CRC mismatch (footer at byte {at}: expected {crc}, computed {actual})")


class _Reader:
    """Files the records of the data and summary sections into a :class:`McapContent`."""

    def __init__(self, data: bytes, out: McapContent, topics: Collection[str] | None) -> None:
        self.data, self.out = data, out
        self.wanted = None if topics is None else frozenset(topics)
        self.keep: dict[int, bool] = {}  # channel id -> its messages are wanted
        self.header_seen = False
        self.data_end_seen = False
        self.zstd: Any = None  # one decompressor for the file's chunks (making one costs about a third of a chunk)
        # the bytes before this offset match the data section's CRC (_intact_data_section): a chunk that ends there
        # decompresses to what its writer compressed, so its own CRC (a fifth of the reading time) is not computed
        self.intact_below = 0
        self.decompressed = 0  # bytes, all chunks so far

    def record(self, opcode: int, at: int, body: int, end: int) -> None:
        first = not self.header_seen
        if (opcode == HEADER) != first:
            raise McapError(f"record at byte {at}: " + ("the file does not start with a header record" if first
                                                        else "a second header record"))
        self.header_seen = True
        if self.data_end_seen and opcode in _DATA_ONLY:
            raise McapError(f"record 0x{opcode:02x} at byte {at} after the data section's end")
        if not self.data_end_seen and opcode in _SUMMARY_ONLY:
            raise McapError(f"summary record 0x{opcode:02x} at byte {at} inside the data section")
        if opcode == CHUNK:
            self._chunk(at, body, end)
        elif opcode == DATA_END:
            self._data_end(at, body, end)
        elif opcode in _IN_CHUNK:
            if self.data_end_seen:  # summary copies of schemas and channels: covered by the summary CRC
                return
            self._inner(opcode, self.data, at, body, end)
        elif opcode == METADATA:
            cur = _Cursor(self.data, body, end, f"metadata record at byte {at}")
            self.out.metadata.append((cur.string(), cur.string_map()))

    def _data_end(self, at: int, body: int, end: int) -> None:
        crc = _Cursor(self.data, body, end, "DataEnd").u32()
        if crc:
            actual = zlib.crc32(memoryview(self.data)[:at])
            if actual != crc:
                raise McapError(f"data section CRC mismatch (expected {crc}, computed {actual}): the file was "
                                "changed after it was written")
        self.data_end_seen = True

    def _chunk(self, at: int, body: int, end: int) -> None:
        cur = _Cursor(self.data, body, end, f"chunk at byte {at}")
        _start, _end, size, crc = _CHUNK_HEAD.unpack_from(self.data, cur.take(_CHUNK_HEAD.size))
        compression = cur.string()
        n = cur.u64()
        payload = memoryview(self.data)[cur.take(n):cur.pos]
        if size > MAX_CHUNK_BYTES:
            raise McapError(f"chunk at byte {at}: declared size {size} bytes is implausible")
        self.decompressed += size
        if self.decompressed > MAX_DECOMPRESSED_BYTES:
            raise McapError(f"chunk at byte {at}: the chunks decompress to more than "
                            f"{MAX_DECOMPRESSED_BYTES // 2**20} MB: larger than any episode log")
        if compression == "zstd" and self.zstd is None:
            import zstandard

            self.zstd = zstandard.ZstdDecompressor()
        records = _decompress(payload, compression, size, at, self.zstd)
        if len(records) != size:
            raise McapError(f"chunk at byte {at}: {len(records)} bytes decompressed, {size} declared")
        if crc and end > self.intact_below and zlib.crc32(records) != crc:
            raise McapError(f"chunk at byte {at}: CRC mismatch (the chunk's content is damaged)")
        self._scan(records, at)

    def _scan(self, records: bytes, at: int) -> None:
        """The records of the chunk at byte ``at`` (``records``: its decompressed bytes): the wanted messages
        go to ``out.messages``, schemas and channels to :meth:`_inner`."""
        size = len(records)
        keep_of, append = self.keep.get, self.out.messages.append
        pos = 0
        start, head = _MESSAGE_START.unpack_from, _RECORD.size + _MESSAGE_HEAD.size
        while pos < size:
            if pos + _MESSAGE_START.size <= size:  # one unpack for most records (messages); the rest is ignored
                opcode, length, channel, log_time = start(records, pos)
            elif pos + _RECORD.size <= size:
                (opcode, length), channel, log_time = _RECORD.unpack_from(records, pos), -1, 0
            else:
                raise _chunk_fault(at, _CUT)
            stop = pos + _RECORD.size + length
            if stop > size:
                raise _chunk_fault(at, _PAST_END)
            if opcode == MESSAGE:  # inline: most records are messages
                if length < _MESSAGE_HEAD.size:
                    raise _chunk_fault(at, _TOO_SHORT)
                keep = keep_of(channel)
                if keep:
                    append((channel, log_time, records[pos + head:stop]))
                elif keep is None:
                    raise _chunk_fault(at, _UNDECLARED, channel)
            elif opcode in _IN_CHUNK:
                self._inner(opcode, records, at, pos + _RECORD.size, stop)
            else:
                raise _chunk_fault(at, _NOT_IN_CHUNK, opcode)
            pos = stop

    def _inner(self, opcode: int, data: bytes, at: int, body: int, end: int) -> None:
        """A schema, channel or message record (top level or inside the chunk at byte ``at``)."""
        if opcode == MESSAGE:
            if end - body < _MESSAGE_HEAD.size:
                raise McapError(f"message record in the record at byte {at} is too short")
            channel, _seq, log_time, _publish = _MESSAGE_HEAD.unpack_from(data, body)
            keep = self.keep.get(channel)
            if keep is None:
                raise McapError(f"message on undeclared channel {channel} (record at byte {at})")
            if keep:
                self.out.messages.append((channel, log_time, data[body + _MESSAGE_HEAD.size:end]))
            return
        cur = _Cursor(data, body, end, f"record at byte {at}")
        if opcode == SCHEMA:
            sid = cur.u16()
            name, encoding = cur.string(), cur.string()
            cur.raw(cur.u32())  # the schema text: the analysis checks messages against its own schemas
            self._declare(self.out.schemas, sid, (name, encoding), "schema", at)
        else:
            cid, sid = cur.u16(), cur.u16()
            topic, encoding = cur.string(), cur.string()
            cur.string_map()
            if sid and sid not in self.out.schemas:
                raise McapError(f"channel {topic!r} refers to undeclared schema {sid} (record at byte {at})")
            self._declare(self.out.channels, cid, (topic, sid, encoding), "channel", at)
            self.keep[cid] = self.wanted is None or topic in self.wanted

    @staticmethod
    def _declare(table: dict, key: int, value: tuple, what: str, at: int) -> None:
        if table.setdefault(key, value) != value:
            raise McapError(f"{what} {key} declared twice with different content (record at byte {at})")


def _chunk_fault(at: int, code: int, value: int = 0) -> McapError:
    """The error of the record loop over the chunk at byte ``at`` (both loops' messages are made here, so they
    are the same text): ``code`` one of _CUT ... _NOT_IN_CHUNK, ``value`` the channel id or opcode it names."""
    what = {_CUT: "a record header is cut at the chunk's end", _PAST_END: "a record runs past the chunk's end",
            _TOO_SHORT: "a message record is too short", _UNDECLARED: f"message on undeclared channel {value}",
            _NOT_IN_CHUNK: f"record type 0x{value:02x} cannot be in a chunk"}[code]
    return McapError(f"chunk at byte {at}: {what}")


def _decompress(payload: memoryview, compression: str, size: int, at: int, zstd: Any = None) -> bytes:
    """A chunk's records; never more than ``size`` bytes are allocated, whatever the payload claims. ``zstd``: a
    ``zstandard.ZstdDecompressor`` to use (a new one if None)."""
    try:
        if compression == "":
            return bytes(payload)
        if compression == "zstd":
            import zstandard

            claimed = zstandard.frame_content_size(payload)
            if claimed not in (size, -1):  # stated (the Python writer) or not (the Foxglove SDK's)
                raise McapError(f"chunk at byte {at}: the zstd frame states {claimed} bytes, the chunk {size}")
            return (zstd or zstandard.ZstdDecompressor()).decompress(payload, max_output_size=size)
        if compression == "lz4":
            import lz4.frame

            with lz4.frame.LZ4FrameDecompressor() as decompressor:
                out = decompressor.decompress(bytes(payload), max_length=size)
                # inside the block: leaving it resets the decompressor, and with it ``eof``
                if not decompressor.eof:
                    raise McapError(f"chunk at byte {at}: the lz4 frame holds more than the {size} bytes declared")
            return out
    except McapError:
        raise
    except Exception as err:  # zstandard/lz4 raise their own error types on damaged frames
        raise McapError(f"chunk at byte {at}: cannot decompress ({type(err).__name__}: {err})") from None
    raise McapError(f"chunk at byte {at}: unknown compression {compression!r}")
