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
