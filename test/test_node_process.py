"""The node as a separate process (``python -m rod_sim.ros.node``): lockstep against the offline
model, clean shutdown on SIGTERM, a readable log after SIGKILL, exit status 2 for bad input,
and the one-process demo. Each test uses its own ROS domain id (ros_domains) with LOCALHOST
discovery."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from ros_domains import next_domains  # noqa: E402
import ros_graph  # noqa: E402
from procs import ros_env  # noqa: E402
from rod_sim.core.integrators import make_integrator  # noqa: E402
from rod_sim.core.models import make_model  # noqa: E402
from rod_sim.core.simulator import Simulator  # noqa: E402
from rod_sim.io.log_reader import LogReader  # noqa: E402
from rod_sim.io.series import read_rod_states  # noqa: E402
from rod_sim.io.scene_yaml import load_scene, scene_from_yaml_text, scene_to_yaml  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "paper_example.yaml"
PERIOD_NS = 10_000_000
DOMAIN_LOCKSTEP, DOMAIN_SIGTERM, DOMAIN_SIGKILL, DOMAIN_DEMO, DOMAIN_BAD = next_domains(5)
STARTUP_S = 40.0
"""[s] allowed for a node process to come up (compiling the kernels on a cold cache)."""


@pytest.fixture(scope="module", autouse=True)
def compiled_kernels():
    """Compile (or load) the reduced model's kernels once here, so node processes find them
    in the cache and start quickly."""
    sim = Simulator(make_model("reduced", load_scene(PAPER)), make_integrator("dop853-jit"))
    sim.advance(0.01)


class NodeProcess(ros_graph.NodeProcess):
    """``python -m rod_sim.ros.node --ros-args -p k:=v ...`` with output in files."""

    def __init__(self, tmp_path: Path, domain: int, **params):
        super().__init__(tmp_path, domain, name=f"node_{domain}",
                         command=("-m", "rod_sim.ros.node"), **params)


@pytest.fixture
def node_process(tmp_path):
    started = []

    def start(domain: int, **params) -> NodeProcess:
        p = NodeProcess(tmp_path, domain, **params)
        started.append(p)
        return p

    yield start
    for p in started:
        p.kill()


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def test_lockstep_subprocess_reproduces_the_offline_model(node_process, tmp_path, monkeypatch):
    """The seed's example driven over the topic: the tip pulse sampled at each period start
    and held, against Simulator.advance with the same held forces."""
    paper = load_scene(PAPER)
    scene = paper.with_changes(loads=())
    scene_file = tmp_path / "paper_no_loads.yaml"
    scene_file.write_text(scene_to_yaml(scene), encoding="utf-8")
    node = node_process(DOMAIN_LOCKSTEP, scene_file=scene_file, sync_mode=True)

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_LOCKSTEP))
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN_LOCKSTEP)
    client = Node("lockstep_client", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(client)
    states: dict[int, JointState] = {}
    try:
        pub = client.create_publisher(Float64MultiArray, "nodal_forces", 10)
        sub = client.create_subscription(JointState, "rod_states",
                                         lambda m: states.setdefault(stamp_ns(m), m), 10)

        def spin_until(condition, timeout, what):
            deadline = time.monotonic() + timeout
            while not condition():
                assert node.proc.poll() is None, f"node exited: {node.stderr}"
                assert time.monotonic() < deadline, f"timed out waiting for {what}"
                executor.spin_once(timeout_sec=0.01)

        spin_until(lambda: pub.get_subscription_count() > 0 and sub.get_publisher_count() > 0,
                   STARTUP_S, "the node")
        end = time.monotonic() + 0.5                 # let the node match our subscription too
        spin_until(lambda: time.monotonic() > end, 1.0, "settling")

        steps = 100                                   # 1 s: the whole Y pulse
        held = [paper.scripted_forces(k * PERIOD_NS / 1e9) for k in range(steps)]
        for k, forces in enumerate(held):
            msg = Float64MultiArray()
            msg.data = [float(v) for v in forces.ravel()]
            pub.publish(msg)
            spin_until(lambda: (k + 1) * PERIOD_NS in states, 10.0, f"state {k + 1}")
    finally:
        executor.shutdown()
        client.destroy_node()
        context.try_shutdown()
    assert node.stop() == 0

    offline = Simulator(make_model("reduced", scene), make_integrator("dop853-jit", rtol=1e-8))
    worst = 0.0
    for k, forces in enumerate(held):
        offline.set_forces(forces)
        offline.advance(PERIOD_NS / 1e9)
        msg = states[(k + 1) * PERIOD_NS]
        worst = max(worst, np.max(np.abs(np.asarray(msg.position) - offline.y[:8])),
                    np.max(np.abs(np.asarray(msg.velocity) - offline.y[8:16])))
    assert worst <= 1e-9
    assert np.max(np.abs(offline.y[:8])) > 0.05, "the pulse should have moved the chain"


def test_sigterm_closes_the_log_with_its_summary(node_process, tmp_path):
    log = tmp_path / "sigterm.mcap"
    node = node_process(DOMAIN_SIGTERM, scene_file=PAPER, record_path=log)
    node.wait_for_output("recording to")
    ros_graph.wait_for_states(DOMAIN_SIGTERM, 60, node)
    assert node.stop(signal.SIGTERM) == 0
    assert "log closed" in node.stderr
    with LogReader(log) as reader:
        assert reader.complete
        meta = reader.metadata()
        assert {"scene", "model", "integrator", "version"} <= set(meta)
        assert meta["model"] == "reduced" and meta["integrator"].startswith("dop853-jit rtol=1e-08")
        assert scene_from_yaml_text(meta["scene"]).n == 8
        assert "/rod_states" in reader.topics() and "/applied_forces" in reader.topics()
    t, phi, _ = read_rod_states(log)
    assert t[0] == 0.0 and len(t) >= 50
    np.testing.assert_allclose(np.diff(t), 0.01, atol=1e-12)
    with AnyReader([log], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        count = sum(1 for conn, _, raw in reader.messages()
                    if reader.deserialize(raw, conn.msgtype) is not None)
    assert count > 5 * len(t)


def _holders(path: Path) -> list[str]:
    """The processes that have ``path`` open (Linux /proc)."""
    found = []
    for fds in Path("/proc").glob("[0-9]*/fd"):
        try:
            if any(os.readlink(fd) == str(path) for fd in fds.iterdir()):
                found.append(fds.parent.name)
        except OSError:             # gone, or not ours to read
            continue
    return found


def test_sigkill_leaves_the_log_readable_to_its_last_chunk(node_process, tmp_path):
    log = tmp_path / "sigkill.mcap"
    node = node_process(DOMAIN_SIGKILL, scene_file=PAPER, record_path=log,
                        real_time_factor=0.0)
    node.wait_for_output("recording to")
    deadline = time.monotonic() + 30.0
    while not (log.exists() and log.stat().st_size > 400_000):
        assert time.monotonic() < deadline, "the log did not grow"
        time.sleep(0.05)
    node.proc.send_signal(signal.SIGKILL)
    assert node.proc.wait(timeout=10) == -signal.SIGKILL
    # its log writer (a child process) writes what it was handed and ends: nothing holds the
    # log open for long
    deadline = time.monotonic() + 15.0
    while _holders(log):
        assert time.monotonic() < deadline, f"processes {_holders(log)} still hold the log"
        time.sleep(0.05)
    with LogReader(log) as reader:
        assert not reader.complete
        assert reader.metadata()["model"] == "reduced"
    t, phi, _ = read_rod_states(log)
    assert t[0] == 0.0 and len(t) > 50 and np.all(np.isfinite(phi))
    np.testing.assert_allclose(np.diff(t), 0.01, atol=1e-12)


@pytest.mark.parametrize("params, match", [
    ({"scene_file": "/nonexistent/scene.yaml"}, "file not found"),
    ({"scene_file": str(PAPER), "model": "stiff"}, "unknown model"),
    ({"scene_file": "INVALID", "model": "reduced"}, "rods"),
    ({"scene_file": str(PAPER), "rate_hz": "-1.0"}, "rate_hz"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, params, match):
    if params["scene_file"] == "INVALID":
        bad = tmp_path / "bad.yaml"
        bad.write_text("rods: {count: 2, length: [1.0], mass_per_length: 1.0, "
                       "bending_stiffness: 1.0}\nnodes: {mass: 1.0}\n"
                       "hinges: {stiffness: 1.0, damping: 0.0}\n")
        params = dict(params, scene_file=str(bad))
    args = [sys.executable, "-m", "rod_sim.ros.node", "--ros-args"]
    for key, value in params.items():
        args += ["-p", f"{key}:={value}"]
    done = subprocess.run(args, cwd=REPO, env=ros_env(DOMAIN_BAD), capture_output=True,
                          text=True, timeout=STARTUP_S)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("sim_node: error:")]
    assert len(errors) == 1 and match in errors[0], done.stderr


def test_rod_sim_node_subcommand_is_the_node(tmp_path):
    """`rod-sim node --ros-args ...` hands the ROS arguments to the node untouched."""
    args = [sys.executable, "-m", "rod_sim.tools.cli", "node", "--ros-args",
            "-p", f"scene_file:={PAPER}", "-p", "model:=stiff"]
    done = subprocess.run(args, cwd=REPO, env=ros_env(DOMAIN_BAD), capture_output=True,
                          text=True, timeout=STARTUP_S)
    assert done.returncode == 2 and "unknown model" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr and "unrecognized arguments" not in done.stderr


def test_help_exits_0():
    done = subprocess.run([sys.executable, "-m", "rod_sim.ros.node", "--help"], cwd=REPO,
                          env=ros_env(DOMAIN_BAD), capture_output=True, text=True, timeout=30)
    assert done.returncode == 0 and "scene_file" in done.stdout


@pytest.mark.slow
def test_demo_runs_node_and_controller_and_records(tmp_path):
    out = tmp_path / "demo" / "demo.mcap"
    done = subprocess.run([sys.executable, "-m", "rod_sim.ros.demo", "--out", str(out),
                           "--duration", "0.5", "--sync"], cwd=REPO, env=ros_env(DOMAIN_DEMO),
                          capture_output=True, text=True, timeout=STARTUP_S)
    assert done.returncode == 0, done.stderr
    assert str(out) in done.stdout
    with LogReader(out) as reader:
        assert reader.complete
        commands = sum(1 for _ in reader.messages(["/nodal_forces"]))
    t, _, _ = read_rod_states(out)
    assert t[-1] == pytest.approx(0.5) and commands >= 50
    again = subprocess.run([sys.executable, "-m", "rod_sim.ros.demo", "--out", str(out)],
                           cwd=REPO, env=ros_env(DOMAIN_DEMO), capture_output=True, text=True,
                           timeout=STARTUP_S)
    assert again.returncode == 2 and "exists" in again.stderr
