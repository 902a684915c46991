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
import io
import os
import struct
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
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2.decoder import DecoderFactory

from rod_sim import __version__
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import cdr, msgdefs, topics as topic_msgs

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
                                      compression=kinds[compression])
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
        self._writer.add_message(channel_id=channel_id, log_time=t_ns, publish_time=t_ns,
                                 sequence=self._sequence[topic], data=data)

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
        """Write the last chunk, the summary and the footer, and close the file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()

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


class LogReader:
    """Reads an MCAP log (rod_sim's or any ROS 2 one); a context manager.

    Uses the summary and indexes of a complete file; when they are missing or unreadable (a
    writer killed before ``close``) it scans the file from the start and stops at the first
    incomplete record. Raises :class:`LogFormatError` for a file that is not MCAP.

    Attributes: ``complete`` is True when the file has its summary and indexes (it was closed
    cleanly); ``truncated`` becomes True once a scan has met an incomplete last record.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._file = open(self.path, "rb")
        try:
            self._size = self._file.seek(0, io.SEEK_END)
            self._file.seek(0)
            if self._file.read(len(MAGIC)) != MAGIC:
                raise LogFormatError(f"{self.path} is not an MCAP file (bad magic)")
            self._file.seek(0)
            self._reader = make_reader(self._file, decoder_factories=[DecoderFactory()])
            self._summary = self._read_summary()
        except BaseException:
            self._file.close()
            raise
        self.complete = self._summary is not None
        self.truncated = False

    def _read_summary(self):
        if self._size < 2 * len(MAGIC) + 29:
            return None
        self._file.seek(-len(MAGIC), io.SEEK_END)
        if self._file.read(len(MAGIC)) != MAGIC:
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

    # ----- linear scan, for files without a summary -----

    def _scan(self) -> Iterator[Any]:
        """Records in file order (chunks broken up), up to the first incomplete record."""
        f, size, pos = self._file, self._size, len(MAGIC)
        while pos < size:
            if pos + 9 > size:
                self.truncated = True
                return
            f.seek(pos)
            opcode, length = struct.unpack("<BQ", f.read(9))
            end = pos + 9 + length
            if end > size:
                self.truncated = True
                return
            if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                return
            reader = _RECORD_READERS.get(opcode)
            if opcode == Opcode.MESSAGE or reader is not None:
                body = f.read(length)
                try:
                    stream = ReadDataStream(io.BytesIO(body))
                    record = (Message.read(stream, length) if opcode == Opcode.MESSAGE
                              else reader(stream))
                    records = (breakup_chunk(record, validate_crc=True)
                               if isinstance(record, Chunk) else [record])
                except Exception as exc:  # noqa: BLE001 - any decoding failure is corruption
                    raise LogFormatError(f"{self.path}: corrupt record (opcode {opcode:#x}) at "
                                         f"byte {pos}: {exc}") from exc
                yield from records
            pos = end

    # ----- queries -----

    def metadata(self, name: str = METADATA_NAME) -> dict[str, str]:
        """The metadata record ``name`` (default ``rod_sim``): its str -> str entries.

        Raises LogFormatError when the log has none.
        """
        try:
            if self._summary is not None:
                records = self._reader.iter_metadata()
            else:
                records = (r for r in self._scan() if isinstance(r, Metadata))
            for record in records:
                if record.name == name:
                    return dict(record.metadata)
        except McapError as exc:
            raise LogFormatError(f"{self.path}: cannot read metadata: {exc}") from exc
        if self.truncated:
            raise LogFormatError(f"{self.path} is truncated before its {name!r} metadata record")
        raise LogFormatError(f"{self.path} has no {name!r} metadata record (not a rod_sim log?)")

    def topics(self) -> dict[str, str]:
        """Absolute topic name -> ROS type name (e.g. ``'/rod_states': 'sensor_msgs/msg/JointState'``)."""
        if self._summary is not None:
            schemas, channels = self._summary.schemas, self._summary.channels.values()
        else:
            schemas, channels = {}, []
            for record in self._scan():
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels.append(record)
        return {c.topic: (schemas[c.schema_id].name if c.schema_id in schemas else "")
                for c in channels}

    def messages(self, topics: Iterable[str] | str | None = None
                 ) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log_time [ns], decoded message)`` in log-time order (file order on ties).

        ``topics``: absolute or relative names to keep (default: all). Decoded messages have
        the ROS field names as attributes. A file without summary is scanned; its raw payloads
        are then held in memory to be sorted.
        """
        wanted = None
        if topics is not None:
            names = [topics] if isinstance(topics, str) else list(topics)
            wanted = {t if t.startswith("/") else "/" + t for t in names}
        try:
            if self._summary is not None:
                for item in self._reader.iter_decoded_messages(topics=wanted, log_time_order=True):
                    yield item.channel.topic, item.message.log_time, item.decoded_message
            else:
                yield from self._scan_messages(wanted)
        except McapError as exc:
            raise LogFormatError(f"{self.path}: cannot decode messages: {exc}") from exc

    def _scan_messages(self, wanted: set[str] | None) -> Iterator[tuple[str, int, Any]]:
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        found: list[tuple[int, int, Message]] = []
        for record in self._scan():
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None:
                    raise LogFormatError(f"{self.path}: message on unknown channel {record.channel_id}")
                if wanted is None or channel.topic in wanted:
                    found.append((record.log_time, len(found), record))
        found.sort(key=lambda item: (item[0], item[1]))
        factory = DecoderFactory()
        decoders: dict[int, Any] = {}
        for log_time, _, record in found:
            channel = channels[record.channel_id]
            decoder = decoders.get(channel.id)
            if decoder is None:
                decoder = factory.decoder_for(channel.message_encoding, schemas.get(channel.schema_id))
                if decoder is None:
                    raise LogFormatError(f"{self.path}: cannot decode {channel.topic} "
                                         f"({channel.message_encoding})")
                decoders[channel.id] = decoder
            yield channel.topic, log_time, decoder(record.data)


    # ----- raw access, for players -----

    def channels(self) -> dict[str, ChannelInfo]:
        """Absolute topic name -> :class:`ChannelInfo` (type, encoding, channel metadata such
        as ``offered_qos_profiles``, message count when the summary has statistics)."""
        if self._summary is not None:
            schemas, channels = self._summary.schemas, list(self._summary.channels.values())
            stats = self._summary.statistics
            counts = dict(stats.channel_message_counts) if stats is not None else {}
        else:
            schemas, channels, counts = {}, [], {}
            for record in self._scan():
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels.append(record)
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
        ``topics``: absolute names to keep (default: all). A file without summary is scanned
        and its payloads are held in memory to be sorted."""
        wanted = None if topics is None else set(topics)
        try:
            if self._summary is not None:
                for _, channel, message in self._reader.iter_messages(
                        topics=wanted, log_time_order=True):
                    yield channel.topic, message.log_time, message.data
                return
            channels: dict[int, Channel] = {}
            found: list[tuple[int, int, str, bytes]] = []
            for record in self._scan():
                if isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    channel = channels.get(record.channel_id)
                    if channel is None:
                        raise LogFormatError(f"{self.path}: message on unknown channel "
                                             f"{record.channel_id}")
                    if wanted is None or channel.topic in wanted:
                        found.append((record.log_time, len(found), channel.topic, record.data))
            found.sort(key=lambda item: (item[0], item[1]))
            for log_time, _, topic, data in found:
                yield topic, log_time, data
        except McapError as exc:
            raise LogFormatError(f"{self.path}: cannot read messages: {exc}") from exc


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
    """``(t (N,) [s], phi (N, n) [rad], phi_rate (N, n) [rad/s])`` from the ``/rod_states`` of a
    log (complete or truncated). Raises LogFormatError if it has none."""
    return _joint_series(path, "/rod_states", "rod_")


def read_applied_forces(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(t (N,) [s], forces (N, n, 2) [N])`` from ``/applied_forces`` (rows X_k, Y_k).
    Raises LogFormatError if the log has none or a message is not of even length."""
    times, forces = [], []
    with LogReader(path) as reader:
        for _, t_ns, msg in reader.messages(["/applied_forces"]):
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
