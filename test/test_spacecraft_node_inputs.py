"""The node's spacecraft inputs (issue 28): ``base_wrench``, the ``wheel`` entry of
``hinge_torques``, command arrays over several chains validated chain by chain, lockstep and
the services with a free base.

Without a ROS graph: the command layout (what each topic holds per chain, the one-line
refusals) and the held inputs (n + 2, 3) with the base's and the wheel's rows. With a ROS graph
(the node a separate process, this process the controller; ROS domains from ros_domains,
LOCALHOST): a lockstep session on config/two_wing_deployment.yaml (a free bus with a wheel and
two chains) whose log holds the applied base wrench of every period (a base-frame wrench turned
by the bus angle of the state at the period's start), whose states an offline simulator
holding the logged inputs reproduces bit for bit, and which gives the same log messages when
run twice; bad commands rejected and counted, the node going on; a wrench and a wheel torque
sent to a fixed base rejected with their reasons; ~/step and ~/reset with the base and the
wheel."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray, MultiArrayDimension  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from ros_domains import next_domains  # noqa: E402
from ros_graph import Client, NodeProcess, stamp_ns, unique_namespace  # noqa: E402
from rod_sim.io.scene_yaml import load_scene  # noqa: E402
from rod_sim.ros.command_layout import CommandLayout, to_inertial  # noqa: E402
from rod_sim.ros.commands import WRENCH, CommandIntake  # noqa: E402
from rod_sim.ros.conversions import CommandError  # noqa: E402
from rod_sim.ros.inputs import Inputs  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
WINGS = REPO / "config" / "two_wing_deployment.yaml"
SMALL = REPO / "config" / "small_chain.yaml"
SPIN_UP = REPO / "config" / "spin_up_beam.yaml"
DOMAIN_A, DOMAIN_B, DOMAIN_FIXED, DOMAIN_SERVICES = next_domains(4)
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
N = 10                     # two wings of 5 panels
PERIOD_NS = 10_000_000


def array(values, dims=()) -> Float64MultiArray:
    msg = Float64MultiArray(data=[float(v) for v in values])
    msg.layout.dim = [MultiArrayDimension(label=label, size=size, stride=size)
                      for label, size in dims]
    return msg


def wrench(fx=0.0, fy=0.0, m=0.0, frame="world", **extra) -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.frame_id = frame
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.torque.z = fx, fy, m
    for key, value in extra.items():                # e.g. force_z=1.0
        part, axis = key.split("_")
        setattr(getattr(msg.wrench, part), axis, value)
    return msg


def diag_values(msg) -> dict[str, str]:
    return {kv.key: kv.value for kv in msg.status[0].values}


# ----- without a ROS graph -----

WINGS_LAYOUT = CommandLayout((("left", 5), ("right", 5)), "free", True)


def test_layout_of_the_scenes():
    assert CommandLayout.of_scene(load_scene(WINGS)) == WINGS_LAYOUT
    assert WINGS_LAYOUT.values(2) == 20 and WINGS_LAYOUT.values(1) == 11
    assert WINGS_LAYOUT.rows == N + 2
    small = CommandLayout.of_scene(load_scene(SMALL))
    assert small == CommandLayout.single(small.n) and small.rows == small.n
    spin = CommandLayout.of_scene(load_scene(SPIN_UP))
    assert spin.base_mode == "prescribed" and not spin.free_base


def test_per_chain_validation_names_the_chain():
    lay = WINGS_LAYOUT
    good = lay.forces(array(range(20), [("left", 10), ("right", 10)]))
    assert good.shape == (10, 2) and good[5].tolist() == [10.0, 11.0]
    with pytest.raises(CommandError, match=r"^chain right: layout dim of 8 values, expected 10 "
                                           r"\[X_1, Y_1, \.\.\., X_5, Y_5\]$"):
        lay.forces(array(range(18), [("left", 10), ("right", 8)]))
    with pytest.raises(CommandError, match=r"must name the chains in scene order"):
        lay.forces(array(range(20), [("right", 10), ("left", 10)]))
    with pytest.raises(CommandError, match=r"^expected 20 values in scene order: chain left 10 "
                                           r".*chain right 10 .*, got 19$"):
        lay.forces(array(range(19)))
    assert lay.forces(array(range(20), [("node", 10), ("xy", 2)])).shape == (10, 2)  # ignored
    bad = list(range(20))
    bad[13] = math.inf
    with pytest.raises(CommandError, match=r"non-finite value inf at data\[13\] "
                                           r"\(chain right, Y_2\)"):
        lay.forces(array(bad))


def test_the_wheel_is_the_last_torque_entry():
    lay = WINGS_LAYOUT
    t = lay.torques(array([*range(10), 0.5], [("left", 5), ("right", 5), ("wheel", 1)]))
    assert t.tolist() == [*map(float, range(10)), 0.5]
    with pytest.raises(CommandError, match=r"expected 11 values .*the wheel entry 1 .*got 10"):
        lay.torques(array(range(10)))
    with pytest.raises(CommandError, match=r"the wheel entry: layout dim of 2 values"):
        lay.torques(array(range(12), [("left", 5), ("right", 5), ("wheel", 2)]))
    with pytest.raises(CommandError, match=r"non-finite value nan at data\[10\] "
                                           r"\(the wheel entry\)"):
        lay.torques(array([*range(10), math.nan]))
    small = CommandLayout.single(3)
    with pytest.raises(CommandError, match=r"^expected 3 values \[T_0, \.\.\., T_2\] \[N m\] "
                                           r"for hinges hinge_0\.\.hinge_2, got 4 \(the scene "
                                           r"has no reaction wheel: no 'wheel' entry\)$"):
        small.torques(array(range(4)))


def test_wrench_validation():
    lay = WINGS_LAYOUT
    values, body = lay.wrench(wrench(1.0, 2.0, 3.0), "world")
    assert values.tolist() == [1.0, 2.0, 3.0] and not body
    assert lay.wrench(wrench(1.0, frame="base"), "world")[1]
    assert lay.wrench(wrench(1.0, frame="map"), "map")[1] is False   # the node's frame_id
    for msg, match in ((wrench(frame="map"), r"header.frame_id 'map': expected 'world' "
                                             r"\(inertial\) or 'base'"),
                       (wrench(m=math.nan), r"non-finite value nan in wrench.torque.z"),
                       (wrench(force_z=1.0), r"wrench.force.z = 1: a planar base takes"),
                       (wrench(torque_x=-2.0), r"wrench.torque.x = -2")):
        with pytest.raises(CommandError, match=match):
            lay.wrench(msg, "world")
    with pytest.raises(CommandError, match=r"base is fixed: a base wrench cannot act on it"):
        CommandLayout.single(3).wrench(wrench(1.0), "world")
    with pytest.raises(CommandError, match=r"base is prescribed"):
        CommandLayout.of_scene(load_scene(SPIN_UP)).wrench(wrench(1.0), "world")


def test_base_frame_wrench_turned_by_psi():
    # independent numbers: the base turned by +90 degrees, its x axis along Oxy's y axis
    np.testing.assert_allclose(to_inertial(np.array([2.0, 0.0, 5.0]), True, math.pi / 2),
                               [0.0, 2.0, 5.0], atol=1e-15)
    np.testing.assert_allclose(to_inertial(np.array([0.0, 3.0, 0.0]), True, math.pi / 6),
                               [-1.5, 3.0 * math.sqrt(3) / 2, 0.0], atol=1e-15)
    assert to_inertial(np.array([2.0, 1.0, 0.0]), False, 1.0).tolist() == [2.0, 1.0, 0.0]


def test_held_inputs_with_a_free_base_and_lockstep_queue():
    psi = [0.0]
    inputs = Inputs(N, 0.0, WINGS_LAYOUT, lambda: psi[0])
    w = inputs.wrench.accept(wrench(10.0, 0.0, 7.0, frame="base"), 0)
    t = inputs.torques.accept(array([*np.arange(10.0), 0.25]), 0)
    f = inputs.forces.accept(array(np.ones(20)), 0)
    assert w is not None and t is not None and f is not None
    psi[0] = math.pi / 2
    held, _ = inputs.held(0, wall_age=False)
    assert held.shape == (N + 2, 3)
    np.testing.assert_allclose(held[N], [0.0, 10.0, 7.0], atol=1e-12)
    assert held[N + 1].tolist() == [0.0, 0.0, 0.25] and held[:N, 2].tolist() == list(range(10))
    assert (held[:N, :2] == 1.0).all()
    # lockstep: each queued command keeps the other topics' last ones; the body-frame wrench
    # is turned by psi when its period starts
    inputs.queue.extend([w, t])
    psi[0] = 0.0
    first = inputs.next_queued()
    assert first[N].tolist() == [10.0, 0.0, 7.0] and not first[:N].any()
    psi[0] = math.pi
    second = inputs.next_queued()
    np.testing.assert_allclose(second[N], [-10.0, 0.0, 7.0], atol=1e-12)
    assert second[N + 1, 2] == 0.25
    counts = inputs.counts()
    assert counts["base_wrench_received"] == "1" and counts["base_wrench_active"] == "true"
    # a fixed base: the wrench intake refuses, the held inputs stay (n, 3)
    fixed = Inputs(3, 0.0)
    assert fixed.wrench.accept(wrench(1.0), 0) is None and fixed.wrench.rejected == 1
    assert fixed.held(0, wall_age=False)[0].shape == (3, 3)


def test_wrench_intake_refuses_oversize_before_decoding():
    intake = CommandIntake(N, 0.0, WRENCH, WINGS_LAYOUT)
    assert intake.decode(b"\0" * (intake.max_bytes + 1)) is None
    assert intake.rejected == 1 and "more than the" in intake.last_rejection


# ----- with a ROS graph -----

class Session:
    """A lockstep node (separate process) on ``scene`` and this process as its controller."""

    def __init__(self, tmp_path, domain, ns, scene, log=None, **params):
        self.node = NodeProcess(tmp_path, domain, name=f"node_{domain}",
                                extra=["-r", f"__ns:={ns}"], scene_file=scene, sync_mode=True,
                                **({"record_path": log} if log else {}), **params)
        self.client = Client(domain, namespace=ns)
        c = self.client.node
        self.pubs = {"forces": c.create_publisher(Float64MultiArray, "nodal_forces", 10),
                     "torques": c.create_publisher(Float64MultiArray, "hinge_torques", 10),
                     "wrench": c.create_publisher(WrenchStamped, "base_wrench", 10)}
        self.states, self.diags = [], []
        c.create_subscription(JointState, "rod_states", self.states.append, LATCHED)
        c.create_subscription(DiagnosticArray, "/diagnostics", self.diags.append, 10)
        self.node.wait_for_output("commands on")
        self.client.spin_until(lambda: self.states and all(
            p.get_subscription_count() > 0 for p in self.pubs.values()), 30.0, "discovery",
            self.node)

    def answer(self, topic, msg):
        """Publish one valid command; wait for the state of the period it starts."""
        before = stamp_ns(self.states[-1])
        self.pubs[topic].publish(msg)
        self.client.spin_until(lambda: stamp_ns(self.states[-1]) > before, 30.0,
                               f"the period after a {topic} command", self.node)

    def counts(self, key, value):
        self.client.spin_until(lambda: self.diags and diag_values(self.diags[-1]).get(key)
                               == value, 20.0, lambda: f"{key} = {value}: {self.diags[-1:]}",
                               self.node)
        return diag_values(self.diags[-1])

    def close(self) -> int:
        self.client.close()
        return self.node.stop()


DIMS_F = [("left", 10), ("right", 10)]
DIMS_T = [("left", 5), ("right", 5), ("wheel", 1)]


def run_session(tmp_path, domain, ns, log):
    """The scripted lockstep session on the two wings; returns the node's stderr."""
    s = Session(tmp_path, domain, ns, WINGS, log)
    try:
        for _ in range(5):
            s.answer("wrench", wrench(200.0, -100.0, 50.0))
        for _ in range(5):
            s.answer("torques", array([0.0] * 10 + [0.5], DIMS_T))
        for _ in range(5):
            s.answer("wrench", wrench(300.0, 0.0, -80.0, frame="base"))
        before = stamp_ns(s.states[-1])
        s.pubs["forces"].publish(array(range(18), [("left", 10), ("right", 8)]))
        s.counts("nodal_forces_rejected", "1")
        s.pubs["torques"].publish(array([0.0] * 10))
        s.counts("hinge_torques_rejected", "1")
        s.pubs["wrench"].publish(wrench(m=math.nan))       # one publisher: in this order
        s.pubs["wrench"].publish(wrench(1.0, force_z=1.0))
        s.pubs["wrench"].publish(wrench(1.0, frame="map"))
        s.counts("base_wrench_rejected", "3")
        assert stamp_ns(s.states[-1]) == before          # a rejected command steps nothing
        for _ in range(3):
            s.answer("forces", array(0.1 * np.arange(20), DIMS_F))
        values = s.counts("nodal_forces_received", "4")          # the last command
        assert values["base_wrench_received"] == "13"
        assert values["commands_rejected"] == "5" and values["commands_received"] == "23"
        assert values["last_rejection"].startswith("base_wrench: header.frame_id 'map'")
        assert s.node.proc.poll() is None
    finally:
        assert s.close() == 0, s.node.stderr
    return s.node.stderr


def log_messages(path):
    """(topic, log time, CDR bytes) of every message but /diagnostics (wall-clock values)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [(c.topic, m.log_time, bytes(m.data))
                for _, c, m in make_reader(f).iter_messages(log_time_order=False)
                if not c.topic.endswith("diagnostics")]


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_lockstep_session_log_replay_and_determinism(tmp_path, monkeypatch):
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator
    from rod_sim.io.log_reader import LogReader

    ns = unique_namespace()
    logs = [tmp_path / "a.mcap", tmp_path / "b.mcap"]
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_A))
    err = run_session(tmp_path, DOMAIN_A, ns, logs[0])
    for reason in ("chain right: layout dim of 8 values, expected 10",   # the first one of
                   "expected 11 values in scene order", "non-finite value nan in wrench"):
        assert reason in err, err                                      # each topic is logged
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_B))
    run_session(tmp_path, DOMAIN_B, ns, logs[1])
    a, b = (log_messages(p) for p in logs)
    assert len(a) > 100 and a == b, "two lockstep runs with the same commands differ"

    with LogReader(logs[0]) as reader:
        msgs = [(topic[len(ns) + 1:], t, m) for topic, t, m in reader.messages()]
    per = {}
    for topic, t, m in msgs:
        per.setdefault(topic, []).append((t, m))
    assert len(per["base_wrench"]) == 10 + 3           # received ones recorded (nan too)
    base = [(t, np.array(m.data)) for t, m in per["applied_base"]]
    assert [t for t, _ in base] == [k * PERIOD_NS for k in range(18)]
    assert list(per["applied_base"][0][1].layout.dim[0].label) == list("base")
    for k in range(5):
        assert base[k][1].tolist() == [200.0, -100.0, 50.0, 0.0]
        assert base[5 + k][1].tolist() == [200.0, -100.0, 50.0, 0.5]
    states = {t: m for t, m in per["rod_states"]}
    joints = {t: m for t, m in per["joint_states"]}
    for k in range(10, 15):                    # base frame: turned by psi at the period start
        t = k * PERIOD_NS
        psi = states[t].position[0] - joints[t].position[0]    # phi_1 - theta_0 (left chain)
        assert abs(psi) > 1e-6                             # the bus has turned by then
        expected = [300.0 * math.cos(psi), 300.0 * math.sin(psi), -80.0, 0.5]
        np.testing.assert_allclose(base[k][1], expected, rtol=0, atol=1e-12)
    # the node applied exactly what it logged: an offline simulator holding the logged inputs
    # period by period reproduces the logged states bit for bit
    scene = load_scene(WINGS)
    sim = Simulator(make_model("reduced", scene), make_integrator("dop853-jit", rtol=1e-8))
    forces = dict(per["applied_forces"])
    torques = dict(per["applied_torques"])
    for k in range(18):
        t = k * PERIOD_NS
        held = np.zeros((N + 2, 3))
        held[:N, :2] = np.reshape(forces[t].data, (N, 2))
        held[:N, 2] = torques[t].data
        held[N] = base[k][1][:3]
        held[N + 1, 2] = base[k][1][3]
        sim.set_held(held)
        sim.advance(0.01)
        assert np.array_equal(sim.snapshot().phi, states[t + PERIOD_NS].position), k


@pytest.mark.ros
@pytest.mark.timeout(300)
def test_fixed_base_refuses_wrench_and_wheel(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_FIXED))
    n = load_scene(SMALL).n
    s = Session(tmp_path, DOMAIN_FIXED, unique_namespace(), SMALL)
    try:
        s.answer("forces", array(np.zeros(2 * n)))
        before = stamp_ns(s.states[-1])
        s.pubs["wrench"].publish(wrench(1.0))
        s.pubs["torques"].publish(array(np.zeros(n + 1)))
        values = s.counts("base_wrench_rejected", "1")
        values = s.counts("hinge_torques_rejected", "1")
        assert stamp_ns(s.states[-1]) == before
        s.answer("torques", array(np.zeros(n)))            # the node goes on
        assert s.node.proc.poll() is None and values["base_wrench_active"] == "false"
    finally:
        assert s.close() == 0, s.node.stderr
    assert "rejected a base_wrench command: the scene's base is fixed: a base wrench cannot " \
           "act on it" in s.node.stderr
    assert "the scene has no reaction wheel" in s.node.stderr


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_step_and_reset_restore_base_and_wheel(tmp_path, monkeypatch):
    """Paused at the start: ~/step with a held wrench and wheel torque moves the bus and
    spins the wheel (its energy is in the ledger); ~/reset brings base and wheel back (the
    energy at t = 0 again), and the same commands and steps give the same states again."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_SERVICES))
    ns = unique_namespace()
    node = NodeProcess(tmp_path, DOMAIN_SERVICES, extra=["-r", f"__ns:={ns}"],
                       scene_file=WINGS, start_paused=True, step_count=20,
                       command_timeout=0.0)
    client = Client(DOMAIN_SERVICES, namespace=ns)
    try:
        node.wait_for_output("commands on")
        c = client.node
        pub_w = c.create_publisher(WrenchStamped, "base_wrench", 10)
        pub_t = c.create_publisher(Float64MultiArray, "hinge_torques", 10)
        states, diags = [], []
        c.create_subscription(JointState, "rod_states", states.append, LATCHED)
        c.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
        step = c.create_client(Trigger, f"{ns}/rod_sim/step")
        reset = c.create_client(Trigger, f"{ns}/rod_sim/reset")
        pause = c.create_client(SetBool, f"{ns}/rod_sim/pause")
        client.spin_until(lambda: states and pub_w.get_subscription_count() > 0
                          and pub_t.get_subscription_count() > 0 and step.service_is_ready()
                          and reset.service_is_ready() and pause.service_is_ready(), 30.0,
                          "discovery", node)

        def call(cli, request):
            future = cli.call_async(request)
            client.spin_until(future.done, 60.0, "a service answer", node)
            assert future.result().success, future.result().message
            return future.result()

        def energy_at(t_s):
            client.spin_until(lambda: diags and diag_values(diags[-1])["sim_time_s"]
                              == f"{t_s:.9f}", 20.0, f"diagnostics at t = {t_s}", node)
            return float(diag_values(diags[-1])["energy_J"])

        e0 = energy_at(0.0)

        def stepped(k):
            pub_w.publish(wrench(0.0, 0.0, 400.0))
            pub_t.publish(array([0.0] * 10 + [2.0]))
            client.spin_until(lambda: diags and diag_values(diags[-1])[
                "base_wrench_received"] == str(k) and diag_values(diags[-1])[
                "hinge_torques_received"] == str(k), 20.0, "the commands received", node)
            call(step, Trigger.Request())
            client.spin_until(lambda: stamp_ns(states[-1]) == 20 * PERIOD_NS, 20.0,
                              "the 20 stepped periods", node)
            return np.array(states[-1].position)

        call(pause, SetBool.Request(data=True))    # paused for good: commands only held
        first = stepped(1)
        e1 = energy_at(0.2)
        assert e1 > e0 + 1.0, (e0, e1)        # the base turned and the wheel spun up
        call(reset, Trigger.Request())
        client.spin_until(lambda: stamp_ns(states[-1]) == 0, 20.0, "the state at t = 0", node)
        assert energy_at(0.0) == e0
        second = stepped(2)
        assert np.array_equal(first, second)
        assert energy_at(0.2) == e1
        assert node.proc.poll() is None
    finally:
        client.close()
        assert node.stop() == 0, node.stderr


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_attitude_demo_holds_the_bus(tmp_path):
    """``python -m rod_sim.ros.demo --scene config/two_wing_deployment.yaml`` (shortened, no
    compare): lockstep, one base_wrench per period, each the PD law of the bus angle of the
    state it answers (computed here from the logged states), and the bus held."""
    import subprocess
    import sys

    from procs import ros_env
    from rod_sim.io.log_reader import LogReader
    from rod_sim.ros.attitude import attitude_moment

    (domain,) = next_domains(1)
    log = tmp_path / "attitude.mcap"
    done = subprocess.run([sys.executable, "-m", "rod_sim.ros.demo", "--scene", str(WINGS),
                           "--duration", "2", "--out", str(log), "--no-compare"], cwd=REPO,
                          env=ros_env(domain), capture_output=True, text=True, timeout=500)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "bus angle psi: max |psi|" in done.stdout and "0 rejected" in done.stdout
    with LogReader(log) as reader:
        msgs = list(reader.messages())
    states = {t: m for topic, t, m in msgs if topic == "/rod_states"}
    joints = {t: m for topic, t, m in msgs if topic == "/joint_states"}
    applied = {t: np.array(m.data) for topic, t, m in msgs if topic == "/applied_base"}
    assert len(applied) == 200
    def law(t):
        """The PD moment answering the state at t [ns], from the logged states."""
        psi = states[t].position[0] - joints[t].position[0]       # phi_1 - theta_0 (left)
        rate = states[t].velocity[0] - joints[t].velocity[0]
        return psi, attitude_moment(psi, rate, 0.0, 5000.0, 3000.0, 1e4)

    # the command starting period k answers the state at its start, or, when the kickoff's
    # zero wrench started the run before the first state arrived, the state one period earlier
    times = sorted(applied)[2:]
    lag = 0 if all(applied[t][2] == pytest.approx(law(t)[1], rel=1e-12, abs=1e-9)
                   for t in times[:5]) else PERIOD_NS
    psis = []
    for t in times:
        psi, moment = law(t - lag)
        psis.append(psi)
        assert applied[t][:2].tolist() == [0.0, 0.0] and applied[t][3] == 0.0
        assert applied[t][2] == pytest.approx(moment, rel=1e-12, abs=1e-9), (t, lag)
    assert max(map(abs, psis)) < 0.1 and any(abs(applied[t][2]) > 1.0 for t in applied)


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_attitude_demo_ends_with_compare_passing(tmp_path):
    """``python -m rod_sim.ros.demo --scene config/two_wing_deployment.yaml`` (shortened to 3 s)
    runs ``rod-sim compare`` on its log at the end: compare reads the chain log (left/...,
    right/...), re-runs it with the logged base wrenches (``/applied_base``) and passes over
    both chains and the base: exit 0 (it stopped with exit 2 before compare read chain logs)."""
    import subprocess
    import sys

    from procs import ros_env

    (domain,) = next_domains(1)
    log = tmp_path / "attitude.mcap"
    done = subprocess.run([sys.executable, "-m", "rod_sim.ros.demo", "--scene", str(WINGS),
                           "--duration", "3", "--out", str(log)], cwd=REPO,
                          env=ros_env(domain), capture_output=True, text=True, timeout=800)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "PASS" in done.stdout and "left" in done.stdout and "base: max |psi error|" in \
        done.stdout, done.stdout[-3000:]
    from rod_sim.io.log_reader import LogReader

    with LogReader(log) as reader:
        odom = [m for topic, t, m in reader.messages() if topic == "/base_odometry"]
    assert len(odom) == 301 and odom[-1].child_frame_id == "base"
