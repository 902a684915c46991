"""The node's ``hinge_torques`` command topic (issue 20 item 2), met as a user meets it: the node
as a separate process, a controller (this process) publishing hinge torques, the recorded log
compared (``rod-sim compare``) and replayed (``rod-sim replay``) by the command line.

- lockstep: one period per valid command on either topic, the other topic's last command held
  (``/applied_torques``, ``/applied_forces`` per period in the log); wrong length, NaN and an
  oversize message are rejected, counted on diagnostics, recorded as received (the oversize
  one not) and the node keeps going; the log compares PASS against the full model, a log
  whose torques were tampered with (or dropped) FAILs; replay republishes the torques;
- real time: a torque command is held, then falls back to zero after ``command_timeout``;
- physics through the node: one damped rod under a held torque T settles at phi_1 = T /
  kappa_0 and the node's energy balance (motor work included) closes.

ROS domain ids from ros_domains (LOCALHOST)."""
from __future__ import annotations

import math
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from ros_domains import next_domains  # noqa: E402
from procs import ros_env  # noqa: E402
from ros_graph import Client, NodeProcess, stamp_ns, unique_namespace  # noqa: E402
from rod_sim.io.log_reader import LogReader  # noqa: E402
from rod_sim.ros.commands import TORQUES, CommandIntake  # noqa: E402
from rod_sim.ros.conversions import CommandError, command_torques  # noqa: E402
from test_compare import rewrite  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

REPO = Path(__file__).resolve().parents[1]
SMALL = REPO / "config" / "small_chain.yaml"
DOMAIN_LOCKSTEP, DOMAIN_REALTIME, DOMAIN_STATIC = next_domains(3)
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def array(values) -> Float64MultiArray:
    return Float64MultiArray(data=[float(v) for v in values])


def diag_values(msg) -> dict[str, str]:
    return {kv.key: kv.value for kv in msg.status[0].values}


def rod_sim_cli(*args, domain: int | None = None, timeout: float = 300.0):
    env = ros_env(domain) if domain is not None else None
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", *map(str, args)],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout)


# ----- the intake (no ROS graph) -----

def test_torque_commands_are_validated_like_forces():
    assert command_torques(array([1.0, -2.0, 3.0]), 3).tolist() == [1.0, -2.0, 3.0]
    with pytest.raises(CommandError, match="expected 3 values"):
        command_torques(array([1.0, 2.0]), 3)
    with pytest.raises(CommandError, match=r"non-finite value nan at data\[1\]"):
        command_torques(array([1.0, math.nan, 3.0]), 3)
    intake = CommandIntake(3, 0.5, TORQUES)
    assert intake.max_bytes == 16 * 3 + 4096
    assert intake.decode(b"\0" * (intake.max_bytes + 1)) is None
    assert intake.rejected == 1 and "more than the" in intake.last_rejection
    assert intake.accept(array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), 0) is None   # a force command
    assert intake.rejected == 2 and intake.latest is None
    cmd = intake.accept(array([1.0, 2.0, 3.0]), 7)
    assert cmd.kind == TORQUES and cmd.sim_ns == 7 and intake.received == 3
    assert intake.held(0, wall_age=False).tolist() == [1.0, 2.0, 3.0]


# ----- lockstep: the whole user path -----

@pytest.mark.slow
def test_lockstep_torques_rejections_log_compare_and_replay(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_LOCKSTEP))
    ns = unique_namespace()
    log = tmp_path / "torques.mcap"
    node = NodeProcess(tmp_path, DOMAIN_LOCKSTEP, extra=["-r", f"__ns:={ns}"],
                       scene_file=SMALL, sync_mode=True, model="full", record_path=log)
    client = Client(DOMAIN_LOCKSTEP, namespace=ns)
    try:
        node.wait_for_output("commands on")
        c = client.node
        torques = c.create_publisher(Float64MultiArray, "hinge_torques", 10)
        forces = c.create_publisher(Float64MultiArray, "nodal_forces", 10)
        states, applied, diags = [], [], []
        c.create_subscription(JointState, "rod_states", states.append, LATCHED)
        c.create_subscription(Float64MultiArray, "applied_torques",
                              lambda m: applied.append(list(m.data)), 10)
        c.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
        client.spin_until(lambda: states and torques.get_subscription_count() > 0
                          and forces.get_subscription_count() > 0, 30.0, "discovery", node)

        def answer(publisher, values):
            """Publish one command answering the latest state; wait for the next state."""
            before = stamp_ns(states[-1])
            publisher.publish(array(values))
            client.spin_until(lambda: stamp_ns(states[-1]) > before, 30.0,
                              "the state of the next period", node)

        t_a, t_b, f_c = [4.0, -2.0, 1.0], [1.0, 0.5, -0.5], [0.5, -0.5, 0.0, 1.0, 0.0, -1.0]
        for _ in range(20):
            answer(torques, t_a)
        answer(forces, f_c)                    # advances one period, t_a stays held
        # bad commands: rejected, counted, no period advances, the node keeps going
        t_before = stamp_ns(states[-1])
        torques.publish(array([1.0, 2.0]))
        torques.publish(array([1.0, math.nan, 0.0]))
        torques.publish(array([0.0] * 1000))   # 8000 bytes > 16 n + 4096: refused unread
        client.spin_until(lambda: diags and diag_values(diags[-1])["hinge_torques_rejected"]
                          == "3", 20.0, lambda: f"3 rejections on diagnostics: {diags[-1:]}",
                          node)
        assert stamp_ns(states[-1]) == t_before        # a rejected command steps nothing
        for _ in range(29):
            answer(torques, t_b)               # f_c stays held
        client.spin_until(lambda: applied and applied[-1] == t_b, 10.0, "applied_torques")
        client.spin_until(lambda: diag_values(diags[-1])["hinge_torques_received"] == "52",
                          20.0, lambda: f"the counts on diagnostics: {diags[-1:]}", node)
        values = diag_values(diags[-1])
        assert values["hinge_torques_rejected"] == "3"
        assert values["nodal_forces_received"] == "1" and values["nodal_forces_rejected"] == "0"
        assert values["commands_received"] == "53" and values["commands_rejected"] == "3"
        assert values["last_rejection"].startswith("hinge_torques: ")
        assert node.proc.poll() is None
    finally:
        client.close()
        assert node.stop() == 0, node.stderr
    assert "rejected a hinge_torques command" in node.stderr

    # the log: commands as received, the applied torques and forces of every period
    with LogReader(log) as reader:
        msgs = [(topic, t, msg) for topic, t, msg in reader.messages()]
    received = [list(m.data) for topic, _, m in msgs if topic == f"{ns}/hinge_torques"]
    assert len(received) == 20 + 2 + 29              # the oversize one is not recorded
    assert [1.0, 2.0] in received
    per_period = {topic: [(t, list(m.data)) for tp, t, m in msgs if tp == f"{ns}/{topic}"]
                  for topic in ("applied_torques", "applied_forces")}
    tq, fc = per_period["applied_torques"], per_period["applied_forces"]
    assert len(tq) == len(fc) == 50
    assert [t for t, _ in tq] == [t for t, _ in fc] == [k * 10_000_000 for k in range(50)]
    assert all(v == t_a for _, v in tq[:21])            # period 20: the force command, t_a held
    assert all(v == t_b for _, v in tq[21:])
    assert not np.allclose(fc[21][1], fc[19][1])         # the force command applied ...
    held_c = np.array(fc[21][1]) - np.array(fc[19][1])   # ... on top of the scripted load
    assert np.allclose(held_c, f_c)
    assert all(np.allclose(np.array(v) - np.array(fc[19][1]), f_c) for _, v in fc[21:])

    # compare: the torques are part of the re-run's input
    done = rod_sim_cli("compare", log)
    assert done.returncode == 0, done.stdout + done.stderr
    text = " ".join(done.stdout.split())
    assert "PASS" in text and "torques: 50 /applied_torques messages, max |T| 4 N m" in text
    assert "3 held-command segment(s)" in text          # t_a; + f_c; t_b

    def tampered(items):
        out = []
        for schema, channel, msg in items:
            if channel.topic == f"{ns}/applied_torques" and msg.log_time >= 100_000_000:
                data = bytearray(msg.data)            # CDR little endian: the last double is
                last = struct.unpack_from("<d", data, len(data) - 8)[0]       # T_2
                struct.pack_into("<d", data, len(data) - 8, last + 20.0)
                msg = type(msg)(channel_id=msg.channel_id, sequence=msg.sequence,
                                log_time=msg.log_time, publish_time=msg.publish_time,
                                data=bytes(data))
            out.append((schema, channel, msg))
        return out

    bad = tmp_path / "tampered.mcap"
    rewrite(log, bad, tampered)
    done = rod_sim_cli("compare", bad)
    assert done.returncode == 1 and "FAIL" in done.stdout, done.stdout + done.stderr
    dropped = tmp_path / "no_torques.mcap"
    rewrite(log, dropped, lambda items: [i for i in items
                                         if i[1].topic != f"{ns}/applied_torques"])
    done = rod_sim_cli("compare", dropped)
    assert done.returncode == 1 and "FAIL" in done.stdout, done.stdout + done.stderr
    gap = tmp_path / "torque_gap.mcap"
    rewrite(log, gap, lambda items: [i for i in items if not (
        i[1].topic == f"{ns}/applied_torques" and 150_000_000 <= i[2].log_time <= 200_000_000)])
    done = rod_sim_cli("compare", gap)
    assert done.returncode == 2 and "/applied_torques has a gap" in done.stderr, done.stderr

    # replay: the torques go out again, with the node's QoS (transient local)
    listener = Client(DOMAIN_LOCKSTEP, name="replay_listener")
    try:
        got = []
        listener.node.create_subscription(Float64MultiArray, f"{ns}/applied_torques",
                                          lambda m: got.append(list(m.data)), 100)
        replay = subprocess.Popen([sys.executable, "-m", "rod_sim.tools.cli", "replay", str(log),
                                   "--topics", f"{ns}/applied_torques", "--rate", "5",
                                   "--wait-for-subscribers"], cwd=REPO,
                                  env=ros_env(DOMAIN_LOCKSTEP), stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        try:
            listener.spin_until(lambda: len(got) == 50 or replay.poll() is not None, 60.0,
                                "the replayed torques")
            listener.spin_for(0.3)
        finally:
            replay.kill() if replay.poll() is None else None
            out, err = replay.communicate(timeout=30)
        assert got == [v for _, v in tq], (len(got), err)
    finally:
        listener.close()


# ----- real time: hold and timeout -----

@pytest.mark.slow
def test_realtime_torque_is_held_then_times_out(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_REALTIME))
    ns = unique_namespace()
    node = NodeProcess(tmp_path, DOMAIN_REALTIME, extra=["-r", f"__ns:={ns}"],
                       scene_file=SMALL, command_timeout=0.4)
    client = Client(DOMAIN_REALTIME, namespace=ns)
    try:
        node.wait_for_output("commands on")
        c = client.node
        torques = c.create_publisher(Float64MultiArray, "hinge_torques", 10)
        applied, diags = [], []
        c.create_subscription(Float64MultiArray, "applied_torques",     # on change only:
                              lambda m: applied.append((time.monotonic(), list(m.data))),
                              QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        c.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
        client.spin_until(lambda: applied and torques.get_subscription_count() > 0, 30.0,
                          "discovery", node)
        assert applied[-1][1] == [0.0, 0.0, 0.0]
        torques.publish(array([2.0, 1.0, -1.0]))
        client.spin_until(lambda: applied[-1][1] == [2.0, 1.0, -1.0], 10.0, "the torque held")
        on = applied[-1][0]
        client.spin_until(lambda: applied[-1][1] == [0.0, 0.0, 0.0], 10.0, "the timeout")
        held_s = applied[-1][0] - on
        assert 0.3 < held_s < 2.0, held_s                 # command_timeout 0.4 s (wall)
        torques.publish(array([1.0]))                      # rejected; the node keeps going
        client.spin_until(lambda: diags and diag_values(diags[-1])["hinge_torques_rejected"]
                          == "1", 10.0, "the rejection on diagnostics", node)
        t0 = float(diag_values(diags[-1])["sim_time_s"])
        n_diag = len(diags)
        client.spin_until(lambda: len(diags) > n_diag, 5.0, "the next diagnostics", node)
        assert float(diag_values(diags[-1])["sim_time_s"]) > t0 + 0.5
        assert diag_values(diags[-1])["hinge_torques_active"] == "false"
        assert "expected 3 values" in diag_values(diags[-1])["last_rejection"]
    finally:
        client.close()
        assert node.stop() == 0, node.stderr


# ----- physics through the node -----

ONE_ROD = """name: one_damped_rod
rods: {count: 1, length: 1.0, mass_per_length: 2.0, bending_stiffness: 2.0e3}
nodes: {mass: 0.5}
hinges: {stiffness: 40.0, damping: 20.0}
initial: {phi: 0.0, phi_rate: 0.0}
"""


@pytest.mark.slow
def test_held_torque_deflects_one_rod_to_t_over_kappa(tmp_path, monkeypatch):
    """A hand calculation: one rod, hinge 0 spring kappa_0 = 40 N m/rad, motor T = 2 N m:
    phi_1 -> T / kappa_0 = 0.05 rad (overdamped, time constant ~ nu / kappa = 0.5 s); the
    energy balance with the motor's work closes."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_STATIC))
    scene = tmp_path / "one_rod.yaml"
    scene.write_text(ONE_ROD)
    ns = unique_namespace()
    node = NodeProcess(tmp_path, DOMAIN_STATIC, extra=["-r", f"__ns:={ns}"],
                       scene_file=scene, sync_mode=True)
    client = Client(DOMAIN_STATIC, namespace=ns)
    try:
        node.wait_for_output("commands on")
        c = client.node
        torques = c.create_publisher(Float64MultiArray, "hinge_torques", 10)
        states, diags = [], []
        c.create_subscription(JointState, "joint_states", states.append, LATCHED)
        c.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
        client.spin_until(lambda: states and torques.get_subscription_count() > 0, 30.0,
                          "discovery", node)
        for _ in range(800):                          # 8 s: 16 time constants
            before = stamp_ns(states[-1])
            torques.publish(array([2.0]))
            client.spin_until(lambda: stamp_ns(states[-1]) > before, 30.0, "a state", node)
        q = states[-1].position[0]
        assert q == pytest.approx(2.0 / 40.0, abs=1e-6)
        assert abs(states[-1].velocity[0]) < 1e-5
        n_diag = len(diags)
        client.spin_until(lambda: len(diags) > n_diag, 5.0, "diagnostics", node)
        values = diag_values(diags[-1])
        energy = float(values["energy_J"])            # 1/2 kappa q^2 = 0.05 J at rest
        assert energy == pytest.approx(0.5 * 40.0 * 0.05**2, rel=1e-4)
        # motor work T q = 0.1 J = energy 0.05 J + damper losses 0.05 J; without the motor's
        # power the residual would be -0.1 J; the trapezoid rule over 10 ms periods leaves
        # ~3e-5 J (the start, where the rate rises within I / nu ~ 0.06 s)
        assert abs(float(values["energy_balance_residual_J"])) < 1e-3 * 0.1, values
    finally:
        client.close()
        assert node.stop() == 0, node.stderr
