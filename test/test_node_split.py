"""The parts the node is wired from (issue 26 item 3), each without a ROS graph: the inputs
(held inputs, timeout, lockstep queue), the run control (pause, step, busy, interrupted),
the output table (one encoding to every sink, dividers, applied inputs on change), one
control period (ledger, failure), a period with its outputs (the stepper), the diagnostics
(the monitor), the service adapters, the resolved topic names and /clock."""
from __future__ import annotations

import asyncio
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock as RosClock
from std_msgs.msg import Float64MultiArray, String

from rod_sim.api import load_scene
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator
from rod_sim.io import encoders, topics
from rod_sim.ros import budget
from rod_sim.ros.command_layout import CommandLayout
from rod_sim.ros.commands import FORCES, TORQUES, WRENCH
from rod_sim.ros.control import RunControl, answering, executor_turn
from rod_sim.ros.inputs import Inputs
from rod_sim.ros.monitor import NodeMonitor
from rod_sim.io.topics import divider
from rod_sim.ros.outputs import (OUTPUTS, STATE_TOPICS, Outputs, SimClock, create_clock,
                                 rate_dividers, resolved_names)
from rod_sim.ros.pacing import Pacing
from rod_sim.ros.period import PeriodRunner
from rod_sim.ros.stepper import Stepper

REPO = Path(__file__).resolve().parents[1]

sys.path.insert(0, str(Path(__file__).parent))
from test_encoders import make_scene, make_snapshot  # noqa: E402


def raw(values) -> bytes:
    return serialize_message(Float64MultiArray(data=[float(v) for v in values]))


def test_inputs_hold_time_out_and_queue_in_lockstep():
    inputs = Inputs(2, timeout_s=0.1)
    recorded = []

    def rec(msg, data):
        recorded.append(msg)

    cmd, warning = inputs.receive(raw([1, 2, 3, 4]), inputs.forces, 0, rec)
    assert cmd is not None and not warning and len(recorded) == 1
    held, notes = inputs.held(50_000_000, wall_age=False)
    np.testing.assert_array_equal(held, [[1, 2, 0], [3, 4, 0]])
    held, notes = inputs.held(200_000_000, wall_age=False)        # 0.2 s > timeout
    assert not held.any() and notes[0][0] == FORCES and "set to zero" in notes[0][1]
    cmd, warning = inputs.receive(raw([1, 2, 3]), inputs.forces, 0, rec)
    assert cmd is None and "rejected a nodal_forces command" in warning
    assert inputs.rejection.startswith("nodal_forces: ")
    # lockstep: a torque command keeps the forces of the forces command before it
    torque, _ = inputs.receive(raw([5, 6]), inputs.torques, 0, rec)
    force, _ = inputs.receive(raw([1, 1, 2, 2]), inputs.forces, 0, rec)
    inputs.queue.extend([force, torque])
    np.testing.assert_array_equal(inputs.next_queued(), [[1, 1, 0], [2, 2, 0]])
    np.testing.assert_array_equal(inputs.next_queued(), [[1, 1, 5], [2, 2, 6]])
    assert inputs.counts()["hinge_torques_received"] == "1"
    inputs.receive(raw([7]), inputs.torques, 0, rec)                  # 1 value for 2 hinges
    assert (inputs.total("received"), inputs.total("rejected")) == (5, 2)
    inputs.clear()
    assert not inputs.any_command() and not inputs.queue


def run(coro):
    return asyncio.new_event_loop().run_until_complete(coro)


def test_run_control_pause_step_busy_and_interrupted():
    control = RunControl(sync_mode=False, start_paused=True, rtf=1.0)
    assert control.state(False).startswith("paused at start") and not control.running()
    assert control.first_command() and control.running() and not control.first_command()
    steps = []

    async def turn():
        return None
    ok, message = run(control.step(3, lambda: steps.append(1) or True, lambda: 0.5, turn, 1.0))
    assert not ok and message.startswith("~/step works only while paused")
    control.pause(True, 0.5)
    ok, message = run(control.step(3, lambda: steps.append(1) or True, lambda: 0.5, turn, 1.0))
    assert ok and len(steps) == 3 and message == "stepped to t = 0.5 s"

    async def reset_between():              # a reset while the call waits for its next turn
        control.reset()
    steps.clear()
    ok, message = run(control.step(5, lambda: time.sleep(0.002) or steps.append(1) or True,
                                   lambda: 0.0, reset_between, 0.001))   # one period a slice
    assert not ok and message.startswith("interrupted by ~/reset after 1 of 5")
    control.stepping = True
    ok, message = run(control.step(1, lambda: True, lambda: 0.0, turn, 1.0))
    assert not ok and message.startswith("busy")
    control.fail("boom")
    assert control.state(True) == "error"
    assert control.pause(False, 1.0) == "resumed at t = 1 s (after the integration error: boom)"


class Sink:
    """A publisher (publish) and a recording (record_cdr) that keep what they get."""

    def __init__(self):
        self.items = []

    def publish(self, data):
        self.items.append(data)

    def record_cdr(self, topic, type_name, t_ns, data):
        self.items.append((topic, type_name, t_ns, data))


def test_outputs_send_one_encoding_to_every_sink():
    scene = make_scene(3)
    snap = make_snapshot(scene, seed=4, t=0.02)
    pubs = {o.name: Sink() for o in OUTPUTS}
    log = Sink()
    taps = []
    out = Outputs(scene, {o.name: f"/ns/{o.name}" for o in OUTPUTS}, pubs, log, 10_000_000,
                  "world", {"markers": divider(100.0, 25.0)})
    out.taps.append(lambda s, t, enc: taps.append(enc))
    out.state(snap, 20_000_000)                  # period 2: markers every 4th -> not due
    # a plain chain: every state topic but markers (not due) and base_odometry (moving bases)
    assert [item[0] for item in log.items] == [f"/ns/{n}" for n in STATE_TOPICS
                                               if n not in ("markers", "base_odometry")]
    for topic, type_name, t_ns, data in log.items:
        name = topic.rsplit("/", 1)[1]
        assert pubs[name].items == [data] and taps[0][name] is data
        assert data == encoders.SNAPSHOT_ENCODERS[name](snap, scene, "world")
        assert type_name == topics.TOPIC_TYPES[name] and t_ns == 20_000_000
    assert not pubs["markers"].items
    out.state(snap, 40_000_000, record=False)      # period 4: markers due; not recorded
    assert pubs["markers"].items and len(log.items) == len(STATE_TOPICS) - 2
    assert not pubs["base_odometry"].items
    forces = np.ones((3, 2))
    out.applied(0, forces, np.zeros(3))
    out.applied(10_000_000, forces.copy(), np.zeros(3))   # unchanged: recorded only
    assert len(pubs["applied_forces"].items) == 1
    assert sum(item[0] == "/ns/applied_forces" for item in log.items) == 2
    # a sign of zero is a change of the bytes: recorded as encoded, published again
    out.applied(20_000_000, forces, -np.zeros(3))
    recorded = [item[3] for item in log.items if item[0] == "/ns/applied_torques"]
    oracle = serialize_message(Float64MultiArray(data=[-0.0] * 3))
    assert recorded[-1][-24:] == oracle[-24:] and recorded[-1] != recorded[0]
    assert len(pubs["applied_torques"].items) == 2
    # every record is the encoding of the values of its period
    for (_, _, t_ns, data), values in zip(
            [item for item in log.items if item[0] == "/ns/applied_forces"],
            [forces, forces, forces]):
        assert data[-48:] == serialize_message(
            Float64MultiArray(data=[float(v) for v in values.ravel()]))[-48:]


def test_period_runner_books_the_ledger_and_reports_a_failure():
    scene = make_scene(3)
    model = make_model("reduced", scene)
    sim = Simulator(model, make_integrator("dop853-jit"))
    runner = PeriodRunner(sim, budget.fallback(sim.integrator, 0.5), 10_000_000)
    applied = []
    for _ in range(20):
        snap = runner.run(np.zeros((3, 2)), applied.append)
        assert snap is not None
    assert applied == [k * 10_000_000 for k in range(20)] and sim.t_ns == 200_000_000
    assert abs(runner.ledger.residual) < 1e-6 * max(1.0, runner.ledger.scale)
    runner.note_state(make_snapshot(scene, seed=1))
    assert runner.take_extremes()[0] > 0 and runner.take_extremes() == (0.0, 0.0)
    t_ns, y = sim.t_ns, sim.y.copy()
    assert runner.run(np.full((3, 2), 1e300)) is None
    assert "at t = " in runner.error and sim.t_ns == t_ns
    np.testing.assert_array_equal(sim.y, y)
    runner.reset()
    assert sim.t_ns == 0 and runner.error is None


@pytest.mark.parametrize("rate, topic_rate, k", [(100.0, 50.0, 2), (100.0, 0.0, 1),
                                                 (1000.0, 30.0, 33), (10.0, 50.0, 1)])
def test_divider(rate, topic_rate, k):
    assert divider(rate, topic_rate) == k


# ----- the node's remaining parts (issue 26 item 3: the node is wiring) -----

class Clock:
    """A /clock publisher with one subscriber, writing into ``events``."""

    def __init__(self, events):
        self.events = events

    def get_subscription_count(self):
        return 1

    def publish(self, data):
        self.events.append(("/clock", data))


class Named(Sink):
    """A publisher of ``name`` writing (name, data) into a shared list."""

    def __init__(self, name, items):
        self.name, self.items = name, items

    def publish(self, data):
        self.items.append((self.name, data))


def float_array(data: bytes) -> list[float]:
    return list(deserialize_message(data, Float64MultiArray).data)


def stepper_of(scene, published, log, period_ns=10_000_000):
    model = make_model("reduced", scene)
    sim = Simulator(model, make_integrator("dop853-jit"))
    period = PeriodRunner(sim, budget.fallback(sim.integrator, 0.5), period_ns)
    pubs = {o.name: Named(o.name, published) for o in OUTPUTS}
    outputs = Outputs(scene, {o.name: f"/ns/{o.name}" for o in OUTPUTS}, pubs, log, period_ns,
                      "world")
    return Stepper(period, outputs, SimClock(Clock(published), 0.1)), sim


def test_stepper_sends_the_applied_inputs_then_clock_then_the_state():
    scene = Scene.from_dict({
        "name": "loaded", "rods": {"count": 3, "length": 2.0, "mass_per_length": 3.0,
                                   "bending_stiffness": 1e5},
        "nodes": {"mass": 3.0}, "hinges": {"stiffness": 100.0, "damping": 0.01},
        "loads": [{"node": 3, "axis": "y", "shape": "constant", "amplitude": 20.0,
                   "start": 0.0}]})
    published, log = [], Sink()
    stepper, sim = stepper_of(scene, published, log)
    held = np.array([[1.0, 1.0, 0.5], [1.0, 1.0, 0.25], [1.0, 1.0, 0.0]])
    assert stepper.run(held)
    names = [name for name, _ in published]
    assert names[:3] == ["applied_forces", "applied_torques", "/clock"]     # no base topic
    assert set(names[3:]) == {n for n in STATE_TOPICS if n != "base_odometry"}
    data = dict(published)
    # the applied forces: the commands plus the scripted load (20 N in y on node 3)
    assert float_array(data["applied_forces"]) == [1, 1, 1, 1, 1, 21]
    assert float_array(data["applied_torques"]) == [0.5, 0.25, 0.0]
    clock = deserialize_message(data["/clock"], RosClock).clock
    assert (clock.sec, clock.nanosec) == (0, 10_000_000) and sim.t_ns == 10_000_000
    assert [t for _, _, t, _ in log.items] == [0, 0] + [10_000_000] * (len(names) - 3)
    del published[:], log.items[:]
    assert not stepper.run(np.full((3, 3), 1e300))             # fails: nothing of its end
    assert [name for name, _ in published] == ["applied_forces", "applied_torques"]
    assert stepper.period.error and sim.t_ns == 10_000_000
    del published[:], log.items[:]
    stepper.start()                                         # (a reset): all again, at t now
    stepper.applied(sim.t_ns)                               # unchanged, but published again
    names = [name for name, _ in published]
    assert names[:2] == ["robot_description", "scene"] and names[2] == "/clock"
    assert names[-2:] == ["applied_forces", "applied_torques"]
    assert {t for _, _, t, _ in log.items} == {10_000_000}
    del published[:], log.items[:]           # the period's hinge events last, at their time
    event = SimpleNamespace(to_dict=lambda: {"t": 0.015, "event": "latch", "hinge": 1})
    stepper.period.take_events = lambda: [event]
    assert stepper.run(held)
    assert published[-1][0] == "hinge_events" and '"event": "latch"' in str(published[-1][1])
    assert log.items[-1][0] == "/ns/hinge_events" and log.items[-1][2] == 15_000_000


def test_stepper_sends_the_free_base_row_and_the_wheel():
    scene = load_scene(REPO / "config" / "two_wing_deployment.yaml")
    published = []
    stepper, sim = stepper_of(scene, published, Sink())
    n = scene.n
    held = np.zeros((n + 2, 3))
    held[n] = [1.0, 2.0, 3.0]                     # base wrench in Oxy [N, N, N m]
    held[n + 1, 2] = 4.0                          # wheel motor torque [N m]
    sim.set_held(held)
    stepper.applied(0)
    assert float_array(dict(published)["applied_base"]) == [1.0, 2.0, 3.0, 4.0]


def test_period_events_are_taken_once():
    scene = make_scene(2)
    model = make_model("reduced", scene)
    sim = Simulator(model, make_integrator("dop853-jit"))
    period = PeriodRunner(sim, budget.fallback(sim.integrator, 0.5), 10_000_000)
    assert period.take_events() == []
    sim.events.extend(["a", "b"])
    assert period.take_events() == ["a", "b"] and period.take_events() == []
    sim.events.append("c")
    assert period.take_events() == ["c"]


def test_service_adapters_and_the_failure_line():
    answer = answering(lambda request: f"got {request.data}")
    response = answer(SimpleNamespace(data=True), SimpleNamespace(success=False, message=""))
    assert (response.success, response.message) == (True, "got True")
    wakes = []
    coro = executor_turn(SimpleNamespace(trigger=lambda: wakes.append(1)))()
    coro.send(None)                                   # triggered, then handed back once
    assert wakes == [1]
    with pytest.raises(StopIteration):
        coro.send(None)
    control = RunControl(sync_mode=True, start_paused=False, rtf=1.0)
    assert control.fail("boom at t = 1 s") == ("integration failed: boom at t = 1 s; "
                                               "simulation paused (call ~/reset, or ~/pause "
                                               "false to retry)")
    assert control.paused and control.error == "boom at t = 1 s"


def test_topic_names_dividers_and_clock():
    names = resolved_names(lambda t: t if t.startswith("/") else f"/ns/{t}",
                           (FORCES, TORQUES))
    assert names["diagnostics"] == "/diagnostics" and names["joint_states"] == "/ns/joint_states"
    assert names[FORCES] == "/ns/nodal_forces" and names[TORQUES] == "/ns/hinge_torques"
    assert len(names) == len(OUTPUTS) + 2
    assert rate_dividers(SimpleNamespace(rate_hz=100.0, markers_rate_hz=25.0)) == {"markers": 4}
    assert rate_dividers(SimpleNamespace(rate_hz=100.0, markers_rate_hz=0.0)) == {"markers": 1}
    made = []
    node = SimpleNamespace(create_publisher=lambda *a, **k: made.append((a, k)) or "pub")
    off = create_clock(node, SimpleNamespace(publish_clock=False, clock_reliability="reliable"))
    assert off.publisher is None and not made
    on = create_clock(node, SimpleNamespace(publish_clock=True, clock_reliability="best_effort"))
    (cls, topic, qos), kwargs = made[0]
    assert on.publisher == "pub" and topic == "/clock" and cls is RosClock
    assert qos.reliability == ReliabilityPolicy.BEST_EFFORT and "event_callbacks" in kwargs


def test_outputs_follow_a_new_frame_id_and_inputs_name_their_topics():
    scene = make_scene(2)
    pubs, log = {o.name: Sink() for o in OUTPUTS}, Sink()
    out = Outputs(scene, {o.name: f"/ns/{o.name}" for o in OUTPUTS}, pubs, log, 10_000_000,
                  "world")
    out.set_frame_id("map", 30_000_000)
    urdf = deserialize_message(pubs["robot_description"].items[0], String).data
    assert out.frame_id == "map" and '<link name="map"' in urdf and "world" not in urdf
    assert not log.items and not pubs["scene"].items          # published only, not recorded
    assert Inputs(2, 0.5).named_topics() == (FORCES, TORQUES)
    free = Inputs(10, 0.5, CommandLayout((("left", 5), ("right", 5)), "free", True))
    assert free.named_topics() == (FORCES, TORQUES, WRENCH)


def test_node_monitor_reports_the_parts_and_starts_a_new_window(tmp_path):
    scene = make_scene(3)
    model = make_model("reduced", scene)
    sim = Simulator(model, make_integrator("dop853-jit"))
    work = budget.fallback(sim.integrator, 0.5)
    period = PeriodRunner(sim, work, 10_000_000)
    control, inputs = RunControl(False, False, 1.0), Inputs(3, 0.5)
    recording = SimpleNamespace(path=None, error=None)       # a NodeRecording not recording
    monitor = NodeMonitor(control, period, inputs, Pacing(10_000_000, 1.0), recording, 100.0,
                          "/ns/rod_sim")
    for _ in range(2):
        period.note_state(period.run(np.zeros((3, 2))))
    values = monitor.report().values()
    assert {k: values[k] for k in ("scene", "rate_hz", "recording", "node", "sim_time_s",
                                   "steps_in_window", "mode", "state", "work_budget")} == {
        "scene": "chain_3", "rate_hz": "100", "recording": "off", "node": "/ns/rod_sim",
        "sim_time_s": "0.020000000", "steps_in_window": "2", "mode": "real time x1",
        "state": "running", "work_budget": work.describe()}
    assert values["nodal_forces_received"] == "0"            # the inputs' counts too
    recording.path = tmp_path / "run.mcap"
    message = monitor.message()
    status = message["status"][0]
    assert status["name"] == "rod_sim: simulation" and status["hardware_id"] == "chain_3"
    got = {kv["key"]: kv["value"] for kv in status["values"]}
    assert got["recording"] == str(tmp_path / "run.mcap") and status["level"] == 0
    assert message["header"]["stamp"] == {"sec": 0, "nanosec": 20_000_000}
    period.note_state(make_snapshot(scene, seed=1))
    assert period.max_alpha > 0
    monitor.new_window()
    assert period.max_alpha == 0.0 and period.meter.steps == 0
    recording.error = "disk full"
    assert monitor.report().status()[:2] == (2, "recording stopped: disk full")
