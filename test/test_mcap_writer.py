"""rod_sim.io.mcap_writer writes the file mcap's own writer writes, byte for byte.

The oracle is ``mcap.writer.Writer`` with the options LogWriter uses (chunked, every index,
repeated schemas and channels, statistics, summary offsets, chunk and data-section CRCs), fed
the same call sequence: random interleavings of channels, payload sizes from empty to
larger than a chunk, equal and out-of-order times across channels, every compression.
"""
from __future__ import annotations

import io

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from rod_sim.io.mcap_writer import ChunkedMcapWriter

KINDS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}


def script(seed: int, messages: int, jitter: bool = False) -> list[tuple]:
    """A call sequence: ('schema', ...), ('channel', ...), ('message', ...), ('metadata', ...)."""
    rng = np.random.default_rng(seed)
    calls: list[tuple] = [("metadata", "rod_sim", {"scene": "a: 1", "model": "reduced"})]
    channels = 0
    times: dict[int, int] = {}
    for k in range(messages):
        if channels == 0 or rng.random() < 0.02:
            calls.append(("schema", f"pkg/msg/T{channels}", "ros2msg", f"float64 x{k}".encode()))
            calls.append(("channel", f"/topic_{channels}", "cdr", channels + 1,
                          {"offered_qos_profiles": "- depth: 1", "n": str(k)}))
            channels += 1
        ch = int(rng.integers(1, channels + 1))
        t = times.get(ch, int(rng.integers(0, 10**6))) + int(rng.integers(0, 3)) * 1000
        if jitter:          # any order, even within a channel: the writer does not sort
            t = 5000 + int(rng.integers(-3, 4))
        times[ch] = t
        size = int(rng.choice([0, 1, 7, 100, 5000, 70000]))
        data = rng.integers(0, 4, size, dtype=np.uint8).tobytes()   # compressible
        calls.append(("message", ch, t, data, t + 5, k % 70000))
    return calls


def play(writer, calls) -> None:
    writer.start(profile="ros2", library="rod_sim/test")
    for call in calls:
        kind, args = call[0], call[1:]
        if kind == "metadata":
            writer.add_metadata(*args)
        elif kind == "schema":
            writer.register_schema(*args)
        elif kind == "channel":
            writer.register_channel(topic=args[0], message_encoding=args[1],
                                    schema_id=args[2], metadata=args[3])
        else:
            ch, t, data, pub, seq = args
            writer.add_message(channel_id=ch, log_time=t, data=data, publish_time=pub,
                               sequence=seq)
    writer.finish()


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("seed,messages,chunk_size", [(1, 400, 64 * 1024), (2, 60, 1000),
                                                      (3, 1, 256 * 1024), (4, 0, 1024)])
def test_same_bytes_as_mcap_writer(compression, seed, messages, chunk_size):
    calls = script(seed, messages)
    if messages == 0:       # a log with metadata and a channel but no message
        calls += [("schema", "a/msg/B", "ros2msg", b"int8 b"), ("channel", "/b", "cdr", 1, {})]
    theirs, ours = io.BytesIO(), io.BytesIO()
    play(Writer(theirs, chunk_size=chunk_size, compression=KINDS[compression],
                enable_data_crcs=True), calls)
    play(ChunkedMcapWriter(ours, chunk_size=chunk_size, compression=compression), calls)
    assert ours.getvalue() == theirs.getvalue()
    # and mcap's reader, validating every CRC, reads the messages back in order
    sent = [c for c in calls if c[0] == "message"]
    ours.seek(0)
    reader = make_reader(ours, validate_crcs=True)
    read = [(m.channel_id, m.log_time, m.data, m.publish_time, m.sequence)
            for _, _, m in reader.iter_messages(log_time_order=False)]
    assert read == [c[1:] for c in sent]


@pytest.mark.parametrize("chunk_size", range(150, 420, 7))
def test_chunks_close_at_the_same_size(chunk_size):
    """Small messages against many chunk sizes: some chunks end exactly at chunk_size."""
    calls = script(5, 40, jitter=True)
    calls = [c if c[0] != "message" else c[:3] + (c[3][:12],) + c[4:] for c in calls]
    theirs, ours = io.BytesIO(), io.BytesIO()
    play(Writer(theirs, chunk_size=chunk_size, enable_data_crcs=True), calls)
    play(ChunkedMcapWriter(ours, chunk_size=chunk_size, compression="zstd"), calls)
    assert ours.getvalue() == theirs.getvalue()


def test_unknown_compression_is_refused():
    with pytest.raises(ValueError, match="compression must be one of"):
        ChunkedMcapWriter(io.BytesIO(), chunk_size=1024, compression="gzip")
