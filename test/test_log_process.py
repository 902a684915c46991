"""Logs written through a child process (rod_sim.io.log_process, the node's recording).

The oracle of the bytes is mcap's own writer (``mcap.writer.Writer``) fed the same calls; a
killed parent, a full disk and a Ctrl-C are run for real (processes, /dev/full, SIGINT).
"""
from __future__ import annotations

import errno
import io
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from rod_sim.io.log_writer import LogWriter
from rod_sim.io.mcap_writer import ChunkedMcapWriter

sys.path.insert(0, str(Path(__file__).parent))
from test_mcap_writer import play, script  # noqa: E402

METADATA = {"scene": "name: s\n", "model": "reduced", "integrator": "dop853"}
PAYLOAD = bytes(range(256)) * 40                 # 10 KiB, compressible


def _gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.02)
    return False


@pytest.mark.parametrize("compression", ["zstd", "none"])
def test_same_bytes_as_mcap_writer(tmp_path, compression):
    from mcap.writer import CompressionType

    from rod_sim.io.log_process import ProcessSink

    calls = script(11, 300)
    theirs = io.BytesIO()
    kind = {"zstd": CompressionType.ZSTD, "none": CompressionType.NONE}[compression]
    play(Writer(theirs, chunk_size=16 * 1024, enable_data_crcs=True, compression=kind), calls)
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), compression)
        play(ChunkedMcapWriter(chunk_size=16 * 1024, sink=sink), calls)
    assert path.read_bytes() == theirs.getvalue()


class _Trickle(io.RawIOBase):
    """A raw file that takes at most ``most`` bytes per write (as a filling disk may), then
    ``None`` (as a non-blocking one) once ``stall`` writes were made, if given."""

    def __init__(self, most: int, stall: int | None = None):
        self.data, self.most, self.stall, self.calls = bytearray(), most, stall, 0

    def writable(self):
        return True

    def write(self, b):
        self.calls += 1
        if self.stall is not None and self.calls > self.stall:
            return None
        take = bytes(b[:self.most])
        self.data += take
        return len(take)


def test_a_raw_file_that_takes_part_of_each_write_gets_every_byte():
    from mcap.writer import CompressionType

    from rod_sim.io.mcap_writer import ChunkSink

    calls = script(7, 200)
    theirs = io.BytesIO()
    play(Writer(theirs, chunk_size=16 * 1024, enable_data_crcs=True,
                compression=CompressionType.ZSTD), calls)
    trickle = _Trickle(most=1000)
    play(ChunkedMcapWriter(chunk_size=16 * 1024, sink=ChunkSink(trickle, "zstd")), calls)
    assert bytes(trickle.data) == theirs.getvalue() and trickle.calls > len(theirs.getvalue()) // 1000


def test_a_raw_file_that_takes_nothing_is_an_error_not_a_lost_chunk():
    from rod_sim.io.mcap_writer import ChunkSink

    with pytest.raises(OSError, match="the log took None of"):
        play(ChunkedMcapWriter(chunk_size=16 * 1024, sink=ChunkSink(_Trickle(64, stall=3))),
             script(7, 200))


@pytest.mark.parametrize("refused", ["memfd_create", "ftruncate"])
def test_no_shared_ring_to_be_had_sends_the_chunks_through_the_pipe(tmp_path, monkeypatch,
                                                                     refused):
    """``ulimit -f`` applies to a memfd too: its ftruncate fails with EFBIG."""
    from mcap.writer import CompressionType

    from rod_sim.io.log_process import ProcessSink

    def refuse(*args):
        raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))

    calls = script(5, 300)
    theirs = io.BytesIO()
    play(Writer(theirs, chunk_size=16 * 1024, enable_data_crcs=True,
                compression=CompressionType.ZSTD), calls)
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        monkeypatch.setattr(os, refused, refuse)
        sink = ProcessSink(f.fileno(), "zstd")
        monkeypatch.undo()
        play(ChunkedMcapWriter(chunk_size=16 * 1024, sink=sink), calls)
    assert path.read_bytes() == theirs.getvalue()
    assert sink.ring_chunks == 0 and sink.pipe_chunks > 3


def test_log_writer_through_a_process_writes_what_it_writes_in_process(tmp_path):
    def write(path, process):
        with LogWriter(path, metadata=METADATA, writer_process=process) as log:
            for k in range(200):
                log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, PAYLOAD)
                log.write("/clock", "rosgraph_msgs/msg/Clock", k * 1000,
                          {"clock": {"sec": 0, "nanosec": k * 1000}})
        return path.read_bytes()

    assert write(tmp_path / "a.mcap", True) == write(tmp_path / "b.mcap", False)
    with open(tmp_path / "a.mcap", "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) == 400


def test_the_writer_process_imports_the_parents_package_whatever_the_directory(tmp_path,
                                                                               monkeypatch):
    """A working directory holding another ``rod_sim`` (another checkout, an older version
    whose frames differ) must not be what the child runs: here that one exits at once."""
    decoy = tmp_path / "decoy" / "rod_sim" / "io"
    decoy.mkdir(parents=True)
    (decoy.parent / "__init__.py").write_text("")
    (decoy / "__init__.py").write_text("")
    (decoy / "log_process.py").write_text("raise SystemExit('the decoy ran')\n")
    monkeypatch.chdir(decoy.parents[1])
    path = tmp_path / "log.mcap"
    with LogWriter(path, metadata=METADATA, writer_process=True) as log:
        for k in range(100):
            log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, PAYLOAD)
    with open(path, "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) == 100


CHILD = textwrap.dedent("""
    import os, signal, sys, time
    from rod_sim.io.log_writer import LogWriter
    log = LogWriter(sys.argv[1], metadata={"scene": "s", "model": "reduced",
                                           "integrator": "i"}, writer_process=True)
    payload = bytes(range(256)) * 40
    for k in range(int(sys.argv[2])):
        log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, payload)
    print(log._sink._proc.pid, flush=True)
    if sys.argv[3] == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # this process stands for a node that
    os.killpg(os.getpgid(0), signal.SIGINT)         # closes its log on Ctrl-C: the terminal's
    time.sleep(0.2)                                 # Ctrl-C goes to the foreground group
    for k in range(int(sys.argv[2]), 2 * int(sys.argv[2])):
        log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, payload)
    log.close()
""")


def _run_child(tmp_path, how: str, messages: int):
    path = tmp_path / "run.mcap"
    proc = subprocess.run([sys.executable, "-c", CHILD, str(path), str(messages), how],
                          capture_output=True, text=True, timeout=120,
                          start_new_session=True)     # its own group, for the SIGINT
    return path, proc


def test_a_killed_parent_leaves_every_chunk_it_handed_over(tmp_path):
    from rod_sim.io.log_reader import LogReader

    messages = 300                     # 3 MB: 11 full chunks of 256 KiB and one open
    path, proc = _run_child(tmp_path, "kill", messages)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    writer_pid = int(proc.stdout.split()[0])
    assert _gone(writer_pid, 30.0), "the log writer process outlived its parent"
    per_chunk = -(-(256 * 1024) // (len(PAYLOAD) + 31))      # records to pass 256 KiB
    with LogReader(path) as reader:
        assert not reader.complete
        got = sum(1 for _ in reader.raw_messages())
    # every full chunk was handed over and written; only the open one is lost
    assert messages - per_chunk <= got < messages


def test_a_ctrl_c_does_not_reach_the_writer_process_and_the_log_closes_whole(tmp_path):
    path, proc = _run_child(tmp_path, "sigint", 100)
    assert proc.returncode == 0, proc.stderr
    with open(path, "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) == 200


def test_a_full_disk_in_the_writer_process_is_raised_with_its_errno():
    log = LogWriter("/dev/full", metadata=METADATA, overwrite=True, writer_process=True)
    with pytest.raises(OSError) as err:
        for k in range(200):
            log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, PAYLOAD)
        log.close()
    assert err.value.errno == errno.ENOSPC and "No space left" in str(err.value)
    log.close()                         # after the error: returns, writes nothing
    assert log._sink._proc.poll() is not None


def test_a_writer_process_killed_mid_run_stops_the_log_with_a_clear_error(tmp_path):
    """The child dies (an OOM kill, say): the node's next chunk raises OSError naming it, the
    log stops, and closing it returns at once."""
    path = tmp_path / "run.mcap"
    log = LogWriter(path, metadata=METADATA, writer_process=True)
    for k in range(30):                 # the first chunk is handed over
        log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, PAYLOAD)
    child = log._sink._proc
    os.kill(child.pid, signal.SIGKILL)
    child.wait(timeout=10)
    with pytest.raises(OSError, match="log writer process ended"):
        for k in range(30, 200):
            log.write_cdr("/rod_states", "sensor_msgs/msg/JointState", k * 1000, PAYLOAD)
    start = time.monotonic()
    log.close()
    assert time.monotonic() - start < 5.0 and log.closed


# ----- the shared ring (chunks' bytes in shared memory, frames through the pipe) -----

def _mcap_bytes(calls, chunk_size: int, compression: str = "zstd", finish: bool = True) -> bytes:
    """The oracle: mcap's own writer fed ``calls``; without ``finish``, the bytes it has
    written when the caller is killed (the chunks closed so far, no summary)."""
    from mcap.writer import CompressionType

    kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
            "none": CompressionType.NONE}[compression]
    out = io.BytesIO()
    writer = Writer(out, chunk_size=chunk_size, enable_data_crcs=True, compression=kind)
    if not finish:
        writer.finish = lambda: None        # play() ends with finish()
    play(writer, calls)
    return out.getvalue()


def _small(calls, limit: int) -> list[tuple]:
    """``calls`` with every payload cut to ``limit`` bytes (no chunk larger than the ring)."""
    return [c if c[0] != "message" else c[:3] + (c[3][:limit],) + c[4:] for c in calls]


def _play_in_thread(writer, calls):
    import threading

    errors = []

    def run():
        try:
            play(writer, calls)
        except BaseException as exc:    # noqa: BLE001 (handed to the test)
            errors.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, errors


def _waiting_on_a_stopped_child(sink, calls):
    """Stop ``sink``'s child (SIGSTOP) and play ``calls`` (chunks of 16 KiB) in a thread
    until the parent waits for ring space: (the thread, its errors). The caller resumes or
    kills the child in any case."""
    os.kill(sink._proc.pid, signal.SIGSTOP)
    thread, errors = _play_in_thread(ChunkedMcapWriter(chunk_size=16 * 1024, sink=sink), calls)
    _until(lambda: sink.ring_chunks >= 2 or errors)
    thread.join(0.5)
    assert thread.is_alive() and not errors, "the parent did not wait for ring space"
    return thread, errors


def _until(condition, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_same_bytes_through_a_small_ring_that_wraps_around(tmp_path, compression):
    """Chunks of ~16-21 KiB through a 40 KiB ring: most start at its beginning again."""
    from rod_sim.io.log_process import ProcessSink

    calls = _small(script(21, 600), 5000)
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), compression, ring_bytes=40 * 1024)
        play(ChunkedMcapWriter(chunk_size=16 * 1024, sink=sink), calls)
    assert path.read_bytes() == _mcap_bytes(calls, 16 * 1024, compression)
    assert sink.pipe_chunks == 0 and sink.ring_chunks > 20 and sink.wraps > 10


def test_a_chunk_larger_than_the_ring_goes_through_the_pipe(tmp_path):
    """Messages of 70000 bytes make chunks larger than a 64 KiB ring: those go through the
    pipe, the others through the ring, in order."""
    from rod_sim.io.log_process import ProcessSink

    calls = script(11, 300)
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), "zstd", ring_bytes=64 * 1024)
        play(ChunkedMcapWriter(chunk_size=16 * 1024, sink=sink), calls)
    assert path.read_bytes() == _mcap_bytes(calls, 16 * 1024)
    assert sink.pipe_chunks > 3 and sink.ring_chunks > 3


@pytest.mark.timing     # signals (SIGSTOP, SIGKILL) and waits
def test_a_full_ring_makes_the_parent_wait_for_the_child(tmp_path):
    """The child stopped (SIGSTOP): the parent fills the 64 KiB ring and waits, overwriting
    nothing the child has not written; the child continued, the log is whole."""
    from rod_sim.io.log_process import ProcessSink

    calls = _small(script(31, 400), 5000)
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), "zstd", ring_bytes=64 * 1024)
        try:
            thread, errors = _waiting_on_a_stopped_child(sink, calls)
            assert 2 <= sink.ring_chunks <= 3     # what 64 KiB holds of chunks > 16 KiB
        finally:
            os.kill(sink._proc.pid, signal.SIGCONT)
        thread.join(60.0)
    assert not thread.is_alive() and not errors, errors
    assert sink.ring_waits >= 1
    assert path.read_bytes() == _mcap_bytes(calls, 16 * 1024)


@pytest.mark.timing     # signals (SIGSTOP, SIGKILL) and waits
def test_more_chunks_than_the_ack_pipe_holds_acknowledgements(tmp_path):
    """One message per chunk (chunk_size 1), 30000 of them, the child stopped at first: the
    parent stops at what the ack pipe can hold (the child never blocks writing an
    acknowledgement while the parent waits to write a frame) and the log is whole."""
    from rod_sim.io.log_process import ProcessSink

    calls = _small(script(41, 30000), 12)
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), "none")
        os.kill(sink._proc.pid, signal.SIGSTOP)
        thread, errors = _play_in_thread(ChunkedMcapWriter(chunk_size=1, sink=sink), calls)
        try:        # the parent stops at the bound (its frames fill 1 MiB of pipe later)
            _until(lambda: sink.ring_chunks >= sink._max_pending or errors)
            thread.join(0.3)
            assert sink.ring_chunks == sink._max_pending and thread.is_alive()
        finally:
            os.kill(sink._proc.pid, signal.SIGCONT)
        thread.join(90.0)
        if thread.is_alive():               # a deadlock: end it, then fail
            sink._proc.kill()
            thread.join(10.0)
            pytest.fail("parent and writer process wait for each other")
    assert not errors, errors
    assert sink.ring_chunks == 30000 and sink.ring_waits > 0
    assert path.read_bytes() == _mcap_bytes(calls, 1, "none")


KILLED_WITH_A_FULL_RING = textwrap.dedent("""
    import os, signal, sys
    sys.path.insert(0, sys.argv[2])
    from test_mcap_writer import play, script
    from rod_sim.io.log_process import ProcessSink
    from rod_sim.io.mcap_writer import ChunkedMcapWriter
    fd = os.open(sys.argv[1], os.O_WRONLY | os.O_CREAT | os.O_EXCL)
    sink = ProcessSink(fd, "zstd")
    os.kill(sink._proc.pid, signal.SIGSTOP)         # it has written nothing yet
    print(sink._proc.pid, flush=True)
    writer = ChunkedMcapWriter(chunk_size=16 * 1024, sink=sink)
    writer.finish = lambda: None                    # killed before the summary
    calls = [c if c[0] != "message" else c[:3] + (c[3][:5000],) + c[4:]
             for c in script(51, 500)]
    play(writer, calls)
    print(sink.ring_chunks, flush=True)
    os.kill(os.getpid(), signal.SIGKILL)
""")


@pytest.mark.timing     # signals (SIGSTOP, SIGKILL) and waits
def test_a_killed_parent_with_chunks_in_the_ring_leaves_them_all(tmp_path):
    """The parent killed while every chunk it handed over is still in the ring (the child
    stopped until then): the child writes them all and ends; the file is what mcap's writer
    had written at that point, byte for byte."""
    path = tmp_path / "killed.mcap"
    proc = subprocess.run([sys.executable, "-c", KILLED_WITH_A_FULL_RING, str(path),
                           str(Path(__file__).parent)],
                          capture_output=True, text=True, timeout=120)
    lines = proc.stdout.split()
    if lines:                       # continued in any case: no stopped process left
        os.kill(int(lines[0]), signal.SIGCONT)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    writer_pid, in_ring = map(int, lines)
    assert _gone(writer_pid, 30.0), "the log writer process outlived its parent"
    assert in_ring > 20
    calls = _small(script(51, 500), 5000)
    assert path.read_bytes() == _mcap_bytes(calls, 16 * 1024, finish=False)


@pytest.mark.timing     # signals (SIGSTOP, SIGKILL) and waits
def test_a_writer_process_killed_while_the_parent_waits_for_ring_space(tmp_path):
    """The parent waits for ring space (the child stopped) and the child is killed: the wait
    ends with OSError naming it, not a hang."""
    from rod_sim.io.log_process import ProcessSink

    calls = _small(script(61, 400), 5000)
    with open(tmp_path / "run.mcap", "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), "zstd", ring_bytes=64 * 1024)
        try:
            thread, errors = _waiting_on_a_stopped_child(sink, calls)
            assert sink.ring_chunks <= 3
        finally:                            # killed in any case: no stopped process left
            os.kill(sink._proc.pid, signal.SIGKILL)
        thread.join(10.0)
        assert not thread.is_alive(), "the parent still waits for a dead writer process"
        sink.close()
    assert len(errors) == 1 and isinstance(errors[0], OSError), errors
    assert "log writer process ended" in str(errors[0])


def _chunk_sizes(data: bytes) -> list[int]:
    """The uncompressed sizes [bytes] of the chunks of an MCAP file, read by mcap's reader."""
    summary = make_reader(io.BytesIO(data)).get_summary()
    return [c.uncompressed_size for c in summary.chunk_indexes]


def test_chunks_at_the_ring_boundaries(tmp_path):
    """One message per chunk, sizes planned against an 8 KiB ring: a chunk ending exactly at
    the ring's end stays there, one a byte longer starts the ring again, a chunk of the
    whole ring fits, one a byte larger goes through the pipe; the bytes are mcap's."""
    from rod_sim.io.log_process import ProcessSink

    ring, record = 8192, 31             # a message record: 31 bytes and the payload

    def calls_for(payloads):
        head = [("metadata", "rod_sim", {"a": "b"}),
                ("schema", "pkg/msg/T", "ros2msg", b"uint8[] data"),
                ("channel", "/t", "cdr", 1, {})]
        return head + [("message", 1, 1000 * k, bytes([k % 251]) * size, 1000 * k, k)
                       for k, size in enumerate(payloads)]

    first = _chunk_sizes(_mcap_bytes(calls_for([100]), 1, "none"))[0]  # schema, channel, 1 message
    sizes = [first, ring - first,       # ends exactly at the ring's end: no wrap
             1000, ring - 1000 + 1,     # one byte past the end: wraps to the start
             999,                       # ends exactly at the end again
             ring,                      # the whole ring
             ring + 1,                  # larger than the ring: through the pipe
             500, 40]
    calls = calls_for([100] + [s - record for s in sizes[1:]])
    theirs = _mcap_bytes(calls, 1, "none")
    assert _chunk_sizes(theirs) == sizes
    path = tmp_path / "ours.mcap"
    with open(path, "xb", buffering=0) as f:
        sink = ProcessSink(f.fileno(), "none", ring_bytes=ring)
        play(ChunkedMcapWriter(chunk_size=1, sink=sink), calls)
    assert (sink.wraps, sink.pipe_chunks, sink.ring_chunks) == (1, 1, 8)   # the 4th wraps
    assert path.read_bytes() == theirs


def test_handover_bench_runs_and_both_ways_write_the_same_file(capsys):
    """A smoke test: its own check (the two files equal) passes; bad counts exit 2."""
    from rod_sim.io import handover_bench

    assert handover_bench.main(["--rounds", "1", "--chunks", "3", "--gap-ms", "0"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("ring: CPU per 256 KiB chunk") and "\npipe: CPU per 256 KiB" in out
    with pytest.raises(SystemExit) as exit_:
        handover_bench.main(["--rounds", "0"])
    assert exit_.value.code == 2


@pytest.mark.parametrize("writer_process", [True, False])
def test_an_interrupt_while_the_log_opens_leaves_no_file(tmp_path, monkeypatch, writer_process):
    """Ctrl-C or SIGTERM inside the writer's set-up (the writer process starting, the header
    written) left the file it had created, empty or with a header only: the log is whole or
    absent."""
    from rod_sim.io import log_process

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    if writer_process:
        monkeypatch.setattr(log_process.ProcessSink, "__init__", interrupted)
    else:
        monkeypatch.setattr(ChunkedMcapWriter, "add_metadata", interrupted)
    path = tmp_path / "opening.mcap"
    with pytest.raises(KeyboardInterrupt):
        LogWriter(path, metadata={"scene": "x", "model": "reduced", "integrator": "rk4"},
                  writer_process=writer_process)
    assert not path.exists()
