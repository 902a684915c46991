"""Rewrite a truncated MCAP log (a writer killed before ``close``, e.g. by SIGKILL) as a
complete one: the same header, metadata, schemas, channels and every message of its complete
chunks, then a summary (statistics, chunk and metadata indexes) and message indexes, so that
readers that need the summary (rosbags, ``ros2 bag``) open it. Like ``mcap recover``.

The source is opened by :func:`rod_sim.io.log_open.open_mcap` (a
:class:`~rod_sim.io.log_reader.LogReader`), so a corrupt source (a CRC mismatch) is refused,
never copied; the incomplete last record is dropped. Memory: the chunks
whose time ranges overlap, independent of the log length.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from rod_sim.io.log_format import CHUNK_SIZE
from rod_sim.io.log_open import open_mcap
from rod_sim.io.log_reader import LogReader


@dataclass(frozen=True)
class RepairResult:
    """What :func:`repair_log` wrote: ``messages``, ``channels``, ``metadata`` records,
    ``first_ns``/``last_ns`` (log times, None without messages), ``dropped_bytes`` (the
    incomplete tail of the source) and whether the source was already ``complete``."""

    messages: int
    channels: int
    metadata: int
    first_ns: int | None
    last_ns: int | None
    dropped_bytes: int
    complete: bool


def repair_log(src: str | os.PathLike, dst: str | os.PathLike) -> RepairResult:
    """Write the readable content of ``src`` to the new file ``dst`` (FileExistsError if it
    exists) as a complete MCAP file. Raises LogFormatError for a source that is not MCAP or is
    corrupt; on any error a partly written ``dst`` is removed."""
    dst = Path(dst)
    with open_mcap(src) as reader, open(dst, "xb") as out:
        try:
            result = _copy(reader, out)
        except BaseException:
            out.close()
            dst.unlink(missing_ok=True)
            raise
    return result


def _copy(reader: LogReader, out) -> RepairResult:
    header = reader.header()
    schemas, channels, metadata = reader.definitions()
    writer = McapWriter(out, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD,
                        enable_data_crcs=True)
    writer.start(profile=header.profile, library=header.library)
    for record in metadata:
        writer.add_metadata(record.name, dict(record.metadata))
    schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data)
                  for sid, s in schemas.items()}
    channel_ids = {}
    for cid, c in channels.items():
        channel_ids[cid] = writer.register_channel(
            topic=c.topic, message_encoding=c.message_encoding,
            schema_id=schema_ids.get(c.schema_id, 0), metadata=dict(c.metadata))
    count, first, last = 0, None, None
    for channel, message in reader.records():
        writer.add_message(channel_id=channel_ids[channel.id], log_time=message.log_time,
                           publish_time=message.publish_time, sequence=message.sequence,
                           data=message.data)
        count += 1
        first = message.log_time if first is None else first
        last = message.log_time
    writer.finish()
    out.flush()
    os.fsync(out.fileno())
    return RepairResult(messages=count, channels=len(channels), metadata=len(metadata),
                        first_ns=first, last_ns=last,
                        dropped_bytes=reader._size - reader.data_end, complete=reader.complete)
