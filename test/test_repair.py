"""``rod-sim repair``: a log whose writer was SIGKILLed (no summary; rosbags cannot open it) is
rewritten complete, with every message of its complete chunks, and rosbags reads it (issue 11
item 6). The node's SIGKILL case is in the ros-marked test below (ROS domain id from
ros_domains)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from rod_sim.io.log_reader import LogReader
from rod_sim.tools import cli
from ros_domains import next_domain  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"
JAZZY = get_typestore(Stores.ROS2_JAZZY)
DOMAIN_REPAIR_NODE = next_domain()


def rod_sim(*args) -> int:
    return cli.main([str(a) for a in args])


def ours(path: Path) -> list[tuple[str, int, bytes]]:
    with LogReader(path) as reader:
        return list(reader.raw_messages())


def rosbags_messages(path: Path) -> list[tuple[str, int, bytes]]:
    with AnyReader([path], default_typestore=JAZZY) as reader:
        out = []
        for conn, t, raw in reader.messages():
            assert reader.deserialize(raw, conn.msgtype) is not None
            out.append((conn.topic, t, bytes(raw)))
    return sorted(out, key=lambda m: m[1])


def kill_when_larger(proc: subprocess.Popen, log: Path, size: int, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while not (log.exists() and log.stat().st_size > size):
        assert proc.poll() is None, "the writer ended before the log grew"
        assert time.monotonic() < deadline, "the log did not grow"
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=10) == -signal.SIGKILL


def check_repaired(tmp_path: Path, log: Path, capsys) -> Path:
    with LogReader(log) as reader:
        assert not reader.complete
    with pytest.raises(Exception):          # rosbags needs the summary
        rosbags_messages(log)
    before = log.read_bytes()
    assert rod_sim("repair", log) == 0
    out = log.with_name(log.stem + ".repaired.mcap")
    text = capsys.readouterr().out
    kept = ours(log)
    assert f"{len(kept)} messages" in text
    assert log.read_bytes() == before                        # the source is untouched
    with LogReader(out) as reader:
        assert reader.complete and not reader.truncated
        assert reader.metadata() == LogReader(log).metadata()
        assert reader.channels().keys() == LogReader(log).channels().keys()
    got = rosbags_messages(out)
    assert len(got) == len(kept) > 100
    assert sorted(got, key=lambda m: (m[1], m[0])) == sorted(kept, key=lambda m: (m[1], m[0]))
    return out


def test_repair_a_sigkilled_simulate_log(tmp_path, capsys):
    log = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(PAPER),
                             "--model", "reduced", "--t-end", "500", "--rate", "1000",
                             "--out", str(log)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    kill_when_larger(proc, log, 600_000)
    out = check_repaired(tmp_path, log, capsys)
    t = [m[1] for m in ours(out) if m[0] == "/rod_states"]
    assert t[0] == 0 and np.all(np.diff(t) == 1_000_000)
    assert rod_sim("repair", log) == 2                                # refuses to overwrite
    assert "exists" in capsys.readouterr().err
    assert rod_sim("repair", out) == 0                                # complete: nothing to do
    assert "nothing to repair" in capsys.readouterr().out
    assert not out.with_name(out.stem + ".repaired.mcap").exists()


def test_repair_bad_input(tmp_path, capsys):
    missing = tmp_path / "missing.mcap"
    assert rod_sim("repair", missing) == 2
    assert "no such file" in capsys.readouterr().err
    text = tmp_path / "x.mcap"
    text.write_text("hello")
    assert rod_sim("repair", text) == 2
    assert "not an MCAP" in capsys.readouterr().err
    assert not (tmp_path / "x.repaired.mcap").exists()


def test_repair_refuses_a_corrupt_log(tmp_path, capsys):
    log = tmp_path / "cut.mcap"
    assert rod_sim("simulate", PAPER, "--model", "reduced", "--t-end", "1", "--markers-rate",
                   "0", "--out", log) == 0          # the layout the offsets below were made for
    data = bytearray(log.read_bytes())
    cut = data[:int(len(data) * 0.8)]
    cut[2000] ^= 0x08
    log.write_bytes(bytes(cut))
    capsys.readouterr()
    # the flip is in the first chunk, which holds the channel definitions of this log without
    # summary: the warning names the chunk, the error says why the rest cannot be read
    assert rod_sim("repair", log, "--out", tmp_path / "r.mcap") == 2
    warning, error = capsys.readouterr().err.strip().splitlines()
    assert warning.startswith("rod-sim: warning:") and "is damaged" in warning
    assert error.startswith("rod-sim repair: error:") and "corrupt log: the damaged chunk at" \
        " byte" in error and "held the definition of channel" in error
    assert not (tmp_path / "r.mcap").exists()



def test_repair_refuses_a_log_whose_only_complete_chunk_is_damaged(tmp_path, capsys):
    """Cut after its first chunk, that chunk's data flipped: no message is intact, so there is
    nothing to repair: exit 2, one line, nothing written (not an empty "repaired" log)."""
    import struct

    log = tmp_path / "one.mcap"
    assert rod_sim("simulate", PAPER, "--t-end", "1", "--out", log) == 0
    data = bytearray(log.read_bytes())
    off = 8                                     # after the magic: (opcode, u64 length, body)
    while data[off] != 0x06:                    # the first chunk record
        off += 9 + struct.unpack_from("<Q", data, off + 1)[0]
    end = off + 9 + struct.unpack_from("<Q", data, off + 1)[0]
    cut = data[:end + 100]                      # the chunk whole, the next record cut short
    cut[(off + end) // 2] ^= 0x08               # inside its compressed records
    log.write_bytes(bytes(cut))
    capsys.readouterr()
    assert rod_sim("repair", log, "--out", tmp_path / "r.mcap") == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[0].startswith("rod-sim: warning:") and "is damaged" in lines[0]
    assert lines[-1].startswith("rod-sim repair: error:") and "no intact message" in lines[-1]
    assert not (tmp_path / "r.mcap").exists()

@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(90)
def test_repair_a_sigkilled_node_log(tmp_path, capsys):
    pytest.importorskip("rclpy")
    log = tmp_path / "node.mcap"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(DOMAIN_REPAIR_NODE), PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "rod_sim.ros.node", "--ros-args",
                             "-p", f"scene_file:={PAPER}", "-p", f"record_path:={log}",
                             "-p", "real_time_factor:=0.0"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        kill_when_larger(proc, log, 400_000, timeout=80.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    check_repaired(tmp_path, log, capsys)
