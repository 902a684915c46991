"""The node under bad, extreme and unusual use (issues 11 and 13), in this process with real
rclpy: log lines never raise, a 1e12 N command fails fast with a named cause while services
answer, oversize commands, recording after a reset, duplicate names, namespaces and the params
file, /diagnostics, /clock while paused, start_paused, ~/step with a count, the lockstep t = 0
state. ROS domain ids from ros_domains (one per context, LOCALHOST)."""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

import test_node_ros as base  # noqa: E402
from ros_domains import next_domain  # noqa: E402
from rod_sim.io.log_reader import LogReader  # noqa: E402
from rod_sim.io.scene_yaml import load_scene  # noqa: E402
from rod_sim.io.topics import DIAGNOSTICS_STATUS_NAME  # noqa: E402
from rod_sim.ros.node import (NodeConfigError, RodSimNode,  # noqa: E402
                              has_hinge_events, params_files)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90)]

REPO = Path(__file__).resolve().parents[1]
PAPER, SMALL, PARAMS = base.PAPER, base.SMALL, base.PARAMS
PERIOD_NS = base.PERIOD_NS
force_command, without_loads, stamp_ns = base.force_command, base.without_loads, base.stamp_ns


harness = base.harness_fixture()


def diag_values(msg) -> dict[str, str]:
    return {kv.key: kv.value for kv in msg.status[0].values}


def timed_call(h, srv_type, name, request):
    """(response, seconds from the call to its response; the client is ready first)."""
    client = h.client.create_client(srv_type, name)
    h.spin_until(client.service_is_ready, what=f"service {name}")
    start = time.monotonic()
    future = client.call_async(request)
    h.spin_until(future.done, timeout=20.0, what=f"response of {name}")
    return future.result(), time.monotonic() - start


# ----- issue 11: the node -----

def test_log_lines_of_every_severity_never_raise(harness, tmp_path):
    """A timeout (INFO), then a malformed command (WARN) from the one throttled logger crashed
    rclpy with 'Logger severity cannot be changed between calls'."""
    h = harness(scene_file=str(without_loads(SMALL, tmp_path)), command_timeout=0.1)
    h.wait_matched()
    h.commands.publish(force_command([1.0] * 6))
    h.spin_until(lambda: h.node.inputs.forces.active, what="the command held")
    h.spin_until(lambda: not h.node.inputs.forces.active, what="the command timeout")
    h.commands.publish(force_command([1.0, 2.0]))
    h.spin_until(lambda: h.node.commands_rejected == 1, what="the rejection")
    t = h.node.sim_time
    h.spin_for(0.3)
    assert h.node.sim_time > t, "the node stopped after a rejection"
    for level in ("error", "info", "warning", "info", "error"):   # one key: one call site
        h.node._throttle.until.clear()
        h.node._throttle.log("one key", level, f"a {level} line")


def test_huge_command_fails_fast_with_a_named_cause_and_services_answer(harness, tmp_path):
    """1e12 N held: each 10 ms period would cost seconds (50 000 steps). The work budget
    stops the period, the node pauses with ERROR and services answer at once."""
    h = harness(scene_file=str(without_loads(PAPER, tmp_path)), max_period_cost=0.3)
    h.subscribe("/diagnostics", DiagnosticArray)
    h.wait_matched("diagnostics")
    h.spin_until(lambda: h.received["/diagnostics"], what="diagnostics")
    start = time.monotonic()
    h.commands.publish(force_command([1e12] * 16))
    h.spin_until(lambda: h.node.control.error is not None, timeout=10.0, what="the failure")
    assert time.monotonic() - start < 5.0
    assert "work budget exceeded" in h.node.control.error and "max_period_cost" in h.node.control.error
    assert "1e+12 N" in h.node.control.error, h.node.control.error    # names the force that did it
    assert h.node.control.paused and np.all(np.isfinite(h.node.sim.y))
    h.spin_until(lambda: any(m.status[0].level == b"\x02" and "work budget" in m.status[0].message
                             for m in h.received["/diagnostics"]),
                 timeout=3.0, what="ERROR on /diagnostics")
    response, latency = timed_call(h, Trigger, "/rod_sim/step", Trigger.Request())
    assert not response.success and "work budget" in response.message
    assert latency < 2.0, f"~/step answered after {latency:.2f} s"
    response, latency = timed_call(h, SetBool, "/rod_sim/pause", SetBool.Request(data=True))
    assert response.success and latency < 2.0


def test_work_budget_is_measured_and_ordinary_periods_stay_within_it(harness):
    h = harness(scene_file=str(PAPER), real_time_factor=0.0, max_period_cost=0.2)
    b = h.node._budget
    assert b.unit == "steps" and 50 <= b.limit and b.unit_cost_s > 0
    # docs/interface.md section 6: max_period_cost / (2 x the measured step cost), at least 50
    assert b.limit == max(50, int(0.2 / (2 * b.unit_cost_s)))
    assert h.node.sim.integrator.max_steps == b.limit
    h.spin_until(lambda: h.node.sim_time > 2.0, what="2 s through the tip pulse")
    assert h.node.control.error is None


def test_oversize_and_undecodable_commands_are_refused_by_length(harness, tmp_path):
    h = harness(scene_file=str(without_loads(SMALL, tmp_path)), command_timeout=0.0,
                record_path=str(tmp_path / "big.mcap"))
    h.wait_matched()
    valid = [1.0, -2.0, 3.0, -4.0, 5.0, -6.0]
    h.commands.publish(force_command(valid))
    h.spin_until(lambda: h.node.inputs.forces.latest is not None, what="the valid command")
    big = Float64MultiArray()
    big.data = np.zeros(1_000_000).tolist()         # 8 MB
    h.commands.publish(big)
    h.spin_until(lambda: h.node.commands_rejected == 1, timeout=20.0, what="the rejection")
    assert "bytes, more than" in h.node.inputs.forces.last_rejection
    h.node._on_command_bytes(b"\x00\x01\x00\x00\x05")   # not a Float64MultiArray
    assert h.node.commands_rejected == 2 and "cannot be decoded" in h.node.inputs.forces.last_rejection
    np.testing.assert_array_equal(h.node.inputs.forces.latest.forces.ravel(), valid)
    t = h.node.sim_time
    h.spin_for(0.3)
    assert h.node.sim_time > t
    h.close()
    with LogReader(tmp_path / "big.mcap") as reader:
        commands = [msg for topic, _, msg in reader.messages() if topic == "/nodal_forces"]
    assert [list(m.data) for m in commands] == [valid]    # the oversize one is not recorded


def test_recording_after_reset_skips_existing_files_and_reports_failures(harness, tmp_path):
    log = tmp_path / "run.mcap"
    taken = tmp_path / "run_1.mcap"
    taken.write_bytes(b"someone else's file")
    h = harness(scene_file=str(SMALL), record_path=str(log))
    h.spin_until(lambda: h.node.sim_time > 0.05, what="running")
    response = h.call(Trigger, "/rod_sim/reset", Trigger.Request())
    assert response.success and "run_2.mcap" in response.message
    assert h.node.log_path == tmp_path / "run_2.mcap"
    assert taken.read_bytes() == b"someone else's file"
    level, _, values = h.node.diagnostic_report().status()
    assert values["recording_error"] == "none"

    def refuse(path):
        raise NodeConfigError(f"record_path: cannot create {path}")

    h.node._recording._open_log = refuse
    response = h.call(Trigger, "/rod_sim/reset", Trigger.Request())
    assert "recording stopped" in response.message and h.node.log_path is None
    level, message, _ = h.node.diagnostic_report().status()
    assert level == 2 and "recording stopped: record_path: cannot create" in message


def test_a_second_node_of_the_same_name_is_reported(harness, tmp_path):
    h = harness(scene_file=str(SMALL))
    timers = len(list(h.node.timers))
    h.spin_for(2.5)
    assert h.node.diagnostic_report().values()["name_conflict"] == "false"
    assert len(list(h.node.timers)) == timers - 1      # the one-shot check's timer is gone
    twin = RodSimNode(context=h.context, parameter_overrides=[
        Parameter("scene_file", value=str(SMALL))])
    h.nodes.append(twin)
    h.executor.add_node(twin)
    h.spin_until(lambda: twin.diagnostic_report().values()["name_conflict"] == "true",
                 timeout=10.0, what="the duplicate-name warning")
    level, message, _ = twin.diagnostic_report().status()
    assert level == 1 and "2 nodes named /rod_sim" in message and "-r __node:=" in message


# ----- issue 13: ROS conventions -----

def test_namespace_params_file_resolved_names_and_absolute_diagnostics(harness, tmp_path,
                                                                       monkeypatch):
    """The shipped params file applies under a namespace; topics and the log use resolved
    names; /diagnostics stays absolute; hinge_events exist only for scenes with events."""
    monkeypatch.chdir(tmp_path)     # the params file's scene is found next to it, not here
    log = tmp_path / "arm1.mcap"
    h = harness(ros_args=["--ros-args", "-r", "__ns:=/arm1", "--params-file", str(PARAMS),
                          "-p", f"record_path:={log}"])
    assert h.node.settings.scene_file == "paper_example.yaml"
    assert h.node.scene_path == PARAMS.parent / "paper_example.yaml"
    h.subscribe("/diagnostics", DiagnosticArray)
    h.subscribe("rod_states", JointState)            # the client is in /arm1 too
    h.wait_matched("rod_states", "diagnostics")
    h.commands.publish(force_command([0.0] * 16))
    h.spin_until(lambda: h.received["/diagnostics"] and len(h.received["rod_states"]) > 3,
                 what="states and diagnostics")
    names = dict(h.client.get_topic_names_and_types())
    assert {"/arm1/rod_states", "/arm1/nodal_forces", "/arm1/applied_forces",
            "/diagnostics"} <= set(names)
    assert "/arm1/diagnostics" not in names and "/rod_states" not in names
    assert not any(name.endswith("hinge_events") for name in names)
    services = dict(h.client.get_service_names_and_types())
    assert "/arm1/rod_sim/pause" in services
    status = h.received["/diagnostics"][-1].status[0]
    assert status.name == DIAGNOSTICS_STATUS_NAME == "rod_sim: simulation"
    assert diag_values(h.received["/diagnostics"][-1])["node"] == "/arm1/rod_sim"
    h.close()
    with LogReader(log) as reader:
        logged = {topic for topic, _, _ in reader.messages()}
    assert {"/arm1/rod_states", "/arm1/joint_states", "/arm1/applied_forces",
            "/arm1/nodal_forces", "/diagnostics"} <= logged
    assert not any(t.startswith("/rod_states") for t in logged)


def test_params_file_for_another_name_is_explained(tmp_path, monkeypatch):
    params = tmp_path / "old.params.yaml"
    params.write_text(f"rod_sim:\n  ros__parameters:\n    scene_file: {SMALL}\n")
    args = ["--ros-args", "-r", "__ns:=/arm1", "--params-file", str(params)]
    assert params_files(args) == (str(params),)
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = next_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    context = rclpy.Context()
    rclpy.init(args=["test", *args], context=context, domain_id=domain)
    try:
        with pytest.raises(NodeConfigError) as err:
            RodSimNode(context=context, params_files=params_files(args))
    finally:
        context.try_shutdown()
    text = str(err.value)
    assert "scene_file: parameter is required" in text and str(params) in text
    assert "/arm1/rod_sim" in text and "/**" in text and "\n" not in text


def test_shipped_params_file_is_namespace_agnostic_and_complete():
    import yaml

    from rod_sim.ros.node import PARAMETERS

    data = yaml.safe_load(PARAMS.read_text())
    assert list(data) == ["/**"]
    assert set(data["/**"]["ros__parameters"]) == {p.name for p in PARAMETERS}


def test_hinge_events_only_for_scenes_with_latches_or_stops():
    assert not has_hinge_events(load_scene(PAPER))
    assert has_hinge_events(load_scene(REPO / "config" / "deployment.yaml"))


def test_start_paused_clock_while_paused_step_count_and_first_command(harness, tmp_path):
    h = harness(scene_file=str(without_loads(SMALL, tmp_path)), start_paused=True)
    h.subscribe("/clock", Clock, 10)                 # default QoS: reliable
    h.spin_until(lambda: len(h.received["/clock"]) >= 5, timeout=10.0, what="/clock while paused")
    assert h.node.sim.t_ns == 0 and h.node.control.paused
    assert all(m.clock.sec == 0 and m.clock.nanosec == 0 for m in h.received["/clock"])
    assert "start_paused" in h.node.diagnostic_report().state
    info = h.client.get_publishers_info_by_topic("/clock")
    assert [i.qos_profile.reliability for i in info] == [ReliabilityPolicy.RELIABLE]

    assert h.node.set_parameters([Parameter("step_count", value=5)])[0].successful
    assert not h.node.set_parameters([Parameter("step_count", value=0)])[0].successful
    stepped = h.call(Trigger, "/rod_sim/step", Trigger.Request())
    assert stepped.success and h.node.sim.t_ns == 5 * PERIOD_NS and h.node.control.paused
    h.spin_for(0.3)                                  # the frozen time after the step
    assert h.received["/clock"][-1].clock.nanosec == 5 * PERIOD_NS

    h.wait_matched()
    h.commands.publish(force_command([0.0] * 6))     # the first command starts the clock
    h.spin_until(lambda: h.node.sim_time > 0.2, what="running after the first command")
    assert not h.node.control.paused


def test_start_paused_resumes_with_pause_false_and_clock_reliability_parameter(harness):
    h = harness(scene_file=str(SMALL), start_paused=True, clock_reliability="best_effort")
    h.spin_for(0.3)
    assert h.node.sim.t_ns == 0
    info = h.client.get_publishers_info_by_topic("/clock")
    assert [i.qos_profile.reliability for i in info] == [ReliabilityPolicy.BEST_EFFORT]
    h.call(SetBool, "/rod_sim/pause", SetBool.Request(data=False))
    h.spin_until(lambda: h.node.sim_time > 0.1, what="running after ~/pause false")
    with pytest.raises(NodeConfigError, match="clock_reliability: unknown value 'sometimes'"):
        harness(scene_file=str(SMALL), clock_reliability="sometimes")


def test_lockstep_publishes_its_t0_state_to_late_transient_local_subscribers(harness):
    h = harness(scene_file=str(SMALL), sync_mode=True, bogus_parameter=1.0)
    assert h.node.diagnostic_report().values()["unknown_parameters"] == "bogus_parameter"
    h.spin_for(0.3)                                    # no subscriber when t = 0 was published
    late = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    h.subscribe("rod_states", JointState, late)
    h.spin_until(lambda: h.received["rod_states"], what="the t = 0 state")
    assert stamp_ns(h.received["rod_states"][0]) == 0 and h.node.sim.t_ns == 0
    h.wait_matched("rod_states")
    h.commands.publish(force_command([0.0] * 6))
    h.spin_until(lambda: stamp_ns(h.received["rod_states"][-1]) == PERIOD_NS,
                 what="the state of the first period")
    assert not math.isnan(h.received["rod_states"][-1].position[0])
