"""The rod_sim node in this process with real rclpy: topics, commands, lockstep, services,
parameters, pacing and failures. Every test has its own context and ROS_DOMAIN_ID (LOCALHOST)."""
from __future__ import annotations

import math
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from rod_sim.io.log_reader import LogReader  # noqa: E402
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml  # noqa: E402
from rod_sim.ros.node import NodeConfigError, RodSimNode, params_files  # noqa: E402
from ros_domains import next_domain  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "paper_example.yaml"
SMALL = REPO / "config" / "small_chain.yaml"
PARAMS = REPO / "config" / "sim_node.params.yaml"
PERIOD_NS = 10_000_000


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def runnable_s() -> float:
    """[s] this thread has been runnable so far: on a CPU or waiting in a run queue for one
    (Linux schedstat), i.e. not sleeping. A busy loop is runnable all the time however loaded
    the machine is; a thread that waits for a timer is not."""
    on_cpu, queued, _ = Path("/proc/thread-self/schedstat").read_text().split()
    return (int(on_cpu) + int(queued)) / 1e9


def without_loads(path: Path, tmp_path: Path) -> Path:
    """A copy of a scene without scripted loads (applied forces = commands)."""
    out = tmp_path / f"{path.stem}_no_loads.yaml"
    out.write_text(scene_to_yaml(load_scene(path).with_changes(loads=())), encoding="utf-8")
    return out


def force_command(values) -> Float64MultiArray:
    msg = Float64MultiArray()
    msg.data = [float(v) for v in values]
    return msg


class Harness:
    """A RodSimNode and a test client node in one fresh context, spun by one executor."""

    def __init__(self, monkeypatch, ros_args=(), **params):
        self.domain = next_domain()
        monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        monkeypatch.setenv("ROS_DOMAIN_ID", str(self.domain))
        self.context = rclpy.Context()
        rclpy.init(args=["test", *ros_args] if ros_args else None, context=self.context,
                   domain_id=self.domain)
        self.nodes = []
        self.client = Node("test_client", context=self.context)
        self.nodes.append(self.client)
        self.received = defaultdict(list)
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        # as the node's process does: the params files of the ROS arguments locate scene_file
        self.node = RodSimNode(params_files(list(ros_args)), context=self.context,
                               parameter_overrides=overrides)
        self.nodes.append(self.node)
        self.executor = SingleThreadedExecutor(context=self.context)
        for node in self.nodes:
            self.executor.add_node(node)
        self.commands = self.client.create_publisher(Float64MultiArray, "nodal_forces", 10)

    def subscribe(self, topic: str, cls, qos=10) -> None:
        self.client.create_subscription(cls, topic, self.received[topic].append, qos)

    def spin_until(self, condition, timeout: float = 10.0, what: str = "condition") -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.01)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)

    def wait_matched(self, *topics) -> None:
        """Until the node's publishers see our subscriptions and it hears our commands."""
        self.spin_until(lambda: self.commands.get_subscription_count() > 0
                        and all(self.matched(t) > 0 for t in topics),
                        what="discovery")

    def matched(self, topic: str) -> int:
        """Subscriptions matched to the node's publisher of the output ``topic`` (its name
        in the output table: ``diagnostics`` is published on the absolute /diagnostics)."""
        return self.node._pubs[topic].get_subscription_count()

    def call(self, srv_type, name: str, request):
        client = self.client.create_client(srv_type, name)
        self.spin_until(client.service_is_ready, what=f"service {name}")
        future = client.call_async(request)
        self.spin_until(future.done, what=f"response of {name}")
        return future.result()

    def close(self) -> None:
        if not self.context.ok():
            return
        self.executor.shutdown()
        for node in reversed(self.nodes):
            node.destroy_node()
        self.context.try_shutdown()


def harness_fixture():
    """A ``harness`` fixture: ``harness(**params)`` makes a :class:`Harness` (in a ROS domain of
    its own, from ros_domains), closed after the test."""

    @pytest.fixture
    def harness(monkeypatch):
        made = []

        def make(**kwargs) -> Harness:
            h = Harness(monkeypatch, **kwargs)
            made.append(h)
            return h

        yield make
        for h in made:
            h.close()

    return harness


harness = harness_fixture()


def test_topics_types_and_sizes(harness):
    h = harness(scene_file=str(PAPER))
    for topic, cls in [("joint_states", JointState), ("rod_states", JointState),
                       ("bending", JointState), ("node_poses", PoseArray),
                       ("markers", MarkerArray), ("applied_forces", Float64MultiArray),
                       ("diagnostics", DiagnosticArray)]:
        h.subscribe(topic, cls)
    h.subscribe("/clock", Clock, QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    h.spin_until(lambda: h.received["diagnostics"] and len(h.received["markers"]) >= 5,
                 timeout=15.0, what="diagnostics and markers")

    types = dict(h.client.get_topic_names_and_types())
    expected = {"/joint_states": "sensor_msgs/msg/JointState",
                "/rod_states": "sensor_msgs/msg/JointState",
                "/bending": "sensor_msgs/msg/JointState",
                "/node_poses": "geometry_msgs/msg/PoseArray",
                "/markers": "visualization_msgs/msg/MarkerArray",
                "/applied_forces": "std_msgs/msg/Float64MultiArray",
                "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
                "/clock": "rosgraph_msgs/msg/Clock",
                "/nodal_forces": "std_msgs/msg/Float64MultiArray"}
    for topic, type_name in expected.items():
        assert types.get(topic) == [type_name], topic
    services = dict(h.client.get_service_names_and_types())
    assert services["/rod_sim/reset"] == ["std_srvs/srv/Trigger"]
    assert services["/rod_sim/step"] == ["std_srvs/srv/Trigger"]
    assert services["/rod_sim/pause"] == ["std_srvs/srv/SetBool"]

    n = 8
    js = h.received["joint_states"][-1]
    assert list(js.name) == [f"hinge_{k}" for k in range(n)]
    assert len(js.position) == len(js.velocity) == len(js.effort) == n
    rs = h.received["rod_states"][-1]
    assert list(rs.name) == [f"rod_{k}" for k in range(1, n + 1)] and len(rs.position) == n
    assert rs.header.frame_id == "world"
    bd = h.received["bending"][-1]
    assert list(bd.name) == [f"alpha_{k}" for k in range(1, n + 1)] + [
        f"beta_{k}" for k in range(1, n + 1)]
    assert len(h.received["node_poses"][-1].poses) == n + 1
    mk = h.received["markers"][-1].markers
    assert [m.ns for m in mk] == ["rods"] * n + ["nodes"]
    assert len(mk[0].points) >= 2 and len(mk[-1].points) == n
    assert len(h.received["applied_forces"][-1].data) == 2 * n
    status = h.received["diagnostics"][-1].status[0]
    keys = {kv.key for kv in status.values}
    assert {"real_time_factor_measured", "step_cost_mean_ms", "step_cost_max_ms", "sim_time_s",
            "energy_J", "energy_balance_residual_J", "commands_rejected",
            "max_abs_alpha_rad", "max_abs_beta_rad"} <= keys
    assert h.received["/clock"], "no /clock"

    # stamps are simulated time, whole control periods apart, the same on every state topic
    stamps = [stamp_ns(m) for m in h.received["rod_states"]]
    gaps = np.diff(stamps)
    assert np.all(gaps > 0) and np.all(gaps % PERIOD_NS == 0)
    # every period is published; an in-process client starved of CPU may miss some (KEEP_LAST)
    assert np.min(gaps) == PERIOD_NS
    assert stamp_ns(h.received["joint_states"][-1]) in stamps
    clock = h.received["/clock"][-1].clock
    assert (clock.sec * 1_000_000_000 + clock.nanosec) % PERIOD_NS == 0


def test_bad_commands_are_rejected_counted_and_the_last_valid_one_kept(harness, tmp_path):
    h = harness(scene_file=str(without_loads(SMALL, tmp_path)), command_timeout=0.0)
    h.subscribe("applied_forces", Float64MultiArray)
    h.subscribe("rod_states", JointState)
    h.subscribe("diagnostics", DiagnosticArray)
    h.wait_matched("rod_states", "diagnostics")
    valid = [1.0, -2.0, 3.0, -4.0, 5.0, -6.0]
    h.commands.publish(force_command(valid))
    h.spin_until(lambda: h.received["applied_forces"]
                 and list(h.received["applied_forces"][-1].data) == valid, what="valid command")
    h.commands.publish(force_command([1.0, 2.0, 3.0]))
    h.commands.publish(force_command([1.0, math.nan, 3.0, 4.0, 5.0, 6.0]))
    h.commands.publish(force_command([math.inf] * 6))
    h.spin_until(lambda: h.node.commands_rejected == 3, what="3 rejections")
    t_rejected = h.node.sim_time
    h.received["diagnostics"].clear()
    h.spin_until(lambda: h.received["diagnostics"], timeout=5.0, what="diagnostics")
    assert h.node.sim_time > t_rejected + 0.1, "the simulation stopped after bad commands"
    assert list(h.received["applied_forces"][-1].data) == valid
    values = {kv.key: kv.value for kv in h.received["diagnostics"][-1].status[0].values}
    assert values["commands_rejected"] == "3" and values["commands_received"] == "4"
    assert "non-finite" in values["last_rejection"]


def test_command_timeout_falls_back_to_zero_force(harness, tmp_path):
    h = harness(scene_file=str(without_loads(SMALL, tmp_path)), command_timeout=0.2)
    h.subscribe("applied_forces", Float64MultiArray)
    h.wait_matched("applied_forces")
    h.commands.publish(force_command([5.0] * 6))
    h.spin_until(lambda: any(list(m.data) == [5.0] * 6 for m in h.received["applied_forces"]),
                 what="the command applied")
    h.spin_until(lambda: list(h.received["applied_forces"][-1].data) == [0.0] * 6,
                 timeout=3.0, what="zero force after the timeout")


def drive_lockstep(h: Harness, commands) -> list:
    """Send each command after the state of the previous one arrived; returns the states."""
    h.subscribe("rod_states", JointState)
    h.wait_matched("rod_states")
    for k, values in enumerate(commands):
        h.commands.publish(force_command(values))
        target = (k + 1) * PERIOD_NS
        h.spin_until(lambda: any(stamp_ns(m) == target for m in h.received["rod_states"]),
                     what=f"state at {target} ns")
    return [m for m in h.received["rod_states"] if stamp_ns(m) > 0]


def test_lockstep_is_one_period_per_command_and_deterministic(harness, tmp_path):
    scene = str(without_loads(PAPER, tmp_path))
    rng = np.random.default_rng(2024)
    commands = rng.normal(scale=200.0, size=(30, 16))
    runs = []
    for run in range(2):
        log = tmp_path / f"lockstep_{run}.mcap"
        h = harness(scene_file=scene, sync_mode=True, record_path=str(log))
        h.spin_for(0.3)
        assert h.node.sim_time == 0.0, "lockstep advanced before the first command"
        states = drive_lockstep(h, commands)
        assert [stamp_ns(m) for m in states] == [(k + 1) * PERIOD_NS for k in range(30)]
        h.spin_for(0.3)
        assert h.node.sim.t_ns == 30 * PERIOD_NS, "lockstep advanced without a command"
        h.close()
        runs.append((states, log))

    (states_a, log_a), (states_b, log_b) = runs
    for a, b in zip(states_a, states_b):
        assert list(a.position) == list(b.position) and list(a.velocity) == list(b.velocity)

    def decoded(path):
        with LogReader(path) as reader:
            assert reader.complete
            return [(topic, t, repr(msg)) for topic, t, msg in reader.messages()
                    if topic != "/diagnostics"]      # wall-clock measurements differ by design

    messages = decoded(log_a)
    assert messages == decoded(log_b)
    topics_logged = {m[0] for m in messages}
    assert {"/nodal_forces", "/applied_forces", "/rod_states", "/joint_states", "/bending",
            "/node_poses", "/markers"} <= topics_logged
    assert sum(m[0] == "/nodal_forces" for m in messages) == 30
    assert sum(m[0] == "/rod_states" for m in messages) == 31     # t = 0 and 30 periods
    # markers_rate_hz 50 at rate_hz 100: the states of every second period, from t = 0
    assert [t for topic, t, _ in messages if topic == "/markers"] == [
        k * 2 * PERIOD_NS for k in range(16)]


@pytest.mark.parametrize("markers_rate_hz, every", [(0.0, 1), (30.0, 3), (1000.0, 1)])
def test_markers_on_every_kth_period(harness, tmp_path, markers_rate_hz, every):
    h = harness(scene_file=str(SMALL), sync_mode=True, markers_rate_hz=markers_rate_hz)
    h.subscribe("markers", MarkerArray)
    h.wait_matched("markers")
    drive_lockstep(h, np.zeros((7, 6)))
    h.spin_for(0.2)
    stamps = sorted({m.markers[0].header.stamp.nanosec + 10**9 * m.markers[0].header.stamp.sec
                     for m in h.received["markers"]})
    assert stamps == [k * PERIOD_NS for k in range(1, 8) if k % every == 0]


def test_services_pause_step_reset(harness):
    h = harness(scene_file=str(SMALL))
    h.spin_until(lambda: h.node.sim_time >= 0.1, what="running")
    refused = h.call(Trigger, "/rod_sim/step", Trigger.Request())
    assert not refused.success and "paused" in refused.message

    paused = h.call(SetBool, "/rod_sim/pause", SetBool.Request(data=True))
    assert paused.success and h.node.control.paused
    t_ns = h.node.sim.t_ns
    h.spin_for(0.3)
    assert h.node.sim.t_ns == t_ns, "time went on while paused"
    stepped = h.call(Trigger, "/rod_sim/step", Trigger.Request())
    assert stepped.success and h.node.sim.t_ns == t_ns + PERIOD_NS

    reset = h.call(Trigger, "/rod_sim/reset", Trigger.Request())
    assert reset.success and h.node.sim.t_ns == 0
    np.testing.assert_array_equal(h.node.sim.y, h.node.model.initial_state())
    h.spin_for(0.2)
    assert h.node.sim.t_ns == 0, "a reset must not resume a paused simulation"

    resumed = h.call(SetBool, "/rod_sim/pause", SetBool.Request(data=False))
    assert resumed.success and not h.node.control.paused
    start = time.monotonic()
    h.spin_until(lambda: h.node.sim_time >= 0.2, what="running again")
    assert time.monotonic() - start < 1.0, "resuming must not catch up the paused time"


def test_parameters_from_the_params_file_and_descriptors(harness):
    h = harness(ros_args=["--ros-args", "--params-file", str(PARAMS),
                          "-p", f"scene_file:={PAPER}"])
    s = h.node.settings
    assert (s.model, s.rate_hz, s.real_time_factor, s.sync_mode, s.record_path) == (
        "reduced", 100.0, 1.0, False, "")
    assert (s.command_timeout, s.integrator, s.publish_clock, s.frame_id, s.markers_rate_hz) == (
        0.5, "dop853-jit", True, "world", 50.0)
    descriptors = h.node.describe_parameters(["scene_file", "model", "rate_hz",
                                              "real_time_factor", "command_timeout"])
    assert [d.read_only for d in descriptors] == [True, True, True, False, False]
    assert "[Hz]" in descriptors[2].description and "[s]" in descriptors[4].description
    assert descriptors[3].floating_point_range[0].from_value == 0.0

    assert not h.node.set_parameters([Parameter("scene_file", value="x.yaml")])[0].successful
    assert not h.node.set_parameters([Parameter("real_time_factor", value=1e6)])[0].successful
    assert not h.node.set_parameters([Parameter("frame_id", value="")])[0].successful
    assert h.node.set_parameters([Parameter("real_time_factor", value=0.0)])[0].successful
    t0, wall0, runnable0 = h.node.sim_time, time.monotonic(), runnable_s()
    h.spin_for(0.5)
    advanced, wall = h.node.sim_time - t0, time.monotonic() - wall0
    runnable = runnable_s() - runnable0
    # as fast as possible: twice real time or more where this process gets the CPU; on a
    # machine too busy to afford that, it still never waits for the wall clock (the node's
    # thread runnable all along: 99.7 % of the window measured at load 8, where a node paced at
    # real time was runnable 68 % of it: it sleeps between ticks)
    assert advanced > 2.0 * wall or runnable > 0.95 * wall, \
        f"real_time_factor 0: {advanced:.2f} s in {wall:.2f} s, runnable {runnable:.2f} s"


@pytest.mark.parametrize("params, match", [
    ({}, "scene_file: parameter is required"),
    ({"scene_file": "/nonexistent/scene.yaml"}, "file not found"),
    ({"scene_file": str(PAPER), "model": "stiff"}, "unknown model 'stiff'"),
    ({"scene_file": str(PAPER), "integrator": "magic"}, "unknown integrator 'magic'"),
    ({"scene_file": str(PAPER), "rate_hz": -5.0}, "rate_hz"),
    ({"scene_file": str(PAPER), "rate_hz": 100}, "rate_hz"),
])
def test_bad_parameters_raise_one_line_errors(harness, params, match):
    with pytest.raises(NodeConfigError, match=match) as err:
        harness(**params)
    assert "\n" not in str(err.value)


def test_real_time_pacing_within_bounds(harness):
    h = harness(scene_file=str(PAPER), rate_hz=100.0, real_time_factor=1.0)
    h.subscribe("diagnostics", DiagnosticArray)
    h.spin_until(lambda: h.node.sim_time > 0.1, what="start")
    wall0, sim0 = time.monotonic(), h.node.sim_time
    h.spin_for(2.0)
    rtf = (h.node.sim_time - sim0) / (time.monotonic() - wall0)
    values = [{kv.key: kv.value for kv in m.status[0].values}
              for m in h.received["diagnostics"][1:]]
    measured = [float(v["real_time_factor_measured"]) for v in values]
    assert measured and rtf < 1.2 and all(r < 1.2 for r in measured), (rtf, measured)
    # never ahead of real time; behind it only where this process could not get the CPU to
    # keep pace (a loaded machine), and then the node says so: it drops the backlog it cannot
    # catch up within 1 s and counts it on diagnostics
    dropped = int(values[-1]["dropped_periods"])
    assert dropped > 0 or (rtf > 0.8 and all(r > 0.8 for r in measured)), (rtf, measured)


def test_integration_failure_pauses_reports_and_recovers(harness, tmp_path):
    h = harness(scene_file=str(without_loads(SMALL, tmp_path)))
    h.subscribe("diagnostics", DiagnosticArray)
    h.wait_matched("diagnostics")
    h.commands.publish(force_command([1e300] * 6))
    h.spin_until(lambda: h.node.control.error is not None, what="the integration failure")
    assert h.node.control.paused and np.all(np.isfinite(h.node.sim.y))
    h.spin_until(lambda: any(m.status[0].level == b"\x02" for m in h.received["diagnostics"]),
                 what="an ERROR diagnostic")
    error = next(m.status[0] for m in h.received["diagnostics"] if m.status[0].level == b"\x02")
    assert "integration error" in error.message
    h.commands.publish(force_command([0.0] * 6))
    reset = h.call(Trigger, "/rod_sim/reset", Trigger.Request())
    assert reset.success and h.node.control.error is None
    h.call(SetBool, "/rod_sim/pause", SetBool.Request(data=False))
    h.spin_until(lambda: h.node.sim_time > 0.1, what="running after the reset")
    assert h.node.control.error is None


def test_overload_reports_slow_real_time_factor_and_stays_responsive(harness, tmp_path):
    """Stepping and recording 10 000 periods per wall second cannot keep up (a period's own
    work with its outputs, ~0.23 ms in-process at n = 8, `rate_bench --period-cost`, is more
    than twice the 0.1 ms it may take; at 2000 Hz a quiet machine keeps up: rate_bench
    measured RTF 0.986 at load 0.6, and a flake hunt repeat at load 1.5 saw no warning in
    10 s): the node drops backlog instead of stalling, says so on diagnostics and still
    serves requests."""
    h = harness(scene_file=str(PAPER), rate_hz=10000.0, real_time_factor=1.0,
                record_path=str(tmp_path / "overload.mcap"))
    h.subscribe("diagnostics", DiagnosticArray)

    def slow(m) -> bool:
        values = {kv.key: kv.value for kv in m.status[0].values}
        return (m.status[0].level == b"\x01" and "slower than real time" in m.status[0].message
                and float(values["real_time_factor_measured"]) < 0.9
                and int(values["dropped_periods"]) > 0)

    h.spin_until(lambda: any(slow(m) for m in h.received["diagnostics"]), timeout=10.0,
                 what="a diagnostics warning about the real-time factor")
    start = time.monotonic()
    response = h.call(SetBool, "/rod_sim/pause", SetBool.Request(data=True))
    assert response.success and time.monotonic() - start < 1.0


def test_energy_balance_residual_of_the_rigid_model_is_small(harness):
    h = harness(scene_file=str(PAPER), model="rigid", real_time_factor=0.0)
    h.spin_until(lambda: h.node.sim_time >= 2.0, what="2 s of simulated time")
    h.call(SetBool, "/rod_sim/pause", SetBool.Request(data=True))
    report = h.node.diagnostic_report()
    assert report.energy > 1000.0                 # the tip pulse put energy in
    assert abs(report.energy_residual) < 1e-5 * report.energy
