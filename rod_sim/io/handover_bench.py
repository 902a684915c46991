"""CPU of handing a log's chunks to the writer process: through the shared ring or the pipe.

    python -m rod_sim.io.handover_bench [--rounds 7] [--chunks 40] [--gap-ms 1.0]

Two :class:`~rod_sim.io.log_process.ProcessSink` (zstd) on two temporary files: one with the
ring (:data:`~rod_sim.io.log_process.RING_BYTES`), one with ``ring_bytes=0`` (every chunk
through the pipe, as before the ring). Rounds alternate between them; a round hands over
``--chunks`` chunks of 256 KiB (eight different ones, float64 random walks: zstd packs them
to ~94 %, which costs the child, not the parent), each after ``--gap-ms`` of numpy work touching
3.2 MB (the node's period between two chunks: it evicts what the hand-over reads and writes,
as the physics does). Timed: the calling thread's CPU (``time.thread_time``) in
``write_chunk``; reported per chunk [us], the min and the median over the rounds of each
round's mean. Checked after timing: both files are the same bytes.
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

import numpy as np

from rod_sim.io.log_format import CHUNK_SIZE
from rod_sim.io.log_process import RING_BYTES, ProcessSink


def _chunks(count: int = 8) -> list[bytearray]:
    rng = np.random.default_rng(0)
    return [bytearray(np.cumsum(rng.normal(size=CHUNK_SIZE // 8) * 1e-3).tobytes())
            for _ in range(count)]


def _busy(work: np.ndarray, seconds: float) -> None:
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        np.sin(work, out=work)


def measure(rounds: int = 7, chunks: int = 40, gap_ms: float = 1.0) -> dict[str, list[float]]:
    """Per mode ('ring', 'pipe'): each round's mean CPU [us] per chunk handed over."""
    data = _chunks()
    index = {1: [v for k in range(60) for v in (k * 1000, 2100 * k)], 2: [0, 5]}
    work = np.random.default_rng(1).random(400_000)
    stats = dict(attachment_count=0, channel_count=0, channel_message_counts={},
                 message_count=0, metadata_count=0, message_start_time=0,
                 message_end_time=0, schema_count=0)
    result: dict[str, list[float]] = {"ring": [], "pipe": []}
    with tempfile.TemporaryDirectory() as tmp:
        paths = {mode: os.path.join(tmp, f"{mode}.mcap") for mode in result}
        fds = {mode: os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL)
               for mode, path in paths.items()}
        sinks = {mode: ProcessSink(fds[mode], "zstd", RING_BYTES if mode == "ring" else 0)
                 for mode in result}
        try:
            for sink in sinks.values():
                sink.write_start(b"")
            for _ in range(rounds):
                for mode, sink in sinks.items():
                    total = 0.0
                    for k in range(chunks):
                        _busy(work, gap_ms / 1e3)
                        start = time.thread_time()
                        sink.write_chunk(data[k % len(data)], index, k, k)
                        total += time.thread_time() - start
                    result[mode].append(total / chunks * 1e6)
            for sink in sinks.values():
                sink.write_end([], [], stats)
        finally:
            for mode in result:
                sinks[mode].close()
                os.close(fds[mode])
        with open(paths["ring"], "rb") as a, open(paths["pipe"], "rb") as b:
            if a.read() != b.read():
                raise RuntimeError("the ring and the pipe wrote different files")
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rod_sim.io.handover_bench",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=7)
    p.add_argument("--chunks", type=int, default=40, help="chunks per round")
    p.add_argument("--gap-ms", type=float, default=1.0,
                   help="[ms] numpy work before each chunk (the node's period)")
    args = p.parse_args(argv)
    if args.rounds < 1 or args.chunks < 1 or args.gap_ms < 0:
        p.error("--rounds and --chunks must be >= 1, --gap-ms >= 0")
    result = measure(args.rounds, args.chunks, args.gap_ms)
    for mode, rounds in result.items():
        print(f"{mode}: CPU per 256 KiB chunk handed over: min {min(rounds):.1f} us, median "
              f"{statistics.median(rounds):.1f} us ({args.rounds} rounds of {args.chunks}, "
              f"{args.gap_ms:g} ms of work between chunks)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
