"""The parts the node is wired from (issue 26 item 3), each without a ROS graph: the inputs
(held inputs, timeout, lockstep queue), the run control (pause, step, busy, interrupted),
the output table (one encoding to every sink, dividers, applied inputs on change) and one
control period (ledger, failure)."""
from __future__ import annotations

import asyncio
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io import encoders, topics
from rod_sim.ros import budget
from rod_sim.ros.commands import FORCES, TORQUES
from rod_sim.ros.control import RunControl
from rod_sim.ros.inputs import Inputs
from rod_sim.ros.outputs import OUTPUTS, STATE_TOPICS, Outputs, divider
from rod_sim.ros.period import PeriodRunner

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
