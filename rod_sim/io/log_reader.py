"""Reading one MCAP file with its integrity checked (:class:`LogReader`): the framing of every
record, each chunk's CRC, the data-section and summary CRCs, built on the ``mcap`` library's
record parsers. Intact chunks stay readable after damage elsewhere (a flipped bit, a cut file);
one flipped bit outside the chunks' data is located by the data-section CRC and corrected in
what is read. Opening a log (a file or a rosbag2 bag) goes through :mod:`rod_sim.io.log_open`.
"""
from __future__ import annotations

import contextlib
import heapq
import io
import os
import struct
import sys
import time
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk, get_chunk_data_stream
from mcap_ros2.decoder import DecoderFactory

try:    # mcap_ros2's vendored .msg parser prints to stderr before it raises on a corrupt schema
    from mcap_ros2._vendor.rosidl_adapter import parser as _msg_parser
except ImportError:         # pragma: no cover - another mcap_ros2 layout: its prints stay
    _msg_parser = None

from rod_sim.io.crc_locate import locate_single_bit
from rod_sim.io.fast_decode import fast_decoder
from rod_sim.io.log_format import MAGIC, METADATA_NAME, LogFormatError


def _drop_print(*args, **kwargs) -> None:
    """The vendored parser's ``print``: its error text precedes an exception that the log's
    readers report as one line of their own. Shadowing the name in that module alone leaves
    ``sys.stderr`` to every other thread (a process-wide redirection around each decode hid
    the progress lines and compile notices printed meanwhile)."""


if _msg_parser is not None:
    _msg_parser.print = _drop_print


class Checking:
    """The file a :class:`LogReader` is checking now (its integrity pass over every record,
    when it opens), for a command's progress line from another thread: ``path`` ('' when
    none), ``done`` and ``size`` [bytes] of its data section, ``since`` (time.monotonic()
    when the pass began). One per process (:data:`CHECKING`); plain attributes, read without
    a lock (a progress line may be one record behind)."""

    def __init__(self):
        self.path, self.done, self.size, self.since = "", 0, 0, 0.0


CHECKING = Checking()


PASSED_FILES = 8
"""Files whose clean integrity pass is kept inside :func:`passes_reused` at most."""
_PASSED: dict[tuple, dict] = {}
_REUSE = False


@contextlib.contextmanager
def passes_reused():
    """Inside this block a file whose integrity pass found nothing wrong is not checked again
    when it is opened again (unchanged: same device, inode, size and modification time): for
    a command that opens one log several times while it runs (``deployment-figure``: scene,
    states, events, base; each pass reads and checks every record, ~2 s for 260 MB). Outside
    it every open checks the file."""
    global _REUSE
    _REUSE = True
    try:
        yield
    finally:
        _REUSE = False
        _PASSED.clear()


_PASS_RESULTS = ("_schemas", "_channels", "_metadata", "_spans", "_bad_chunks", "_bad_records",
                 "_chunk_headers", "_first_chunk", "_data_crc_mismatch", "_readable_end",
                 "truncated")
"""What the pass sets (read-only afterwards)."""


def _file_key(file, data_limit: int) -> tuple:
    """The identity of an open file's content as far as the pass goes: device, inode, size,
    modification time [ns] and where its data section ends."""
    st = os.fstat(file.fileno())
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, data_limit


_RECORD_READERS = {
    Opcode.HEADER: Header.read,
    Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.METADATA: Metadata.read,
    Opcode.CHUNK: Chunk.read,
}
_FIRST_RESERVED_OPCODE, _FIRST_PRIVATE_OPCODE = 0x10, 0x80
"""Opcodes 0x10..0x7F are reserved by the MCAP spec (no writer uses them): one found in the data
section is a corrupt byte, not an unknown record to skip (0x80.. are user records)."""
_FOOTER_BODY = 8 + 8 + 4


def _chunk_definitions(stream: ReadDataStream, length: int) -> list:
    """The Schema and Channel records of a decompressed chunk (``stream`` of ``length`` bytes,
    as :func:`mcap.stream_reader.get_chunk_data_stream` returns it), then a :class:`_Times`
    of its messages' log times (parsed from the CRC-checked data, not the chunk header);
    messages are otherwise skipped unparsed. Raises ValueError for a record running past the
    chunk's end."""
    data = stream.read(length)
    out: list = []
    pos = 0
    first = last = None
    while pos < length:
        opcode, size = struct.unpack_from("<BQ", data, pos)
        end = pos + 9 + size
        if end > length:
            raise ValueError(f"record of {size} bytes at chunk offset {pos} runs past the chunk")
        if opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            out.append(_RECORD_READERS[opcode](ReadDataStream(io.BytesIO(data[pos + 9:end]))))
        elif opcode == Opcode.MESSAGE:
            t = struct.unpack_from("<Q", data, pos + 9 + 6)[0]
            first = t if first is None else min(first, t)
            last = t if last is None else max(last, t)
        pos = end
    out.append(_Times(first, last))
    return out


@dataclass(frozen=True)
class _Times:
    first: int | None
    last: int | None


_reported: set = set()
"""(path, warning) already printed by this process (a log is often opened more than once)."""


def _report(path: Path, text: str) -> None:
    key = (str(path), text)
    if key not in _reported:
        _reported.add(key)
        print(f"rod-sim: warning: {text}", file=sys.stderr, flush=True)


@dataclass(frozen=True)
class _Span:
    """Where messages live in the data section: a chunk (or one un-chunked message record)
    at byte ``offset`` holding log times ``start``..``end`` [ns]."""

    start: int
    end: int
    offset: int


class LogReader:
    """Reads an MCAP log (rod_sim's or any ROS 2 one); a context manager.

    Opening the file checks its integrity in one pass over the data section (bounded memory:
    one chunk at a time): every record's framing, every chunk's CRC (of its uncompressed
    data), the data-section CRC in the DataEnd record and the summary CRC in the footer (each
    where the writer stored one; 0 means "not computed" in MCAP). Damage never makes intact
    data unreachable, and nothing damaged is used:

    - a chunk whose CRC fails (or that cannot be decoded) is skipped; the chunks before and
      after it are read, and a warning names its byte offset and the gap in log time;
    - a summary whose CRC fails is ignored (the chunks of the data section are read instead);
    - a data-section CRC that fails while every chunk's own CRC holds means a damaged byte
      outside the chunks' data (header, metadata, a chunk's header): one flipped bit there is
      located from the CRC and corrected in what is read (warning naming it); otherwise the
      warning says the metadata is not verified.

    Each warning is in ``warnings`` and printed once per process on stderr. Framing damage
    (a record length, an invalid opcode) still raises :class:`LogFormatError` naming the byte
    offset. The summary and indexes of an undamaged complete file are used for reading;
    otherwise (a writer killed before ``close``, or damage) the chunks found by the pass are
    read, up to the first incomplete record. Message iteration holds at most the chunks whose
    time ranges overlap (memory independent of the log length). Raises
    :class:`LogFormatError` for a file that is not MCAP.

    Attributes: ``complete`` is True when the file has its summary and indexes (it was closed
    cleanly) and no damage was found; ``truncated`` is True when it ends in an incomplete
    record; ``damaged`` is True when something was skipped, ignored or corrected.
    """

    MAX_SEARCH_BYTES = 4 << 20
    """[bytes] outside the chunks' data searched for one flipped bit (a byte-by-byte walk
    in Python, ~1 us a byte); beyond this only the header, metadata and chunk headers."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._file = open(self.path, "rb")
        try:
            self._size = self._file.seek(0, io.SEEK_END)
            self._file.seek(0)
            if self._file.read(len(MAGIC)) != MAGIC:
                raise LogFormatError(f"{self.path} is not an MCAP file (bad magic)")
            self._file.seek(0)
            self._reader = make_reader(self._file, validate_crcs=True,
                                       decoder_factories=[DecoderFactory()])
            self.truncated = False
            self.warnings: list[str] = []
            self._patches: dict[int, int] = {}
            self._footer_at = self._footer_offset()
            self._data_limit = self._footer_at if self._footer_at is not None else self._size
            self._summary = self._read_summary()
            key = _file_key(self._file, self._data_limit) if _REUSE else None
            passed = _PASSED.get(key) if key is not None else None
            if passed is not None:        # this very file already passed in this process
                for name, value in passed.items():
                    setattr(self, name, value)
            else:
                CHECKING.done, CHECKING.size = 0, self._data_limit
                CHECKING.since, CHECKING.path = time.monotonic(), str(self.path)
                try:
                    self._check_data_section()
                finally:
                    CHECKING.path = ""
                if key is not None:
                    self._remember_pass(key)
            if self._data_crc_mismatch is not None:
                self._explain_data_crc()
            if self._bad_records:
                raise self._bad_records[0]
            self._report_bad_chunks()
        except BaseException:
            self._file.close()
            raise
        self.damaged = bool(self.warnings)
        if self.damaged:
            for text in self.warnings:
                _report(self.path, text)
            if self._summary is not None:       # its channels stand in for a damaged chunk's
                for cid, channel in self._summary.channels.items():
                    self._channels.setdefault(cid, channel)
                for sid, schema in self._summary.schemas.items():
                    self._schemas.setdefault(sid, schema)
            self._summary = None                # read the checked chunks, never the indexes
        self.complete = self._summary is not None

    def _read_at(self, pos: int, size: int) -> bytes:
        """``size`` bytes at ``pos``, with the located bit flips corrected."""
        self._file.seek(pos)
        data = self._file.read(size)
        if self._patches:
            fixed = None
            for at, mask in self._patches.items():
                if pos <= at < pos + len(data):
                    fixed = bytearray(data) if fixed is None else fixed
                    fixed[at - pos] ^= mask
            if fixed is not None:
                data = bytes(fixed)
        return data

    def _warn(self, text: str) -> None:
        self.warnings.append(f"{self.path}: {text}")

    def _corrupt(self, pos: int, what: str) -> LogFormatError:
        return LogFormatError(f"{self.path}: corrupt log: {what} at byte {pos}; nothing of it "
                              "is used (a damaged copy? re-record, or try `rod-sim repair`)")

    def _footer_offset(self) -> int | None:
        """Byte offset of the Footer record when the file ends in one (a closed log)."""
        at = self._size - len(MAGIC) - 9 - _FOOTER_BODY
        if at < len(MAGIC):
            return None
        self._file.seek(-len(MAGIC), io.SEEK_END)
        if self._file.read(len(MAGIC)) != MAGIC:
            return None
        self._file.seek(at)
        opcode, length = struct.unpack("<BQ", self._file.read(9))
        if opcode != Opcode.FOOTER or length != _FOOTER_BODY:
            return None
        return at

    def _read_summary(self):
        if self._footer_at is None:
            return None
        self._file.seek(self._footer_at + 9)
        summary_start, _, summary_crc = struct.unpack("<QQI", self._file.read(_FOOTER_BODY))
        self._data_limit = summary_start or self._footer_at
        if summary_crc:
            if not len(MAGIC) <= summary_start <= self._footer_at:
                raise self._corrupt(self._footer_at, f"footer points the summary at byte "
                                                     f"{summary_start}")
            begin = summary_start or self._footer_at
            self._file.seek(begin)
            data = self._file.read(self._footer_at + 9 + 16 - begin)
            if zlib.crc32(data) != summary_crc:
                self._warn(f"the summary section (byte {begin}) is damaged (CRC mismatch): "
                           "ignored, the data section's chunks are read instead "
                           "(`rod-sim repair` rewrites it)")
                self._data_limit = (summary_start if len(MAGIC) <= summary_start < self._footer_at
                                    else self._footer_at)
                return None
        try:
            summary = self._reader.get_summary()
        except (McapError, struct.error, ValueError, UnicodeDecodeError, MemoryError):
            return None
        if summary is None or (summary.statistics is not None
                               and summary.statistics.message_count and not summary.chunk_indexes):
            return None
        return summary

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "LogReader":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    # ----- the integrity pass -----

    def _records(self) -> Iterator[tuple[int, int, bytes]]:
        """(offset, opcode, body) of the data section's records, up to DataEnd (checked
        against its CRC) or the first incomplete record (``truncated``)."""
        size, pos = self._data_limit, len(MAGIC)
        crc = zlib.crc32(MAGIC)
        complete_file = self._footer_at is not None
        while True:
            if pos + 9 > size:
                break
            head = self._read_at(pos, 9)
            opcode, length = struct.unpack("<BQ", head)
            end = pos + 9 + length
            if _FIRST_RESERVED_OPCODE <= opcode < _FIRST_PRIVATE_OPCODE or opcode == 0:
                raise self._corrupt(pos, f"invalid record opcode {opcode:#x}")
            if end > size:
                break
            if opcode == Opcode.DATA_END:
                self._readable_end = self._size
                stored = struct.unpack("<I", self._read_at(pos + 9, 4))[0] if length >= 4 else 0
                if stored and stored != crc:
                    self._data_crc_mismatch = (pos, stored, crc)
                return
            if opcode == Opcode.FOOTER:
                self._readable_end = pos
                break
            body = self._read_at(pos + 9, length)
            crc = zlib.crc32(body, zlib.crc32(head, crc))
            yield pos, opcode, body
            pos = CHECKING.done = end
        if complete_file:
            raise self._corrupt(pos, "no DataEnd record where the data section ends (a record "
                                     "length damaged?)")
        self._readable_end = pos
        self.truncated = pos < size

    def _parse(self, pos: int, opcode: int, body: bytes, *, messages: bool = True) -> list:
        """The record at ``pos`` as a list: a Chunk is decompressed, its CRC checked, and broken
        up into its records (only its schemas and channels unless ``messages``)."""
        try:
            stream = ReadDataStream(io.BytesIO(body))
            if opcode == Opcode.MESSAGE:
                return [Message.read(stream, len(body))]
            record = _RECORD_READERS[opcode](stream)
            if not isinstance(record, Chunk):
                return [record]
            if messages:
                return breakup_chunk(record, validate_crc=True)
            return _chunk_definitions(*get_chunk_data_stream(record, validate_crc=True))
        except MemoryError:
            raise
        except Exception as exc:  # noqa: BLE001 - any decoding failure is corruption
            text = " ".join(str(exc).split())[:200]
            raise self._corrupt(pos, f"unreadable record (opcode {opcode:#x}: "
                                     f"{type(exc).__name__}: {text})") from None

    def _remember_pass(self, key) -> None:
        """Keep what the integrity pass found when it found nothing wrong (a whole file,
        every CRC right): another reader of the same file in this process takes it over."""
        if self.truncated or self.warnings or self._bad_chunks or self._bad_records or \
                self._data_crc_mismatch is not None or self._patches:
            return
        if len(_PASSED) >= PASSED_FILES:
            _PASSED.pop(next(iter(_PASSED)))
        _PASSED[key] = {name: getattr(self, name) for name in _PASS_RESULTS}

    def _check_data_section(self) -> None:
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._metadata: list[Metadata] = []
        self._spans: list[_Span] = []
        self._bad_chunks: list[tuple[int, str]] = []       # (offset, why)
        self._bad_records: list[LogFormatError] = []       # undecodable header / metadata
        self._chunk_headers: list[tuple[int, int]] = []   # byte ranges outside chunk data
        self._first_chunk: int | None = None
        self._data_crc_mismatch: tuple[int, int, int] | None = None
        for pos, opcode, body in self._records():
            if opcode != Opcode.CHUNK and self._first_chunk is not None:   # message indexes
                self._outside_chunks(pos, pos + 9 + len(body))
            if opcode == Opcode.MESSAGE:
                t = self._parse(pos, opcode, body)[0].log_time
                self._spans.append(_Span(t, t, pos))
                continue
            if opcode not in _RECORD_READERS:
                continue
            if opcode == Opcode.CHUNK:
                if self._first_chunk is None:
                    self._first_chunk = pos
                # opcode, length, times, sizes, CRC, compression string, records length
                name_len = struct.unpack_from("<I", body, 28)[0] if len(body) >= 32 else 0
                self._outside_chunks(pos, pos + 9 + 32 + min(name_len, 64) + 8)
                try:
                    parsed = self._parse(pos, opcode, body, messages=False)
                except LogFormatError as exc:
                    self._bad_chunks.append((pos, "CRC mismatch" if "CRCValidation" in str(exc)
                                             else "undecodable"))
                    continue
            else:
                try:
                    parsed = self._parse(pos, opcode, body, messages=False)
                except LogFormatError as exc:        # one flipped bit may still be located
                    self._bad_records.append(exc)
                    continue
            for record in parsed:
                if isinstance(record, Schema):
                    self._schemas[record.id] = record
                elif isinstance(record, Channel):
                    self._channels[record.id] = record
                elif isinstance(record, Metadata):
                    self._metadata.append(record)
                elif isinstance(record, _Times) and record.first is not None:
                    self._spans.append(_Span(record.first, record.last, pos))

    def _outside_chunks(self, start: int, stop: int) -> None:
        """Note bytes outside the chunks' data (merged with the previous range when they
        follow it: two ranges a chunk, whatever the number of its message indexes)."""
        ranges = self._chunk_headers
        if ranges and ranges[-1][1] == start:
            ranges[-1] = (ranges[-1][0], stop)
        else:
            ranges.append((start, stop))

    def _explain_data_crc(self) -> None:
        """Every chunk's CRC holds but the data-section CRC does not: find the one flipped
        bit outside the chunks' data (header, metadata, chunk headers) and correct it, or
        say that the metadata is not verified."""
        pos, stored, computed = self._data_crc_mismatch
        syndrome = stored ^ computed
        damaged = bool(self._bad_chunks or self._bad_records)
        if syndrome & (syndrome - 1) == 0 and not damaged:   # the stored CRC itself
            self._warn(f"the data-section CRC stored at byte {pos + 9} is damaged (one flipped "
                       "bit); every record it covers is intact and used")
            return
        prefix_end = self._first_chunk if self._first_chunk is not None else pos
        ranges = self._chunk_headers
        if sum(b - a for a, b in ranges) > self.MAX_SEARCH_BYTES:    # chunk headers only
            head = 9 + 32 + 64 + 8            # a range begins or ends with a chunk header
            ranges = [r for a, b in ranges for r in ((a, min(b, a + head)),
                                                    (max(a, b - head), b))]
        found = locate_single_bit(syndrome, pos, [(0, prefix_end), *ranges])
        if found is not None:
            at, bit = found
            self._patches[at] = 1 << bit
            self._check_data_section()              # again, with the bit corrected
            if self._data_crc_mismatch is None and not self._bad_chunks and not self._bad_records:
                what = ("a chunk header or message index" if self._first_chunk is not None
                        and at >= self._first_chunk else "the header or metadata record")
                self._warn(f"one flipped bit at byte {at} (bit {bit}, in {what}) was located "
                           "by the data-section CRC and corrected in what is read; every "
                           "chunk's own CRC holds (`rod-sim repair` writes a corrected copy)")
                return
            self._patches.clear()
            self._check_data_section()
        if damaged:
            return                                 # explained by the damaged records
        self._warn(f"the data-section CRC (DataEnd at byte {pos}) does not match, and no "
                   "single flipped bit outside the chunks' data explains it; "
                   "every chunk's own CRC holds and its messages are used, the metadata "
                   "(scene) is not verified")

    def _report_bad_chunks(self) -> None:
        """One warning per damaged chunk: its offset, why, and the gap in log time between
        the intact messages before and after it."""
        if not self._bad_chunks:
            return
        spans = sorted(self._spans, key=lambda sp: sp.offset)
        for pos, why in self._bad_chunks:
            before = max((sp.end for sp in spans if sp.offset < pos), default=None)
            after = min((sp.start for sp in spans if sp.offset > pos), default=None)
            gap = ("from the start" if before is None else f"from {before / 1e9:.9g} s") + \
                  (" to the end" if after is None else f" to {after / 1e9:.9g} s")
            self._warn(f"the chunk at byte {pos} is damaged ({why}): its messages are skipped, "
                       f"the chunks before and after it are read; gap in log time {gap}")

    # ----- messages of the data section, in log-time order -----

    def _span_messages(self, span: _Span) -> list[Message]:
        opcode, length = struct.unpack("<BQ", self._read_at(span.offset, 9))
        return [r for r in self._parse(span.offset, opcode, self._read_at(span.offset + 9, length))
                if isinstance(r, Message)]

    def _scan_ordered(self, wanted: set[str] | None) -> Iterator[tuple[Channel, Message]]:
        """(channel, message) of the data section in (log time, file order), opening a chunk
        only when the next message could come from it."""
        ids = {cid for cid, c in self._channels.items() if wanted is None or c.topic in wanted}
        spans = sorted(self._spans, key=lambda s: (s.start, s.offset))
        heap: list = []
        i = 0
        while i < len(spans) or heap:
            while i < len(spans) and (not heap or spans[i].start <= heap[0][0]):
                span = spans[i]
                for k, record in enumerate(self._span_messages(span)):
                    if record.channel_id not in self._channels:
                        if self._bad_chunks:
                            raise LogFormatError(
                                f"{self.path}: corrupt log: the damaged chunk at byte "
                                f"{self._bad_chunks[0][0]} held the definition of channel "
                                f"{record.channel_id}, which later messages use (a log without "
                                "summary has no other copy)")
                        raise LogFormatError(f"{self.path}: message on unknown channel "
                                             f"{record.channel_id}")
                    if record.channel_id in ids:
                        heapq.heappush(heap, (record.log_time, span.offset, k, record))
                i += 1
            if heap:
                record = heapq.heappop(heap)[3]
                yield self._channels[record.channel_id], record

    # ----- queries -----

    def metadata(self, name: str = METADATA_NAME) -> dict[str, str]:
        """The metadata record ``name`` (default ``rod_sim``): its str -> str entries.

        Raises LogFormatError when the log has none.
        """
        for record in self._metadata:
            if record.name == name:
                return dict(record.metadata)
        if self.truncated and not self._metadata:
            raise LogFormatError(f"{self.path} is truncated before its {name!r} metadata record")
        raise LogFormatError(f"{self.path} has no {name!r} metadata record (not a rod_sim log?)")

    def _schemas_channels(self) -> tuple[dict[int, Schema], list[Channel]]:
        if self._summary is not None:
            return self._summary.schemas, list(self._summary.channels.values())
        return self._schemas, list(self._channels.values())

    def topics(self) -> dict[str, str]:
        """Absolute topic name -> ROS type name (e.g. ``'/rod_states': 'sensor_msgs/msg/JointState'``)."""
        schemas, channels = self._schemas_channels()
        return {c.topic: (schemas[c.schema_id].name if c.schema_id in schemas else "")
                for c in channels}

    def messages(self, topics: Iterable[str] | str | None = None
                 ) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log_time [ns], decoded message)`` in log-time order (file order on ties).

        ``topics``: absolute or relative names to keep (default: all). Decoded messages have
        the ROS field names as attributes.
        """
        wanted = None
        if topics is not None:
            names = [topics] if isinstance(topics, str) else list(topics)
            wanted = {t if t.startswith("/") else "/" + t for t in names}
        schemas, _ = self._schemas_channels()
        factory = DecoderFactory()
        decoders: dict[int, Any] = {}
        for channel, record in self._ordered(wanted):
            decoder = decoders.get(channel.id)
            if decoder is None:
                schema = schemas.get(channel.schema_id)
                decoder = factory.decoder_for(channel.message_encoding, schema)
                if decoder is None:
                    raise LogFormatError(f"{self.path}: cannot decode {channel.topic} "
                                         f"({channel.message_encoding})")
                if channel.message_encoding == "cdr" and schema is not None:
                    decoder = fast_decoder(schema.name, schema.data.decode("utf-8", "replace"),
                                           decoder)
                decoders[channel.id] = decoder
            yield channel.topic, record.log_time, decoder(record.data)

    def _ordered(self, wanted: set[str] | None) -> Iterator[tuple[Channel, Message]]:
        if self._summary is None:
            yield from self._scan_ordered(wanted)
            return
        try:
            for _, channel, message in self._reader.iter_messages(topics=wanted,
                                                                   log_time_order=True):
                yield channel, message
        except (McapError, ValueError) as exc:
            raise LogFormatError(f"{self.path}: cannot read messages: "
                                 f"{' '.join(str(exc).split())[:200]}") from None

    # ----- raw access, for players and repair -----

    def header(self) -> Header:
        """The file's Header record (profile, library)."""
        try:
            opcode, length = struct.unpack("<BQ", self._read_at(len(MAGIC), 9))
            if opcode != Opcode.HEADER:
                raise ValueError(f"opcode {opcode:#x} where the Header record belongs")
            return Header.read(ReadDataStream(io.BytesIO(self._read_at(len(MAGIC) + 9,
                                                                       min(length, 1 << 20)))))
        except (McapError, ValueError, struct.error, UnicodeDecodeError) as exc:
            raise self._corrupt(len(MAGIC), f"unreadable header ({exc})") from None

    def definitions(self) -> tuple[dict[int, Schema], dict[int, Channel], list[Metadata]]:
        """Schemas and channels by id, and the metadata records, as found in the file."""
        schemas, channels = self._schemas_channels()
        return dict(schemas), {c.id: c for c in channels}, list(self._metadata)

    @property
    def message_end_ns(self) -> int | None:
        """[ns] the log time of the file's last message, from its summary's statistics; None
        without them (a truncated or damaged file, or one written without statistics)."""
        stats = self._summary.statistics if self._summary is not None else None
        if stats is None or not stats.message_count:
            return None
        return int(stats.message_end_time)

    @property
    def data_end(self) -> int:
        """[bytes] where the readable data section ends (the size of a complete file)."""
        return self._readable_end

    def records(self) -> Iterator[tuple[Channel, Message]]:
        """Every (channel, message record) in log-time order (file order on ties)."""
        return self._ordered(None)

    def channels(self) -> dict[str, ChannelInfo]:
        """Absolute topic name -> :class:`ChannelInfo` (type, encoding, channel metadata such
        as ``offered_qos_profiles``, message count when the summary has statistics)."""
        schemas, channels = self._schemas_channels()
        stats = self._summary.statistics if self._summary is not None else None
        counts = dict(stats.channel_message_counts) if stats is not None else {}
        return {c.topic: ChannelInfo(
                    topic=c.topic,
                    type_name=schemas[c.schema_id].name if c.schema_id in schemas else "",
                    encoding=c.message_encoding, metadata=dict(c.metadata),
                    message_count=counts.get(c.id),
                    schema=(schemas[c.schema_id].data.decode("utf-8", "replace")
                            if c.schema_id in schemas else ""))
                for c in channels}

    def raw_messages(self, topics: Iterable[str] | None = None
                     ) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, log_time [ns], serialized payload)`` in log-time order (file order on
        ties), without decoding: for CDR channels the payload is what a ROS publisher sends.
        ``topics``: absolute names to keep (default: all)."""
        wanted = None if topics is None else set(topics)
        for channel, record in self._ordered(wanted):
            yield channel.topic, record.log_time, record.data


@dataclass(frozen=True)
class ChannelInfo:
    """One channel of a log: ``topic`` (absolute), ``type_name`` (schema name, e.g.
    ``sensor_msgs/msg/JointState``; '' without schema), ``encoding`` ('cdr' for ROS 2),
    ``metadata`` (str -> str, e.g. ``offered_qos_profiles``), ``message_count`` (None when the
    file has no statistics)."""

    topic: str
    type_name: str
    encoding: str
    metadata: dict[str, str]
    message_count: int | None = None
    schema: str = ""
    """The type's definition as recorded (ros2msg text, dependencies concatenated), '' when
    the log has none."""
