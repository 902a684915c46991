"""The rod_sim log (docs/interface.md section 4): an MCAP file in the ROS 2 profile, as rosbag2 Jazzy writes it.

Layout: header (profile ``ros2``), a metadata record ``rod_sim`` (written first, so that even a
truncated log can be replayed), then zstd-compressed chunks of CDR messages (encoded by
:mod:`rod_sim.io.cdr`), then on :meth:`LogWriter.close` the summary (schemas, channels,
statistics, chunk indexes, metadata index) and message indexes. Schemas are ``ros2msg`` texts
from :mod:`rod_sim.io.msgdefs`; channels carry ``offered_qos_profiles`` (YAML, rosbag2 Jazzy
format) and ``topic_type_hash``; log_time = publish_time = the simulated time [ns].

Chunks are written and flushed to the OS as soon as they are full (:data:`CHUNK_SIZE`), so a
writer killed before ``close`` loses at most the last, unfinished chunk; :class:`LogReader`
then reads every complete chunk by scanning the file.
"""
from __future__ import annotations

import errno
import heapq
import io
import os
import struct
import sys
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk, get_chunk_data_stream
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2.decoder import DecoderFactory

from rod_sim import __version__
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import cdr, msgdefs, topics as topic_msgs
from rod_sim.io.crc_locate import locate_single_bit

METADATA_NAME = "rod_sim"
REQUIRED_METADATA = ("scene", "model", "integrator")
CHUNK_SIZE = 256 * 1024
"""[bytes] uncompressed size at which a chunk is closed and written (rosbag2's is 768 KiB)."""
MAGIC = b"\x89MCAP0\r\n"
PROFILE = "ros2"

RMW_DURATION_INFINITE = {"sec": 9223372036, "nsec": 854775807}
"""rmw's infinite duration, as rosbag2 Jazzy records the default deadline/lifespan/lease."""


class LogFormatError(ValueError):
    """A file is not a (readable) rod_sim MCAP log; ``str(err)`` is one line naming the file."""


class LogWriteError(ValueError):
    """A message cannot be written: unknown type, wrong fields, time going backwards, ..."""


def offered_qos_yaml(*, depth: int = 10, reliability: str = "reliable",
                     durability: str = "volatile", history: str = "keep_last") -> str:
    """``offered_qos_profiles`` channel metadata: a YAML list of one QoS mapping, as rosbag2
    Jazzy (metadata version 9, yaml-cpp block style) writes it for a publisher with these
    policies and default deadline, lifespan and liveliness."""
    def duration(name: str) -> list[str]:
        return [f"  {name}:", f"    sec: {RMW_DURATION_INFINITE['sec']}",
                f"    nsec: {RMW_DURATION_INFINITE['nsec']}"]

    lines = [f"- history: {history}", f"  depth: {int(depth)}",
             f"  reliability: {reliability}", f"  durability: {durability}",
             *duration("deadline"), *duration("lifespan"), "  liveliness: automatic",
             *duration("liveliness_lease_duration"), "  avoid_ros_namespace_conventions: false"]
    return "\n".join(lines)


class _FlushingFile(io.BufferedWriter):
    """Hands every write to the OS at once, so that complete chunks survive a killed process."""

    def write(self, data) -> int:  # type: ignore[override]
        count = super().write(data)
        self.flush()
        return count


class LogWriter:
    """Writes a rod_sim MCAP log; a context manager (``close`` runs on exit, even on errors).

    ``path``: the ``.mcap`` file; an existing file is refused (FileExistsError) unless
    ``overwrite``. ``metadata``: str -> str entries of the ``rod_sim`` record; ``scene`` (the
    resolved scene as YAML), ``model`` and ``integrator`` are required, ``version`` defaults to
    the rod_sim version. ``qos``: optional absolute topic -> ``offered_qos_profiles`` YAML
    (default :func:`offered_qos_yaml`). ``chunk_size`` [bytes], ``compression`` 'zstd', 'lz4'
    or 'none'.

    Messages of one topic must come with non-decreasing times (LogWriteError otherwise);
    different topics may interleave freely (readers sort by log time).
    """

    def __init__(self, path: str | os.PathLike, *, metadata: Mapping[str, str],
                 overwrite: bool = False, qos: Mapping[str, str] | None = None,
                 chunk_size: int = CHUNK_SIZE, compression: str = "zstd"):
        self.path = Path(path)
        record = {"version": __version__, **dict(metadata)}
        missing = [k for k in REQUIRED_METADATA if k not in record]
        if missing:
            raise ValueError(f"log metadata is missing {', '.join(missing)}")
        bad = [k for k, v in record.items() if not isinstance(k, str) or not isinstance(v, str)]
        if bad:
            raise TypeError(f"log metadata keys and values must be str (bad: {', '.join(map(str, bad))})")
        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                 "none": CompressionType.NONE}
        if compression not in kinds:
            raise ValueError(f"compression must be one of {', '.join(kinds)} (got {compression!r})")
        if chunk_size <= 0:
            raise ValueError(f"chunk_size must be > 0 bytes (got {chunk_size})")
        self._qos = dict(qos or {})
        try:
            raw = open(self.path, "wb" if overwrite else "xb", buffering=0)
        except FileExistsError:
            raise FileExistsError(errno.EEXIST, f"refusing to overwrite the existing log {self.path} "
                                  "(remove it or pass overwrite=True)", str(self.path)) from None
        self._file = _FlushingFile(raw)
        try:
            self._writer = McapWriter(self._file, chunk_size=chunk_size,
                                      compression=kinds[compression], enable_data_crcs=True)
            self._writer.start(profile=PROFILE, library=f"rod_sim/{__version__}")
            self._writer.add_metadata(METADATA_NAME, record)
        except BaseException:
            self._file.close()
            raise
        self._schemas: dict[str, int] = {}
        self._encoders: dict[str, Any] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self._last_ns: dict[str, int] = {}
        self._sequence: dict[str, int] = {}
        self._closed = False
        self._broken = False        # a write to the file failed

    # ----- writing -----

    def _channel(self, topic: str, type_name: str) -> int:
        if topic in self._channels:
            channel_id, known = self._channels[topic]
            if known != type_name:
                raise LogWriteError(f"{topic}: already logged as {known}, not {type_name}")
            return channel_id
        if not topic.startswith("/"):
            raise LogWriteError(f"topic names in logs are absolute (got {topic!r})")
        if type_name not in msgdefs.SCHEMAS:
            raise LogWriteError(f"{topic}: no schema for type {type_name!r} "
                                f"(known: {', '.join(msgdefs.SCHEMAS)})")
        if type_name not in self._schemas:
            text = msgdefs.SCHEMAS[type_name]
            self._schemas[type_name] = self._writer.register_schema(
                type_name, "ros2msg", text.encode("utf-8"))
            self._encoders[type_name] = cdr.encoder(type_name)
        channel_id = self._writer.register_channel(
            topic=topic, message_encoding="cdr", schema_id=self._schemas[type_name],
            metadata={"offered_qos_profiles": self._qos.get(topic, offered_qos_yaml()),
                      "topic_type_hash": msgdefs.TYPE_HASHES[type_name]})
        self._channels[topic] = (channel_id, type_name)
        self._sequence[topic] = 0
        return channel_id

    def write(self, topic: str, type_name: str, t_ns: int, msg: Mapping[str, Any]) -> None:
        """Log ``msg`` (nested dicts/lists) on the absolute ``topic`` at ``t_ns`` [ns] (used for
        both log_time and publish_time). Raises LogWriteError for an unknown type, a field the
        type does not have, a negative time or a time before the topic's previous message."""
        if self._closed:
            raise LogWriteError(f"{self.path} is closed")
        if isinstance(t_ns, bool) or not isinstance(t_ns, (int, np.integer)) or t_ns < 0:
            raise LogWriteError(f"{topic}: t_ns must be an integer >= 0 (got {t_ns!r})")
        t_ns = int(t_ns)
        channel_id = self._channel(topic, type_name)
        if t_ns < self._last_ns.get(topic, 0):
            raise LogWriteError(f"{topic}: time goes backwards ({t_ns} ns after "
                                f"{self._last_ns[topic]} ns)")
        try:
            data = self._encoders[type_name](msg)  # also rejects fields the type lacks
        except (ValueError, TypeError, KeyError, AttributeError, struct.error,
                NotImplementedError) as exc:
            raise LogWriteError(f"{topic}: cannot encode {type_name}: {exc}") from exc
        self._sequence[topic] += 1
        self._last_ns[topic] = t_ns
        try:
            self._writer.add_message(channel_id=channel_id, log_time=t_ns, publish_time=t_ns,
                                     sequence=self._sequence[topic], data=data)
        except OSError:
            self._broken = True     # the file ends at its last complete chunk: keep it so
            raise

    def write_snapshot(self, snapshot: Snapshot, scene: Scene, frame_id: str = "world",
                       topics: Iterable[str] | None = None) -> None:
        """Log the messages of :func:`rod_sim.io.topics.snapshot_messages` at ``snapshot.t``,
        on absolute topics (``/rod_states``, ...)."""
        t_ns = topic_msgs.time_ns(snapshot.t)
        for name, msg in topic_msgs.snapshot_messages(snapshot, scene, frame_id, topics).items():
            self.write("/" + name, topic_msgs.TOPIC_TYPES[name], t_ns, msg)

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Write the last chunk, the summary and the footer, and close the file (idempotent).
        After a failed write (e.g. a full disk) nothing more is written: the file ends with
        its last complete chunk, as after a killed writer, and readers scan it (a data-end
        record written now would carry a CRC over bytes that never reached the file)."""
        if self._closed:
            return
        self._closed = True
        if self._broken:
            try:
                self._file.close()
            except OSError:         # the failed write's bytes may still be buffered
                pass
            return
        try:
            self._writer.finish()
        except OSError:
            self._broken = True
            raise
        finally:
            try:
                self._file.close()
            except OSError:
                if not self._broken:
                    raise

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()


# ----- reading -----

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
            self._check_data_section()
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
            pos = end
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

    def resolve(self, names: Iterable[str], namespace: str | None = None) -> dict[str, str]:
        """The logged topic of each base name in ``names`` (e.g. ``rod_states``): see
        :func:`resolve_topics`. Raises LogFormatError when two namespaces hold them."""
        return resolve_topics(self.topics(), names, namespace, str(self.path))

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
                decoder = factory.decoder_for(channel.message_encoding,
                                              schemas.get(channel.schema_id))
                if decoder is None:
                    raise LogFormatError(f"{self.path}: cannot decode {channel.topic} "
                                         f"({channel.message_encoding})")
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
                    message_count=counts.get(c.id))
                for c in channels}

    def raw_messages(self, topics: Iterable[str] | None = None
                     ) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, log_time [ns], serialized payload)`` in log-time order (file order on
        ties), without decoding: for CDR channels the payload is what a ROS publisher sends.
        ``topics``: absolute names to keep (default: all)."""
        wanted = None if topics is None else set(topics)
        for channel, record in self._ordered(wanted):
            yield channel.topic, record.log_time, record.data


def base_name(topic: str) -> str:
    """The last component of a topic name: ``/arm1/rod_states`` -> ``rod_states``."""
    return topic.rstrip("/").rsplit("/", 1)[-1]


def namespace_of(topic: str) -> str:
    """The namespace of an absolute topic: ``/arm1/rod_states`` -> ``/arm1``, ``/x`` -> ``/``."""
    ns = topic.rstrip("/").rsplit("/", 1)[0]
    return ns or "/"


def resolve_topics(available: Iterable[str], names: Iterable[str], namespace: str | None = None,
                   where: str = "the log") -> dict[str, str]:
    """Map base topic names (``rod_states``, ``/rod_states``) to the absolute topics of
    ``available`` that end in them under any namespace (a node started with ``-r __ns:=/arm1``
    records ``/arm1/rod_states``). ``namespace`` (e.g. ``/arm1``) picks one namespace. Names
    not found are left out. Raises LogFormatError when the names are found under more than one
    namespace and none was chosen (two nodes recorded in one log)."""
    available = list(available)
    bases = [base_name(n) for n in names]
    if namespace is not None:
        ns = "/" + namespace.strip("/")
        prefix = ns if ns != "/" else ""
        return {b: prefix + "/" + b for b in bases if prefix + "/" + b in available}
    found: dict[str, list[str]] = {b: sorted(t for t in available if base_name(t) == b)
                                   for b in bases}
    spaces = sorted({namespace_of(t) for ts in found.values() for t in ts})
    if len(spaces) > 1:
        raise LogFormatError(f"{where} holds our topics under {len(spaces)} namespaces "
                             f"({', '.join(spaces[:6])}); choose one with --namespace NS")
    return {b: ts[0] for b, ts in found.items() if ts}


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


def _joint_series(path, topic: str, prefix: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    times, position, velocity = [], [], []
    names = None
    with LogReader(path) as reader:
        topic = reader.resolve([topic]).get(base_name(topic), topic)
        for _, t_ns, msg in reader.messages([topic]):
            if names is None:
                names = list(msg.name)
                expected = [f"{prefix}{k}" for k in range(1, len(names) + 1)]
                if names != expected:
                    raise LogFormatError(f"{path}: {topic} names {names} are not {prefix}1..")
            elif list(msg.name) != names:
                raise LogFormatError(f"{path}: {topic} changes its joint names at {t_ns} ns")
            times.append(t_ns)
            position.append(list(msg.position))
            velocity.append(list(msg.velocity))
    if not times:
        raise LogFormatError(f"{path} has no {topic} messages")
    return (np.asarray(times, dtype=np.int64) / 1e9, np.asarray(position, dtype=float),
            np.asarray(velocity, dtype=float))


def read_rod_states(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t (N,) [s], phi (N, n) [rad], phi_rate (N, n) [rad/s])`` from the ``rod_states`` topic
    of a log (complete or truncated; under any one namespace). Raises LogFormatError if it has
    none."""
    return _joint_series(path, "/rod_states", "rod_")


def read_applied_forces(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(t (N,) [s], forces (N, n, 2) [N])`` from ``/applied_forces`` (rows X_k, Y_k).
    Raises LogFormatError if the log has none or a message is not of even length."""
    times, forces = [], []
    with LogReader(path) as reader:
        topic = reader.resolve(["applied_forces"]).get("applied_forces", "/applied_forces")
        for _, t_ns, msg in reader.messages([topic]):
            data = np.asarray(msg.data, dtype=float)
            if data.size % 2:
                raise LogFormatError(f"{path}: /applied_forces at {t_ns} ns has odd length {data.size}")
            times.append(t_ns)
            forces.append(data.reshape(-1, 2))
    if not times:
        raise LogFormatError(f"{path} has no /applied_forces messages")
    if len({f.shape for f in forces}) != 1:
        raise LogFormatError(f"{path}: /applied_forces changes length")
    return np.asarray(times, dtype=np.int64) / 1e9, np.stack(forces)
