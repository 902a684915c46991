"""Issue 20 item 5: real-time pacing under scheduling delay, met as a user meets it: the node
as a process beside busy sibling processes keeps real time, because it catches up the backlog
its cheap stepping can afford instead of dropping it. The siblings are one busy loop per core
(nice 19), and one more sibling that takes the node off the CPU for 150 ms every 0.5 s
(SIGSTOP / SIGCONT: a scheduling delay of a known length, longer than the four periods the
previous pacer caught up, so the test does not depend on how busy the machine is otherwise).
The previous pacer dropped ~12 of every 15 periods due after such a delay (RTF 0.764 and
0.771 in two runs).
ROS domain id from ros_domains (LOCALHOST)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from sensor_msgs.msg import JointState  # noqa: E402

from ros_domains import next_domain  # noqa: E402
from ros_graph import Client, NodeProcess, stamp_ns, unique_namespace  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "paper_example.yaml"
DOMAIN = next_domain()
PERIOD_NS = 10_000_000
SIBLINGS = os.cpu_count() or 2
"""Busy processes: one per core, at nice 19: they keep every core busy without starving the
node of CPU time on a machine that is busy already (no pacing can make up for too little CPU:
then dropping is right); the stops below are the scheduling delays."""
WINDOW_S = 6.0
DELAY_S, EVERY_S = 0.15, 0.5
"""The node is stopped for DELAY_S every EVERY_S [s] of wall time."""


def queued_s(pid: int) -> float:
    """[s] the main thread of process ``pid`` (the node's executor) has waited in a run queue
    so far: runnable but not running because other processes had the CPU (Linux schedstat;
    the SIGSTOP delays below are not counted: a stopped thread is not runnable)."""
    return int(Path(f"/proc/{pid}/task/{pid}/schedstat").read_text().split()[1]) / 1e9


def deschedule(pid: int, stop: threading.Event) -> None:
    """Take process ``pid`` off the CPU for DELAY_S every EVERY_S until ``stop``."""
    while not stop.wait(EVERY_S - DELAY_S):
        os.kill(pid, signal.SIGSTOP)
        time.sleep(DELAY_S)
        os.kill(pid, signal.SIGCONT)


@pytest.mark.slow
def test_busy_siblings_and_scheduling_delays_keep_real_time(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    ns = unique_namespace()
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"], scene_file=PAPER)
    client = Client(DOMAIN, namespace=ns)
    arrivals: list[tuple[int, int]] = []
    client.node.create_subscription(
        JointState, "rod_states", lambda m: arrivals.append((time.monotonic_ns(), stamp_ns(m))),
        100)
    siblings = []
    try:
        node.wait_for_output("commands on")
        client.spin_until(lambda: len(arrivals) > 50, 30.0, "states", node)
        siblings = [subprocess.Popen([sys.executable, "-c",
                                      "import os; os.nice(19)\nwhile True: pass"])
                    for _ in range(SIBLINGS)]
        stop = threading.Event()
        scheduler = threading.Thread(target=deschedule, args=(node.proc.pid, stop))
        scheduler.start()
        start = len(arrivals)
        queued0 = queued_s(node.proc.pid)
        try:
            client.spin_for(WINDOW_S)
        finally:
            stop.set()
            scheduler.join()
        queued = queued_s(node.proc.pid) - queued0
        window = arrivals[start:]
    finally:
        for proc in siblings:
            proc.kill()
            proc.wait(timeout=10)
        client.close()
        node.kill()
    stamps = [t for _, t in window]
    assert all(b - a == PERIOD_NS for a, b in zip(stamps, stamps[1:])), "one state per period"
    wall = (window[-1][0] - window[0][0]) / 1e9
    rtf = (stamps[-1] - stamps[0]) / 1e9 / wall
    dropped = [line for line in node.stderr.splitlines() if "dropped" in line]
    # Real time is owed where the node gets the CPU it asks for: the nice-19 siblings yield it
    # at once. Where other processes at normal priority keep it waiting for a CPU (make flake's
    # busy loops, a loaded machine: RTF 0.851 and 0.897 at load 8, the node queued for 3.2 and
    # 3.3 s of the 5.9 s window), dropping is right and not asserted against.
    starved = queued > 0.1 * wall
    assert wall > 0.8 * WINDOW_S and (rtf > 0.9 or starved), \
        f"RTF {rtf:.3f} over {wall:.2f} s, queued for a CPU {queued:.2f} s: {dropped}"
