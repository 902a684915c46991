"""A log's compression and file writes in a process of their own.

At n = 1024 and 1 kHz a node records ~200 KB of messages per period: compressing and
checksumming them (~0.3 ms per period) is what separates its period from real time. A thread
did not help (measured: the same real-time factor at 20 % more CPU; why is not established), a
process did (docs/bench.md): :class:`ProcessSink` hands each closed chunk (its bytes
and message index) through a pipe to ``python -m rod_sim.io.log_process``, which runs a
:class:`~rod_sim.io.mcap_writer.ChunkSink` on the log file (the file descriptor is inherited,
opened by the caller). The file is the same, byte for byte.

The child's lifetime is the log's: it ends after the summary, or at the end of its input when
the parent dies (killed), keeping every chunk it received: the file then ends at its last
complete chunk, as after a killed in-process writer. It runs in a session of its own and
ignores SIGINT, so a Ctrl-C in the terminal reaches only the parent, which closes the log.
A write error in the child (OSError: a full disk) ends it; the parent's next call raises that
error (its errno and text).
"""
from __future__ import annotations

import errno as errno_codes
import fcntl
import os
import pickle
import signal
import struct
import subprocess
import sys

from rod_sim.io.mcap_writer import ChunkSink

_LEN = struct.Struct("<Q")
PIPE_BYTES = 1 << 20
"""Pipe buffer asked for (Linux F_SETPIPE_SZ): a whole chunk fits, so handing one over is a
copy into the kernel, not a wait for the child."""
END_TIMEOUT_S = 30.0
"""[s] the parent waits for the child to write the last chunks and the summary."""
_F_SETPIPE_SZ = 1031


class ProcessSink:
    """A :class:`~rod_sim.io.mcap_writer.ChunkSink` in a child process, writing to the open
    file ``fd`` (inherited; the caller keeps and closes its own) with ``compression``."""

    def __init__(self, fd: int, compression: str):
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "rod_sim.io.log_process", str(fd), compression],
            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            pass_fds=(fd,), start_new_session=True)
        try:
            fcntl.fcntl(self._proc.stdin.fileno(), _F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:         # above /proc/sys/fs/pipe-max-size: the default pipe works
            pass
        self._pipe = self._proc.stdin
        self._failed: OSError | None = None

    def _send(self, method: str, args: tuple, payload=None) -> None:
        if self._failed is not None:
            raise self._failed
        meta = pickle.dumps((method, args, 0 if payload is None else len(payload)))
        try:
            self._pipe.write(_LEN.pack(len(meta)) + meta)
            if payload is not None:
                self._pipe.write(payload)
            self._pipe.flush()
        except (BrokenPipeError, ValueError):   # the child ended: its error is the cause
            raise self._child_error() from None

    def _wait(self) -> None:
        """Wait for the child to end; killed after :data:`END_TIMEOUT_S`."""
        try:
            self._proc.wait(timeout=END_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()

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

    def write_start(self, header: bytes) -> None:
        self._send("write_start", (header,))

    def write_metadata(self, name: str, record: bytes) -> None:
        self._send("write_metadata", (name, record))

    def write_chunk(self, raw, index: dict[int, list[int]], start: int, end: int) -> None:
        self._send("write_chunk", (index, start, end), raw)

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
        try:
            self._pipe.close()
        except OSError:
            pass
        self._wait()


def _read_exact(stream, size: int) -> bytes | None:
    data = stream.read(size)
    if len(data) < size:
        return None         # end of input (a partial frame: the parent died while sending)
    return data


def serve(fd: int, compression: str, source) -> int:
    """The child's loop: frames from ``source`` (a binary stream) run on a ChunkSink writing
    to ``fd``; 0 at the end of input, 1 after an error (``errno text`` on stderr)."""
    sink = ChunkSink(os.fdopen(fd, "wb", buffering=0, closefd=True), compression)
    while True:
        head = _read_exact(source, _LEN.size)
        if head is None:
            return 0
        meta = _read_exact(source, _LEN.unpack(head)[0])
        if meta is None:
            return 0
        method, args, size = pickle.loads(meta)
        if size:
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
        if method == "write_end":
            return 0


def main(argv: list[str]) -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    fd, compression = int(argv[0]), argv[1]
    return serve(fd, compression, sys.stdin.buffer)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
