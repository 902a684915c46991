"""Issue 27, item 1: the node's start-up on long chains. `rod-sim node` on a 10 000- or
100 000-rod scene printed nothing, never subscribed within 240 s and ignored SIGINT: its
start-up calibration integrated whole periods with no work bound (22 s for one 10 000-rod
calibration here) and the validity monitor solved the chain's bending mode by Lanczos (40 s at
10 000 rods). Now the start-up is bounded work (budget.measure: every call bounded, ~1 s in
all; the mode of a chain above 4096 rods from its rods), says what it is doing after 2 s, and
SIGINT / SIGTERM at any moment of it end the process within 1 s: status 130 / 143, one line.
its own ROS_DOMAIN_ID (test/ros_domains.py, LOCALHOST)."""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from procs import cpu_seconds, terminal_signals, wait_with_usage  # noqa: E402
from ros_domains import next_domain  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(600)]

REPO = Path(__file__).resolve().parents[1]
DOMAIN = next_domain()
LAUNCH = "import sys; from rod_sim.tools.launch import main; sys.exit(main())"   # as bin/rod-sim


def chain(tmp_path: Path, n: int) -> Path:
    """n of the paper's rods at rest along x, a tip pulse at node n (in motion from t = 0)."""
    path = tmp_path / f"chain{n}.yaml"
    path.write_text(f"name: chain{n}\nrods: {{count: {n}, length: 2.0, mass_per_length: 3.0, "
                    "bending_stiffness: 1.0e5}\nnodes: {mass: 3.0}\nhinges: {stiffness: "
                    "100.0, damping: 0.01}\nloads:\n  - {node: " + str(n) + ", axis: y, shape: "
                    "raised_cosine_pulse, amplitude: 1200.0, start: 0.0, duration: 1.0}\n")
    return path


def start(scene: Path, err: Path) -> subprocess.Popen:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(DOMAIN),
               PYTHONUNBUFFERED="1")
    with open(err, "w") as f:
        return subprocess.Popen([sys.executable, "-c", LAUNCH, "node", "--ros-args", "-p",
                                 f"scene_file:={scene}"], cwd=REPO, env=env, stdout=f,
                                stderr=subprocess.STDOUT, preexec_fn=terminal_signals)


def wait_for(proc, err: Path, text: str, timeout: float) -> float:
    started = time.monotonic()
    while text not in err.read_text():
        assert proc.poll() is None, err.read_text()
        assert time.monotonic() - started < timeout, f"no {text!r} in {timeout} s: " \
                                                     + err.read_text()[-2000:]
        time.sleep(0.05)
    return time.monotonic() - started


@pytest.mark.parametrize("n, limit", [(10_000, 60.0), (100_000, 120.0)])
def test_a_long_chain_starts_in_bounded_time_and_says_so(tmp_path, n, limit):
    err = tmp_path / "node.log"
    proc = start(chain(tmp_path, n), err)
    try:
        took = wait_for(proc, err, f"(n = {n})", limit)          # the node's start line
        log = err.read_text()
        if took > 6.0:          # > 2 s after the imports: what it is doing was said
            assert "rod-sim node: starting: " in log, log
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0, err.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


STOP_CPU_S = 1.0
"""[s] of CPU time from the signal to the exit: the contract's 1 s (docs/interface.md: every
start-up stops within 1 s of Ctrl-C) on a machine that gives the node a core. CPU time is not
stretched by other processes; wall time is: the same stops took 1.06-1.64 s at load 7.5-10
(two cores shared by a dozen processes)."""
STOP_WALL_S = 5.0
"""[s] of wall time from the signal to the exit: a bound that still catches a start-up that
ignores the signal until its next phase (seconds of CPU for 100 000 rods), with a margin of 3
over the worst loaded figure."""


def test_a_signal_at_any_moment_of_the_start_up_ends_it_within_1_s(tmp_path):
    scene = chain(tmp_path, 100_000)
    rng = random.Random(27)
    for trial in range(6):
        sig = rng.choice([signal.SIGINT, signal.SIGTERM])
        delay = rng.uniform(0.1, 6.0)
        err = tmp_path / f"node{trial}.log"
        proc = start(scene, err)
        try:
            time.sleep(delay)
            log = err.read_text()
            if "(n = 100000)" in log:
                continue                                 # already running: test_node_process
            cpu_before = cpu_seconds(proc.pid)
            sent = time.monotonic()
            proc.send_signal(sig)
            usage = wait_with_usage(proc, timeout=30.0)
            took = time.monotonic() - sent
            assert usage is not None, f"still running 30 s after {sig.name}"
            status = proc.returncode
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        log = err.read_text()
        what = f"{sig.name} at {delay:.2f} s: "
        lines = [line for line in log.splitlines() if not line.startswith("[")
                 and ": starting: " not in line]
        assert status == 128 + sig, what + log
        assert "Traceback" not in log, what + log
        assert len(lines) == 1 and lines[0].startswith("rod-sim node: interrupted"), what + log
        assert ("(SIGTERM)" in lines[0]) == (sig == signal.SIGTERM), what + log
        cpu = usage.ru_utime + usage.ru_stime - cpu_before
        assert cpu < STOP_CPU_S, what + f"{cpu:.2f} s of CPU after the signal"
        assert took < STOP_WALL_S, what + f"ended {took:.2f} s after the signal"


SWALLOWED = """
import ctypes, os, signal, sys, time
from rod_sim.ros.process import run_node

def in_callback():
    os.kill(os.getpid(), getattr(signal, sys.argv[1]))
    time.sleep(5)

def make_node():
    # the signal lands inside a ctypes callback (as in numba's machine-code cache): Python
    # reports "Exception ignored on calling ctypes callback function" and drops the
    # KeyboardInterrupt; the start-up runs on
    ctypes.CFUNCTYPE(None)(in_callback)()
    time.sleep(float(sys.argv[2]))          # the rest of the start-up
    from rclpy.node import Node
    return Node("swallowed")

sys.exit(run_node("rod-sim node", make_node, [], ()))
"""


@pytest.mark.parametrize("sig, rest", [("SIGTERM", 0.0), ("SIGINT", 0.0), ("SIGTERM", 30.0)])
def test_a_start_up_signal_that_python_drops_still_ends_the_start_up(tmp_path, sig, rest):
    """CI: SIGTERM 1.59 s into a 100 000-rod node's start-up landed in a ctypes callback of
    llvmlite (numba's cache), which printed "Exception ignored on calling ctypes callback
    function ..." with a traceback and dropped the interruption: the node started and exited
    0. Now the start-up still ends with its one line and 130 / 143: at once when the rest of
    the start-up is short, and by the start-up's watchdog (0.75 s) when it would take 30 s
    more; the dropped interruption is not printed."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(DOMAIN))
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-c", SWALLOWED, sig, str(rest)], env=env,
                          capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          preexec_fn=terminal_signals)
    took = time.monotonic() - started
    signum = getattr(signal, sig)
    line = "rod-sim node: interrupted during start-up" + (" (SIGTERM)" if sig == "SIGTERM"
                                                         else "")
    assert (done.returncode, done.stderr) == (128 + signum, line + "\n")
    assert took < 20.0                  # 30 s of start-up were not waited for
