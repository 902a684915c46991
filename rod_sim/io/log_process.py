"""A log's compression and file writes in a process of their own.

At n = 1024 and 1 kHz a node records ~200 KB of messages per period: compressing and
checksumming them (~0.3 ms per period) is what separates its period from real time. A thread
did not help (measured: the same real-time factor at 20 % more CPU; why is not established), a
process did (docs/bench.md): :class:`ProcessSink` hands each closed chunk (its bytes and
message index) to ``python -m rod_sim.io.log_process``, which runs a
:class:`~rod_sim.io.mcap_writer.ChunkSink` on the log file (the file descriptor is inherited,
opened by the caller). The file is the same, byte for byte.

The hand-over. A chunk's bytes (256 KiB) go into a ring of shared memory (:data:`RING_BYTES`,
an anonymous ``memfd`` the parent creates and maps; the child inherits the descriptor and maps
it too): one copy (~25-30 us) and a small frame (~20-30 us). Measured with the node's caches as
cold as between two of its periods (``python -m rod_sim.io.handover_bench``, docs/bench.md):
57-78 us of the parent's CPU per chunk, against 92-109 us through the pipe, which copies it
into the kernel (and the child copies it out again); in the node's own loop (``rate_bench
--period-cost``, n = 1024) 66-77 us against 97-106 us. Each chunk lies in one contiguous piece
of the ring. Through the *frame pipe* (the child's stdin) go only the frames:
``<u64 length><pickle of (method, args, size, at)>``, where ``size`` [bytes] is the length of
the payload (the chunk's records) and ``at`` the ring position [bytes, counted from the start
of the log, never wrapped] at which it starts (its offset in the ring is ``at % ring size``),
or ``None`` when the ``size`` payload bytes follow the frame in the pipe: a chunk larger than
the ring (one huge message: a chunk ends after the record that passes ``chunk_size``, so a
chunk has no upper bound), or every chunk when there is no ring (``ring_bytes=0``). Through the
*ack pipe* (child to parent) go the acknowledgements: after a chunk from the ring is
compressed and written, the child writes the ring position where it ends (``<u64>``); the
parent reuses ring bytes only below the latest acknowledged position, and waits for the next
acknowledgement when the ring is full (or when the ack pipe could fill: see
:meth:`ProcessSink._reserve`).

The child's lifetime is the log's: it ends after the summary, or at the end of its input when
the parent dies (killed), keeping every chunk it received (those still in the ring too: it
keeps the ring mapped): the file then ends at its last complete chunk, as after a killed
in-process writer. It runs in a session of its own and ignores SIGINT, so a Ctrl-C in the
terminal reaches only the parent, which closes the log. A write error in the child (OSError: a
full disk) ends it; the parent's next call raises that error (its errno and text), as does a
wait for ring space once the child has ended.
"""
from __future__ import annotations

import errno as errno_codes
import fcntl
import mmap
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
from pathlib import Path

from rod_sim.io.mcap_writer import ChunkSink

_LEN = struct.Struct("<Q")
PIPE_BYTES = 1 << 20
"""Frame pipe buffer asked for (Linux F_SETPIPE_SZ): a chunk sent through the pipe (larger
than the ring, or with no ring) up to this size is a copy into the kernel, not a wait for the
child."""
RING_BYTES = 8 << 20
"""[bytes] shared memory for the chunks handed over: 32 chunks of 256 KiB (~45 ms of the
node's log at n = 1024, 1 kHz), so that the child falling behind for a while (a slow disk
write, the machine busy) does not stop the node. Its pages are allocated when the log opens
(MAP_POPULATE; the first 32 chunks cost the parent ~3x otherwise) and kept until it closes.
A 2 MiB ring cost the same per chunk (measured, within the noise)."""
END_TIMEOUT_S = 30.0
"""[s] the parent waits for the child to write the last chunks and the summary."""
_F_SETPIPE_SZ = 1031
_F_GETPIPE_SZ = 1032


PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])
"""The directory holding this ``rod_sim`` package: first on the child's path."""


def child_environment(environ=os.environ) -> dict[str, str]:
    """The child's environment: ``environ`` with :data:`PACKAGE_ROOT` first on PYTHONPATH, so
    that the child imports the parent's own ``rod_sim`` (the frames are this module's
    protocol) whatever the working directory (the child runs ``python -P``, which does not
    put it on the path) or the installed copy."""
    env = dict(environ)
    rest = env.get("PYTHONPATH")
    env["PYTHONPATH"] = PACKAGE_ROOT + (os.pathsep + rest if rest else "")
    return env


def _shared_ring(size: int) -> tuple[int, mmap.mmap | None]:
    """(descriptor, map) of ``size`` bytes of shared memory, its pages allocated now
    (MAP_POPULATE), not in the first periods; (-1, None) where the system refuses it (a file
    size limit, ``ulimit -f``, applies to a memfd too; memory locked down): the chunks then go
    through the pipe."""
    fd = -1
    try:
        fd = os.memfd_create("rod_sim-log-ring")
        os.ftruncate(fd, size)
        return fd, mmap.mmap(fd, size, flags=mmap.MAP_SHARED | getattr(mmap, "MAP_POPULATE", 0))
    except OSError:
        if fd >= 0:
            os.close(fd)
        return -1, None


class ProcessSink:
    """A :class:`~rod_sim.io.mcap_writer.ChunkSink` in a child process, writing to the open
    file ``fd`` (inherited; the caller keeps and closes its own) with ``compression``.
    ``ring_bytes``: the shared ring for the chunks' bytes (:data:`RING_BYTES`; 0: every chunk
    through the frame pipe, as on a system without ``os.memfd_create``)."""

    def __init__(self, fd: int, compression: str, ring_bytes: int = RING_BYTES):
        if ring_bytes < 0:
            raise ValueError(f"ring_bytes must be >= 0 (got {ring_bytes})")
        if not hasattr(os, "memfd_create"):
            ring_bytes = 0
        self._ring = None
        self._ring_size = ring_bytes
        self._head = 0          # ring position where the next chunk may start
        self._tail = 0          # the child's latest acknowledgement: bytes below are free
        self._pending = 0       # chunks put in the ring and not yet acknowledged
        # counts: chunks through the ring, through the pipe, waits for ring space, wraps
        self.ring_chunks = self.pipe_chunks = self.ring_waits = self.wraps = 0
        ring_fd, ack_read, ack_write = -1, -1, -1
        try:
            if ring_bytes:
                ring_fd, self._ring = _shared_ring(ring_bytes)
            if self._ring is None:
                self._ring_size = 0
            else:
                ack_read, ack_write = os.pipe()
                os.set_blocking(ack_read, False)
            self._proc = subprocess.Popen(
                [sys.executable, "-P", "-m", "rod_sim.io.log_process", str(fd), compression,
                 str(ring_fd), str(ack_write)],
                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                pass_fds=tuple(f for f in (fd, ring_fd, ack_write) if f >= 0),
                start_new_session=True, env=child_environment())
        except BaseException:
            if ack_read >= 0:
                os.close(ack_read)
            if self._ring is not None:
                self._ring.close()
            raise
        finally:        # the child holds its own copies; the ack pipe ends (EOF) with it
            for f in (ring_fd, ack_write):
                if f >= 0:
                    os.close(f)
        self._acks = ack_read
        self._ack_bytes = b""
        self._ack_poll = select.poll()          # poll, not select: any descriptor number
        if ack_read >= 0:
            self._ack_poll.register(ack_read, select.POLLIN)
        # acknowledgements unread in the ack pipe at most, so that the child never blocks
        # writing one (while the parent might block writing a frame it does not read)
        self._max_pending = (fcntl.fcntl(ack_read, _F_GETPIPE_SZ) // _LEN.size - 1
                             if ack_read >= 0 else 0)
        try:
            fcntl.fcntl(self._proc.stdin.fileno(), _F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:         # above /proc/sys/fs/pipe-max-size: the default pipe works
            pass
        self._pipe = self._proc.stdin      # written through its descriptor: not buffered
        self._pipe_fd = self._pipe.fileno()
        self._failed: OSError | None = None

    def _send(self, method: str, args: tuple, payload=None, at: int | None = None) -> None:
        """One frame; the payload follows it in the pipe unless it lies in the ring at ``at``."""
        if self._failed is not None:
            raise self._failed
        size = 0 if payload is None else len(payload)
        meta = pickle.dumps((method, args, size, at))
        try:
            self._write_all(_LEN.pack(len(meta)) + meta)
            if payload is not None and at is None:
                self._write_all(payload)
        except (BrokenPipeError, ValueError):   # the child ended: its error is the cause
            raise self._child_error() from None

    def _write_all(self, data) -> None:
        """``data`` into the frame pipe with os.write: one syscall for a frame (a buffered
        writer's write and flush cost ~5 us more per chunk); a blocking pipe takes it all
        unless a signal cuts the write short, then the rest follows."""
        if self._pipe_fd < 0:
            raise ValueError("the frame pipe is closed")
        view = memoryview(data)
        while view:
            view = view[os.write(self._pipe_fd, view):]

    def _read_acks(self, wait: bool) -> None:
        """Take in the child's acknowledgements; with ``wait``, wait for one first (the
        child's end, EOF, raises its error: this wait is bounded by the child's life)."""
        if wait:
            self._ack_poll.poll()       # readable: an acknowledgement, or EOF
        try:
            data = os.read(self._acks, 1 << 16)
        except BlockingIOError:
            return
        if not data:
            raise self._child_error()
        data = self._ack_bytes + data
        whole = len(data) - len(data) % _LEN.size
        self._ack_bytes = data[whole:]
        if whole:
            self._tail = _LEN.unpack_from(data, whole - _LEN.size)[0]   # positions only grow
            self._pending -= whole // _LEN.size

    def _reserve(self, size: int) -> int:
        """The ring position for a chunk of ``size`` bytes (<= the ring): at the head, or at
        the ring's start when it does not fit before the end (the bytes skipped are free
        once the chunk is acknowledged). Waits until the child has acknowledged every byte
        the chunk overwrites, and until fewer than ``_max_pending`` acknowledgements are
        unread. The child reads a chunk only after its frame and acknowledges it only after
        writing it: the pipe's write and read (syscalls, the kernel's lock on the pipe)
        order the copies into the ring before the child's reads, and the child's reads
        before the parent's next copy into the same bytes."""
        ring = self._ring_size
        head = self._head
        offset = head % ring
        at = head if offset + size <= ring else head + ring - offset
        wait = False            # first the acknowledgements there are, then wait for more
        while True:
            empty = self._tail == head       # nothing unacknowledged: any place is free
            if (empty or at + size - self._tail <= ring) and self._pending < self._max_pending:
                break
            self._read_acks(wait)
            self.ring_waits += wait
            wait = True
        if at != head:
            self.wraps += 1
        return at

    def _child_error(self) -> OSError:
        self._wait()
        text = self._proc.stderr.read().decode(errors="replace").strip().splitlines()
        line = text[-1] if text else f"the log writer process ended ({self._proc.returncode})"
        code, _, message = line.partition(" ")
        if code.isdigit():
            self._failed = OSError(int(code), message)
        else:
            self._failed = OSError(errno_codes.EIO, line)
        return self._failed

    def _wait(self) -> None:
        """Wait for the child to end; killed after :data:`END_TIMEOUT_S`."""
        try:
            self._proc.wait(timeout=END_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()

    def write_start(self, header: bytes) -> None:
        self._send("write_start", (header,))

    def write_metadata(self, name: str, record: bytes) -> None:
        self._send("write_metadata", (name, record))

    def write_chunk(self, raw, index: dict[int, list[int]], start: int, end: int) -> None:
        """Hand over one chunk: its bytes into the ring (one copy) and a frame saying where,
        or, larger than the ring, its bytes through the frame pipe."""
        if self._failed is not None:
            raise self._failed
        size = len(raw)
        if self._ring is None or not 0 < size <= self._ring_size:     # no ring, or closed
            self.pipe_chunks += 1
            self._send("write_chunk", (index, start, end), raw)
            return
        at = self._reserve(size)
        offset = at % self._ring_size
        self._ring[offset:offset + size] = raw
        self._send("write_chunk", (index, start, end), raw, at)
        self._head = at + size
        self._pending += 1
        self.ring_chunks += 1

    def write_end(self, schemas: list, channels: list, statistics: dict) -> None:
        """The summary; then waits (at most :data:`END_TIMEOUT_S`) until the child has
        written it and ended."""
        self._send("write_end", (schemas, channels, statistics))
        self.close()
        if self._proc.returncode != 0:
            raise self._child_error()

    def close(self) -> None:
        """End the child's input and wait for it (it writes what it was given, then ends);
        killed after :data:`END_TIMEOUT_S`. Idempotent."""
        self._pipe_fd = -1
        try:
            self._pipe.close()
        except OSError:
            pass
        if self._acks >= 0:     # the child's last acknowledgements go nowhere (EPIPE)
            os.close(self._acks)
            self._acks = -1
        self._wait()
        if self._ring is not None:
            self._ring.close()
            self._ring = None


def _read_exact(stream, size: int) -> bytes | None:
    data = stream.read(size)
    if len(data) < size:
        return None         # end of input (a partial frame: the parent died while sending)
    return data


def serve(fd: int, compression: str, source, ring_fd: int = -1, ack_fd: int = -1) -> int:
    """The child's loop: frames from ``source`` (a binary stream) run on a ChunkSink writing
    to ``fd``, chunk bytes read from the shared ring ``ring_fd`` (mapped here) when a frame
    says so, each acknowledged on ``ack_fd`` once written; 0 at the end of input, 1 after an
    error (``errno text`` on stderr)."""
    sink = ChunkSink(os.fdopen(fd, "wb", buffering=0, closefd=True), compression)
    ring = None
    if ring_fd >= 0:
        ring = memoryview(mmap.mmap(ring_fd, 0))
        os.close(ring_fd)
    while True:
        head = _read_exact(source, _LEN.size)
        if head is None:
            return 0
        meta = _read_exact(source, _LEN.unpack(head)[0])
        if meta is None:
            return 0
        method, args, size, at = pickle.loads(meta)
        if at is not None:
            offset = at % len(ring)
            args = (ring[offset:offset + size], *args)
        elif size:
            payload = _read_exact(source, size)
            if payload is None:
                return 0
            args = (payload, *args)
        try:
            getattr(sink, method)(*args)
        except OSError as exc:
            code = exc.errno if exc.errno is not None else errno_codes.EIO
            text = " ".join(str(exc.strerror or exc).split())
            sys.stderr.write(f"{code} {text}\n")
            return 1
        if at is not None and ack_fd >= 0:
            try:
                os.write(ack_fd, _LEN.pack(at + size))
            except BrokenPipeError:     # the parent is gone or closing: write on, unacked
                os.close(ack_fd)
                ack_fd = -1
        if method == "write_end":
            return 0


def main(argv: list[str]) -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    fd, compression = int(argv[0]), argv[1]
    ring_fd, ack_fd = (int(argv[2]), int(argv[3])) if len(argv) > 3 else (-1, -1)
    return serve(fd, compression, sys.stdin.buffer, ring_fd, ack_fd)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
