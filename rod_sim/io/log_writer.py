"""Writing a rod_sim log (docs/interface.md section 4): an MCAP file in the ROS 2 profile, as
rosbag2 Jazzy writes it.

Layout: header (profile ``ros2``), a metadata record ``rod_sim`` (written first, so that even a
truncated log can be replayed), then zstd-compressed chunks of CDR messages (encoded by
:mod:`rod_sim.io.cdr`) each followed by its message indexes, then on :meth:`LogWriter.close`
the summary (schemas, channels, statistics, chunk indexes, metadata index). The MCAP records
are written by :mod:`rod_sim.io.mcap_writer` (the bytes ``mcap.writer.Writer`` writes, at a
fraction of its cost per message). Schemas are ``ros2msg`` texts
from :mod:`rod_sim.io.msgdefs`; channels carry ``offered_qos_profiles`` (YAML, rosbag2 Jazzy
format) and ``topic_type_hash``; log_time = publish_time = the simulated time [ns].

Chunks are written and flushed to the OS as soon as they are full
(:data:`~rod_sim.io.log_format.CHUNK_SIZE`), so a writer killed before ``close`` loses at most
the last, unfinished chunk; :class:`~rod_sim.io.log_reader.LogReader` then reads every complete
chunk by scanning the file.
"""
from __future__ import annotations

import errno
import io
import os
import struct
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rod_sim.version import __version__
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import cdr, encoders, msgdefs, topics as topic_msgs
from rod_sim.io.mcap_writer import COMPRESSIONS, ChunkedMcapWriter
from rod_sim.io.log_format import CHUNK_SIZE, METADATA_NAME, PROFILE, REQUIRED_METADATA

RMW_DURATION_INFINITE = {"sec": 9223372036, "nsec": 854775807}
"""rmw's infinite duration, as rosbag2 Jazzy records the default deadline/lifespan/lease."""


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
    or 'none'. ``writer_process``: chunks are compressed and written by a child process
    (:mod:`rod_sim.io.log_process`; the node records so), not by the calling thread; the file
    is the same, and a write error there is raised by a later call here.

    Messages of one topic must come with non-decreasing times (LogWriteError otherwise);
    different topics may interleave freely (readers sort by log time).
    """

    def __init__(self, path: str | os.PathLike, *, metadata: Mapping[str, str],
                 overwrite: bool = False, qos: Mapping[str, str] | None = None,
                 chunk_size: int = CHUNK_SIZE, compression: str = "zstd",
                 writer_process: bool = False):
        self.path = Path(path)
        record = {"version": __version__, **dict(metadata)}
        missing = [k for k in REQUIRED_METADATA if k not in record]
        if missing:
            raise ValueError(f"log metadata is missing {', '.join(missing)}")
        bad = [k for k, v in record.items() if not isinstance(k, str) or not isinstance(v, str)]
        if bad:
            raise TypeError(f"log metadata keys and values must be str (bad: {', '.join(map(str, bad))})")
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)} "
                             f"(got {compression!r})")
        if chunk_size <= 0:
            raise ValueError(f"chunk_size must be > 0 bytes (got {chunk_size})")
        self._qos = dict(qos or {})
        try:
            raw = open(self.path, "wb" if overwrite else "xb", buffering=0)
        except FileExistsError:
            raise FileExistsError(errno.EEXIST, f"refusing to overwrite the existing log {self.path} "
                                  "(remove it or pass overwrite=True)", str(self.path)) from None
        self._file = _FlushingFile(raw)
        self._sink = None
        try:
            if writer_process:
                from rod_sim.io.log_process import ProcessSink

                self._sink = ProcessSink(raw.fileno(), compression)
            self._writer = ChunkedMcapWriter(self._file, chunk_size=chunk_size,
                                             compression=compression, sink=self._sink)
            self._writer.start(profile=PROFILE, library=f"rod_sim/{__version__}")
            self._writer.add_metadata(METADATA_NAME, record)
        except BaseException:       # e.g. Ctrl-C while the writer process starts
            if self._sink is not None:
                self._sink.close()
            self._file.close()
            self.path.unlink(missing_ok=True)       # a log is whole or absent
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
        channel_id = self._check(topic, type_name, t_ns)
        encode = self._encoders.get(type_name)
        if encode is None:          # built on first use: write_cdr's topics need none
            encode = self._encoders[type_name] = cdr.encoder(type_name)
        try:
            data = encode(msg)  # also rejects fields the type lacks
        except (ValueError, TypeError, KeyError, AttributeError, struct.error,
                NotImplementedError) as exc:
            raise LogWriteError(f"{topic}: cannot encode {type_name}: {exc}") from exc
        self._add(topic, channel_id, int(t_ns), data)

    def write_cdr(self, topic: str, type_name: str, t_ns: int, data: bytes) -> None:
        """Log a message already encoded (CDR with its encapsulation header, e.g. by
        :mod:`rod_sim.io.encoders`: the bytes a node publishes) as :meth:`write` does."""
        channel_id = self._check(topic, type_name, t_ns)
        self._add(topic, channel_id, int(t_ns), data)

    def _check(self, topic: str, type_name: str, t_ns: int) -> int:
        """The channel of ``topic``; raises LogWriteError for a closed log or a bad time."""
        if self._closed:
            raise LogWriteError(f"{self.path} is closed")
        if isinstance(t_ns, bool) or not isinstance(t_ns, (int, np.integer)) or t_ns < 0:
            raise LogWriteError(f"{topic}: t_ns must be an integer >= 0 (got {t_ns!r})")
        channel_id = self._channel(topic, type_name)
        if t_ns < self._last_ns.get(topic, 0):
            raise LogWriteError(f"{topic}: time goes backwards ({t_ns} ns after "
                                f"{self._last_ns[topic]} ns)")
        return channel_id

    def _add(self, topic: str, channel_id: int, t_ns: int, data: bytes) -> None:
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
        on absolute topics (``/rod_states``, ...), encoded from numpy by
        :mod:`rod_sim.io.encoders` (the same bytes)."""
        t_ns = topic_msgs.time_ns(snapshot.t)
        for name, data in encoders.snapshot_bytes(snapshot, scene, frame_id, topics).items():
            self.write_cdr("/" + name, topic_msgs.TOPIC_TYPES[name], t_ns, data)

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
            if self._sink is not None:
                self._sink.close()      # it has written every chunk it was given
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
