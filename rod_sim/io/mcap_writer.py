"""A chunked MCAP writer with a cheap per-message path: the file ``mcap.writer.Writer`` writes,
byte for byte, for the same calls.

``mcap.writer.Writer`` (mcap 1.x, pure Python) builds each message record through a dataclass
and a dozen small stream writes and struct packs: ~5 us of CPU per message back to back, more
in a node that waits between periods. This writer appends one packed record header and the
payload to the open chunk (a ``bytearray``) and keeps the chunk's message index as flat lists
(~1 us); rare records (header, metadata, schemas, channels, the summary) are written by mcap's
own record classes. The file's bytes are produced by a :class:`ChunkSink` (compression, CRCs,
offsets, indexes, summary): here, or in a process of its own (:mod:`rod_sim.io.log_process`).
The options are those :class:`rod_sim.io.log_writer.LogWriter` uses: chunked, every index,
schemas and channels repeated in the summary, statistics, summary offsets, CRCs of the chunks,
the data section and the summary. ``test/test_mcap_writer.py`` checks the identity against
``mcap.writer.Writer`` on the same call sequences.
"""
from __future__ import annotations

import errno
import struct
import zlib
from typing import IO, Protocol

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, ChunkIndex, DataEnd, Footer, Header, Metadata,
                          MetadataIndex, Schema, Statistics, SummaryOffset)

MAGIC = b"\x89MCAP0\r\n"
COMPRESSIONS = ("zstd", "lz4", "none")

_MESSAGE = struct.Struct("<BQHIQQ")        # opcode, length, channel, sequence, log, publish
_MESSAGE_FIXED = 2 + 4 + 8 + 8
_CHUNK_HEAD = struct.Struct("<BQQQQI")      # opcode, length, start, end, size, crc
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_INDEX_HEAD = struct.Struct("<BQHI")       # opcode, length, channel, byte length of entries


def _compressor(compression: str):
    """bytes -> bytes of the chunk's compression, as mcap's writer compresses (zstd level 3
    with the content size in the frame, lz4 frames with lz4's defaults)."""
    if compression == "zstd":
        import zstandard
        return zstandard.ZstdCompressor(level=3).compress
    if compression == "lz4":
        import lz4.frame
        return lz4.frame.compress
    if compression == "none":
        return bytes
    raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)} (got {compression!r})")


class ChunkSink:
    """The writing half: compresses closed chunks and writes every byte of the file to
    ``stream`` (a binary file object, written in whole records and never seeked), keeping the
    offsets, the CRC of the data section and the chunk and metadata indexes for the summary.
    ``compression``: 'zstd', 'lz4' or 'none'."""

    def __init__(self, stream: IO[bytes], compression: str = "zstd"):
        self._stream = stream
        self._compress = _compressor(compression)
        self._compression = "" if compression == "none" else compression
        self._pos = 0                       # bytes written to stream
        self._data_crc = 0                  # CRC-32 of the data section written so far
        self._metadata_indexes: list[MetadataIndex] = []
        self._chunk_indexes: list[ChunkIndex] = []

    def _write(self, data: bytes) -> None:
        """Data-section bytes: counted in its CRC, then written whole."""
        if data:
            self._data_crc = zlib.crc32(data, self._data_crc)
            self._put(data)

    def _put(self, data: bytes) -> None:
        """Every byte of ``data`` to the stream: a raw file may take part of a write (a disk
        filling up takes what fits, and the next write raises its error)."""
        view, done = memoryview(data), 0
        while done < len(view):
            count = self._stream.write(view[done:])
            if count is None or count <= 0:             # not a blocking regular file
                raise OSError(errno.EIO, f"the log took {count!r} of {len(view) - done} bytes")
            done += count
        self._pos += len(view)

    def write_start(self, header: bytes) -> None:
        """The magic and the header record (its bytes)."""
        self._write(MAGIC)
        self._write(header)

    def write_metadata(self, name: str, record: bytes) -> None:
        """A metadata record (its bytes) named ``name``, indexed."""
        self._metadata_indexes.append(MetadataIndex(offset=self._pos, length=len(record),
                                                    name=name))
        self._write(record)

    def write_chunk(self, raw: bytes | bytearray, index: dict[int, list[int]], start: int,
                    end: int) -> None:
        """One chunk: its records uncompressed (``raw``), its message index (channel ->
        [log_time, offset, ...]) and message times [ns]; written with its message indexes in
        one write."""
        packed = self._compress(raw)
        name = self._compression.encode()
        length = 8 + 8 + 8 + 4 + 4 + len(name) + 8 + len(packed)
        record = b"".join((
            _CHUNK_HEAD.pack(Opcode.CHUNK, length, start, end, len(raw), zlib.crc32(raw)),
            _U32.pack(len(name)), name, _U64.pack(len(packed)), packed))
        chunk_offset = self._pos
        index_start = chunk_offset + len(record)
        offsets = {}
        parts = [record]
        at = index_start
        for channel_id, flat in index.items():
            offsets[channel_id] = at
            size = 8 * len(flat)
            part = _INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 2 + 4 + size, channel_id, size) \
                + struct.pack(f"<{len(flat)}Q", *flat)
            parts.append(part)
            at += len(part)
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end,
            chunk_start_offset=chunk_offset, chunk_length=len(record),
            message_index_offsets=offsets, message_index_length=at - index_start,
            compression=self._compression, compressed_size=len(packed),
            uncompressed_size=len(raw)))
        self._write(b"".join(parts))

    def write_end(self, schemas: list[Schema], channels: list[Channel],
                  statistics: dict) -> None:
        """The data end, the summary, the footer and the closing magic. ``statistics``: the
        fields of mcap's Statistics record but the chunk count (this sink's)."""
        self._write(_record(DataEnd(self._data_crc)))
        summary_start = self._pos
        builder = RecordBuilder()
        offsets = []

        def group(opcode, records) -> None:
            start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + start,
                                         group_length=builder.count - start))

        group(Opcode.SCHEMA, schemas)
        group(Opcode.CHANNEL, channels)
        group(Opcode.STATISTICS, [Statistics(chunk_count=len(self._chunk_indexes),
                                             **statistics)])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.ATTACHMENT_INDEX, [])
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start,
                                     offset_start), zlib.crc32(summary))
        tail = summary + _record(Footer(summary_start=summary_start,
                                        summary_offset_start=offset_start,
                                        summary_crc=crc)) + MAGIC
        self._put(tail)


class Sink(Protocol):
    """What :class:`ChunkedMcapWriter` writes through: a :class:`ChunkSink` or a proxy of one
    in another process (:class:`rod_sim.io.log_process.ProcessSink`). ``write_chunk`` gets
    ``raw`` as a view of the writer's chunk buffer, which is written again after the call:
    a sink uses (or copies) it before it returns and keeps no reference to it."""

    def write_start(self, header: bytes) -> None: ...
    def write_metadata(self, name: str, record: bytes) -> None: ...
    def write_chunk(self, raw, index: dict[int, list[int]], start: int, end: int) -> None: ...
    def write_end(self, schemas: list, channels: list, statistics: dict) -> None: ...


def _record(record) -> bytes:
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()


class ChunkedMcapWriter:
    """Writes one MCAP file to ``stream`` (a binary file object, written in whole records and
    never seeked), or through ``sink`` (then ``stream`` and ``compression`` are the sink's).
    ``chunk_size`` [bytes]: a chunk is closed once its uncompressed records exceed it;
    ``compression``: 'zstd', 'lz4' or 'none'.

    Call order as for ``mcap.writer.Writer``: :meth:`start`, then metadata, schemas, channels
    and messages, then :meth:`finish` (which does not close ``stream``)."""

    def __init__(self, stream: IO[bytes] | None = None, *, chunk_size: int,
                 compression: str = "zstd", sink: Sink | None = None):
        self._sink = ChunkSink(stream, compression) if sink is None else sink
        self._chunk_size = chunk_size
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._metadata_count = 0
        self._counts: dict[int, int] = {}   # channel -> messages, in order of first message
        self._message_count = 0
        self._start_time = 0
        self._end_time = 0
        self._buffer = bytearray(2 * chunk_size + (1 << 16))
        """The open chunk's records, uncompressed: its first ``_used`` bytes. One buffer,
        written again for every chunk (grown only for a record larger than its free
        space): a new bytearray per chunk, grown by each record, cost 75 us per 1 kHz
        period at n = 1024 (~176 KB of messages in six records) against 8.5 us for the
        appends alone, and recording such a period through the writer process cost 102-105
        against 84-87 us of the main process's CPU (2026-11-27, 3 alternating pairs)."""
        self._view = memoryview(self._buffer)
        self._used = 0
        self._index: dict[int, list[int]] = {}  # channel -> [log_time, offset, ...] in the chunk
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0

    def start(self, profile: str = "", library: str = "") -> None:
        self._sink.write_start(_record(Header(profile, library)))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._metadata_count += 1
        self._sink.write_metadata(name, _record(Metadata(name=name, metadata=data)))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """The new schema's id (1, 2, ...); its record goes into the open chunk (which is
        then closed if it is full and holds a message)."""
        schema = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas.append(schema)
        self._add_record(_record(schema))
        return schema.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str]) -> int:
        """The new channel's id (1, 2, ...); its record goes into the open chunk, as a
        schema's."""
        channel = Channel(id=len(self._channels) + 1, topic=topic,
                          message_encoding=message_encoding, schema_id=schema_id,
                          metadata=metadata)
        self._channels.append(channel)
        self._add_record(_record(channel))
        return channel.id

    def _room(self, size: int) -> int:
        """The buffer's offset where ``size`` more bytes of the open chunk go (the buffer
        grows, its bytes kept, for a record larger than its free space)."""
        used = self._used
        if used + size > len(self._buffer):
            bigger = bytearray(max(used + size, 2 * len(self._buffer)))
            bigger[:used] = self._view[:used]
            self._view.release()
            self._buffer, self._view = bigger, memoryview(bigger)
        return used

    def _add_record(self, record: bytes) -> None:
        at = self._room(len(record))
        self._used = end = at + len(record)
        self._view[at:end] = record
        if end > self._chunk_size:
            self._finish_chunk()

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int = 0) -> None:
        """Append one message record (times [ns]) to the open chunk; closes the chunk once it
        exceeds ``chunk_size``. The file's and the chunk's time spans are kept inline, one
        after the other (a helper call per message would cost more than the rest)."""
        if self._message_count:
            if log_time < self._start_time:
                self._start_time = log_time
        else:
            self._start_time = log_time
        if log_time > self._end_time:
            self._end_time = log_time
        self._message_count += 1
        counts = self._counts
        counts[channel_id] = counts.get(channel_id, 0) + 1
        if self._chunk_messages:
            if log_time < self._chunk_start:
                self._chunk_start = log_time
        else:
            self._chunk_start = log_time
        if log_time > self._chunk_end:
            self._chunk_end = log_time
        self._chunk_messages += 1
        index = self._index.get(channel_id)
        if index is None:
            index = self._index[channel_id] = []
        at = self._room(_MESSAGE.size + len(data))
        index += (log_time, at)
        _MESSAGE.pack_into(self._buffer, at, Opcode.MESSAGE, _MESSAGE_FIXED + len(data),
                           channel_id, sequence, log_time, publish_time)
        body = at + _MESSAGE.size
        self._used = end = body + len(data)
        self._view[body:end] = data
        if end > self._chunk_size:
            self._finish_chunk()

    def _finish_chunk(self) -> None:
        """Hand the open chunk to the sink, if it holds a message, and open a new one."""
        if not self._chunk_messages:
            return
        raw, index = self._view[:self._used], self._index
        self._used = 0
        self._index = {}
        self._chunk_messages = 0
        start, end = self._chunk_start, self._chunk_end
        self._chunk_start = self._chunk_end = 0
        with raw:       # the sink uses the bytes during the call (Sink)
            self._sink.write_chunk(raw, index, start, end)

    def finish(self) -> None:
        """Write the last chunk, the data end, the summary, the footer and the closing magic."""
        self._finish_chunk()
        self._sink.write_end(self._schemas, self._channels, dict(
            attachment_count=0, channel_count=len(self._channels),
            channel_message_counts=self._counts, message_count=self._message_count,
            metadata_count=self._metadata_count, message_start_time=self._start_time,
            message_end_time=self._end_time, schema_count=len(self._schemas)))
