"""Spacecraft outputs (SPEC section 8, issue 28 items 2-3): base_odometry as nav_msgs defines it
(our CDR bytes = rclpy's serialize_message), node_poses / joint_states / markers with the base,
the momentum ledger, and from separate processes: `rod-sim simulate` logs base_odometry and the
ledger on /diagnostics, `rod-sim compare` checks the base and every chain from the log alone
(passes an honest log, fails a tampered base), and the URDF of `rod-sim urdf` (parsed by
yourdfpy, forward kinematics composed here) reproduces the logged node_poses of a free base in
motion to 1e-9 m."""
from __future__ import annotations

import io
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from rod_sim.core.models import make_model
from rod_sim.io import encoders, topics
from rod_sim.io.scene_yaml import load_scene

REPO = Path(__file__).resolve().parents[1]
TWO_WING = REPO / "config" / "two_wing_deployment.yaml"
SPIN_UP = REPO / "config" / "spin_up_beam.yaml"


def cli(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


def moving_scene(tmp_path: Path) -> Path:
    """The two-wing scene with the bus drifting and turning from the start."""
    d = yaml.safe_load(TWO_WING.read_text())
    d["base"]["initial"] = {"x": 0.4, "y": -0.3, "psi": 0.2, "x_rate": 0.3, "y_rate": -0.2,
                            "psi_rate": 0.15}
    path = tmp_path / "moving.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


def snapshot_in_motion(path=TWO_WING, t=0.37):
    scene = load_scene(path)
    model = make_model("reduced", scene)
    y = model.initial_state()
    rng = np.random.default_rng(3)
    y = y + rng.normal(0.0, 0.2, y.size)        # a general state: base moved and turning
    return scene, model, model.snapshot(t, y)


# ----- base_odometry: the bytes of rclpy's serializer -----

def odometry_message(snap, frame_id):
    from nav_msgs.msg import Odometry

    x, y, psi, vx, vy, w = (float(v) for v in snap.base)
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(round(snap.t * 1e9), 10**9)
    msg.header.frame_id = frame_id
    msg.child_frame_id = "base"
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(psi / 2), math.cos(psi / 2)
    # twist in the child frame (nav_msgs): the inertial velocity turned by -psi
    msg.twist.twist.linear.x = math.cos(psi) * vx + math.sin(psi) * vy
    msg.twist.twist.linear.y = -math.sin(psi) * vx + math.cos(psi) * vy
    msg.twist.twist.angular.z = w
    return msg


@pytest.mark.parametrize("path", [TWO_WING, SPIN_UP])
@pytest.mark.parametrize("frame", ["world", "odom"])
def test_base_odometry_bytes_are_rclpys(path, frame):
    """Our bytes decode (rclpy) to the message built here from the snapshot by nav_msgs'
    definition, and equal rclpy's serialize_message of it except in the alignment padding
    that Fast CDR leaves uninitialised (ours: zero) -- as test_encoders checks every topic."""
    pytest.importorskip("rclpy")
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message

    from rod_sim.io import cdr

    scene, _, snap = snapshot_in_motion(path)
    ours = encoders.base_odometry(snap, scene, frame)
    msg = odometry_message(snap, frame)
    assert deserialize_message(ours, Odometry) == msg
    theirs = serialize_message(msg)
    assert len(theirs) >= len(ours)
    differ = [i for i in range(len(ours)) if theirs[i] != ours[i]]
    end = 8 + 4 + len(frame) + 1                       # stamp, frame_id (CDR offsets)
    padding = list(range(4 + end, 4 + end + (-end % 4)))   # align child_frame_id's length
    end += -end % 4 + 4 + len("base") + 1              # child_frame_id; then align to 8
    padding += range(4 + end, 4 + end + (-end % 8))    # (+4: the encapsulation header)
    assert all(i in padding and ours[i] == 0 for i in differ), differ
    assert ours == cdr.encoder("nav_msgs/msg/Odometry")(topics.base_odometry(snap, frame))


def test_base_odometry_only_for_a_moving_base():
    from rod_sim.ros.outputs import BY_NAME

    entry = BY_NAME["base_odometry"]
    assert entry.is_state and entry.type_name == "nav_msgs/msg/Odometry"
    assert entry.exists_for(load_scene(TWO_WING)) and entry.exists_for(load_scene(SPIN_UP))
    assert not entry.exists_for(load_scene(REPO / "config" / "paper_example.yaml"))


def test_state_topics_carry_the_base_and_every_chain():
    pytest.importorskip("rclpy")
    from geometry_msgs.msg import PoseArray
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray

    scene, model, snap = snapshot_in_motion()
    n, nc = scene.n, len(scene.chains)
    js = deserialize_message(encoders.joint_states(snap, scene, "world"), JointState)
    assert js.name[:n] == [f"{c.name}/hinge_{h}" for c in scene.chains for h in range(c.count)]
    assert js.name[n:] == ["base_x", "base_y", "base_psi"]
    assert np.allclose(js.position[n:], snap.base[:3]) and np.allclose(js.velocity[n:],
                                                                       snap.base[3:])
    poses = deserialize_message(encoders.node_poses(snap, scene, "world"), PoseArray).poses
    assert len(poses) == n + nc + 1
    last = poses[-1]
    assert (last.position.x, last.position.y) == tuple(snap.base[:2])
    assert math.isclose(2 * math.atan2(last.orientation.z, last.orientation.w),
                        math.remainder(snap.base[2], 2 * math.pi), abs_tol=1e-12)
    # the chains' node 0 at the attach points, turned with the base
    c, s = math.cos(snap.base[2]), math.sin(snap.base[2])
    for ci, chain in enumerate(scene.chains):
        ax, ay = chain.attach
        p = poses[chain.start + ci].position
        assert math.isclose(p.x, snap.base[0] + c * ax - s * ay, abs_tol=1e-12)
        assert math.isclose(p.y, snap.base[1] + s * ax + c * ay, abs_tol=1e-12)
    markers = deserialize_message(encoders.markers(snap, scene, "world"), MarkerArray).markers
    box = [m for m in markers if m.ns == "base"]
    assert len(box) == 1 and box[0].type == 1 and box[0].scale.x == encoders.base_box(scene)
    rods = [m for m in markers if m.ns == "rods"]
    colours = {(m.color.r, m.color.g, m.color.b) for m in rods}
    assert len(rods) == n and len(colours) == nc
    # each rod strip starts at its node of node_poses (bent rods end where the chords do)
    for k, m in enumerate(rods):
        p = poses[k + scene.chain_of_rod[k]].position
        assert math.isclose(m.points[0].x, p.x, abs_tol=1e-9)
        assert math.isclose(m.points[0].y, p.y, abs_tol=1e-9)


def test_plain_scene_snapshot_has_no_spacecraft_fields():
    scene = load_scene(REPO / "config" / "paper_example.yaml")
    snap = make_model("reduced", scene).snapshot(0.0, make_model("reduced", scene).initial_state())
    assert snap.base is None and snap.momentum is None and snap.energy_terms is None


# ----- the momentum ledger -----

def ledger_run(path, rate, model_name="reduced", t_end=1.0):
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.ledger import SpacecraftLedger
    from rod_sim.core.simulator import Simulator

    scene = load_scene(path)
    model = make_model(model_name, scene)
    traj = Simulator(model, make_integrator("dop853-jit", rtol=1e-11, atol=1e-11)).run(t_end,
                                                                                      rate)
    ledger = SpacecraftLedger(model)
    for i in range(traj.t.size):
        ledger.add(traj.t[i], traj.y[i], None, None if traj.modes is None else traj.modes[i])
    return model, traj, ledger


def test_prescribed_base_ledger_closes_with_the_support_reaction():
    """The spin-up hub pushes the beam: without the hub's reaction P would not balance; with
    it the residual is quadrature error, falling as dt^2, and the injected work is the
    beam's energy gain (no dampers, locked hinges)."""
    res = {}
    for rate in (200.0, 800.0):
        model, traj, ledger = ledger_run(SPIN_UP, rate)
        v = ledger.values()
        res[rate] = (abs(v["momentum_balance_residual_y"]),
                     abs(v["angular_momentum_balance_residual"]))
        e0 = model.snapshot(0.0, traj.y[0]).energy_terms["total"]
        e1 = model.snapshot(traj.t[-1], traj.y[-1]).energy_terms["total"]
        assert abs(v["work_injected"] - (e1 - e0)) < 1e-3 * abs(e1 - e0) + 200 / rate**2
    p = model.snapshot(traj.t[-1], traj.y[-1]).momentum
    assert abs(p[1]) > 0.5                          # the beam gained momentum from the hub
    assert res[800.0][0] < res[200.0][0] / 10 and res[800.0][1] < res[200.0][1] / 10
    assert res[800.0][0] < 1e-5 * abs(p[1])


def test_free_base_ledger_conserves_momentum():
    model, traj, ledger = ledger_run(TWO_WING, 100.0)
    v = ledger.values()
    assert abs(v["momentum_balance_residual_x"]) < 1e-10
    assert abs(v["angular_momentum_balance_residual"]) < 1e-8
    assert v["work_injected"] == 0.0


# ----- separate processes: simulate, compare, urdf -----

def read_log(path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list] = {}
    with open(path, "rb") as f:
        for _, channel, message, msg in make_reader(
                f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            out.setdefault(channel.topic, []).append((message.log_time, msg))
    return out


DIAGNOSTIC_KEYS = ("linear_momentum_x_kg_m_s", "angular_momentum_origin_kg_m2_s",
                   "angular_momentum_com_kg_m2_s", "centre_of_mass_x_m", "energy_gravity_J",
                   "energy_base_kinetic_J", "energy_wheel_kinetic_J", "work_injected_J",
                   "momentum_balance_residual_x_kg_m_s",
                   "angular_momentum_balance_residual_kg_m2_s", "base_psi_rad")


@pytest.fixture(scope="module")
def two_wing_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("sc") / "two_wing.mcap"
    r = cli("simulate", str(TWO_WING), "--t-end", "1.5", "--out", str(out))
    assert r.returncode == 0, r.stderr
    return out


def test_simulate_logs_base_odometry_and_the_ledger(two_wing_log):
    log = read_log(two_wing_log)
    states, odo, diag = log["/rod_states"], log["/base_odometry"], log["/diagnostics"]
    assert len(odo) == len(states) == len(diag) == 151
    values = {kv.key: kv.value for kv in diag[-1][1].status[0].values}
    assert set(DIAGNOSTIC_KEYS) <= set(values)
    psi = 2 * math.atan2(odo[-1][1].pose.pose.orientation.z, odo[-1][1].pose.pose.orientation.w)
    assert abs(psi) > 1e-3                        # the bus turns as the wings unfold
    assert math.isclose(float(values["base_psi_rad"]), psi, rel_tol=1e-12)
    assert abs(float(values["angular_momentum_origin_kg_m2_s"])) < 1e-6
    assert odo[-1][1].child_frame_id == "base" and odo[-1][1].header.frame_id == "world"


def test_plain_simulate_log_has_no_spacecraft_topics(tmp_path):
    out = tmp_path / "paper.mcap"
    r = cli("simulate", str(REPO / "config" / "small_chain.yaml"), "--t-end", "0.05", "--out",
            str(out))
    assert r.returncode == 0, r.stderr
    assert not {"/base_odometry", "/diagnostics"} & set(read_log(out))


def tampered(src: Path, dst: Path, dx: float) -> None:
    """A copy of ``src`` whose base_odometry is shifted by ``dx`` [m] from t = 0.5 s on."""
    import dataclasses

    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message
    from test_compare import rewrite

    def shift(items):
        out = []
        for schema, channel, msg in items:
            if channel.topic == "/base_odometry" and msg.log_time >= 500_000_000:
                odo = deserialize_message(msg.data, Odometry)
                odo.pose.pose.position.x += dx
                msg = dataclasses.replace(msg, data=serialize_message(odo))
            out.append((schema, channel, msg))
        return out

    rewrite(src, dst, shift)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_compare_checks_the_base_and_every_chain(two_wing_log, tmp_path):
    pytest.importorskip("rclpy")
    import json

    r = cli("compare", str(two_wing_log), "--json")
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads(r.stdout)
    sc = report["spacecraft"]
    assert [c["chain"] for c in sc["chains"]] == ["left", "right"]
    assert all(c["max_hinge_angle_error"] < 1e-2 for c in sc["chains"])
    assert sc["base"]["samples"] == 151 and sc["base"]["max_psi_error"] < 1e-2
    bad = tmp_path / "tampered.mcap"
    tampered(two_wing_log, bad, 0.5)
    r = cli("compare", str(bad))
    assert r.returncode == 1, r.stdout + r.stderr
    fail = [line for line in r.stdout.splitlines() if line.startswith("FAIL")]
    assert fail and "base: max |position error| 0.5" in r.stdout, r.stdout


# ----- URDF: forward kinematics by an independent parser -----

def transform(joint, q: float) -> np.ndarray:
    """The joint's origin then its motion by q (revolute: about its axis; prismatic: along
    it), 4x4."""
    origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin)
    motion = np.eye(4)
    axis = np.asarray(joint.axis, dtype=float)
    if joint.type == "revolute":
        x, y, z = axis / np.linalg.norm(axis)
        k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
        motion[:3, :3] = np.eye(3) + math.sin(q) * k + (1.0 - math.cos(q)) * (k @ k)
    elif joint.type == "prismatic":
        motion[:3, 3] = q * axis
    return origin @ motion


def test_urdf_forward_kinematics_gives_node_poses_on_a_moving_base(tmp_path):
    yourdfpy = pytest.importorskip("yourdfpy")
    scene_path = moving_scene(tmp_path)
    r = cli("urdf", str(scene_path))
    assert r.returncode == 0, r.stderr
    robot = yourdfpy.URDF.load(io.BytesIO(r.stdout.encode()), load_meshes=False,
                               build_collision_scene_graph=False)
    assert {"base", "left/rod_1", "right/tip"} <= set(robot.link_map)
    assert robot.joint_map["base_x"].type == "prismatic"
    out = tmp_path / "moving.mcap"
    r = cli("simulate", str(scene_path), "--t-end", "0.5", "--rate", "20", "--out", str(out))
    assert r.returncode == 0, r.stderr
    log = read_log(out)
    scene = load_scene(scene_path)
    worst = 0.0
    for (_, js), (_, poses) in zip(log["/joint_states"], log["/node_poses"]):
        q = dict(zip(js.name, js.position))
        frames = {robot.base_link: np.eye(4)}
        pending = list(robot.robot.joints)
        while pending:
            joint = next(j for j in pending if j.parent in frames)
            pending.remove(joint)
            frames[joint.child] = frames[joint.parent] @ transform(joint, q.get(joint.name, 0.0))
        links = [f"{c.name}/{name}" for c in scene.chains
                 for name in [f"rod_{k}" for k in range(1, c.count + 1)] + ["tip"]] + ["base"]
        fk = np.array([frames[link][:2, 3] for link in links])
        logged = np.array([[p.position.x, p.position.y] for p in poses.poses])
        worst = max(worst, float(np.max(np.abs(fk - logged))))
    assert abs(q["base_x"] - 0.4) > 0.1 and worst < 1e-9, worst


SPINNING_PAIR = """
name: spinning_pair
base:
  mode: free
  mass: 100.0
  inertia: 50.0
  initial: {psi_rate: 0.1}
  {wheel}
chains:
  - name: east
    attach: [1.0, 0.0]
    rods: {count: 4, length: 0.5, mass_per_length: 0.2, bending_stiffness: 5.0}
    nodes: {mass: 0.01}
    hinges: {stiffness: 0.0, damping: 1.0e-4}
    initial: {phi: 0.0, phi_rate: 0.1}
  - name: west
    attach: [-1.0, 0.0]
    rods: {count: 4, length: 0.5, mass_per_length: 0.2, bending_stiffness: 5.0}
    nodes: {mass: 0.01}
    hinges: {stiffness: 0.0, damping: 1.0e-4}
    initial: {phi: 3.141592653589793, phi_rate: 0.1}
"""


@pytest.mark.parametrize("wheel", ["", "wheel: {inertia: 0.05, rate: 2.0}"])
def test_compare_reads_the_reference_rates_past_the_base_coordinates(tmp_path, wheel):
    """A free base and two straight radial chains all turning at 0.1 rad/s: a relative
    equilibrium of both models (the centrifugal load keeps the limp chains straight), so every
    rod's rate is 0.1 rad/s in the log and in compare's full-model re-run. compare took the
    re-run's rates from the state's columns 3n..4n, where a free base's coordinates (x_B, y_B,
    psi[, theta_w]) come first: rods 1-3 were compared with the base's pose (errors 0.1
    rad/s on tether_pair)."""
    scene = tmp_path / "spinning_pair.yaml"
    scene.write_text(SPINNING_PAIR.replace("{wheel}", wheel))
    log = tmp_path / "spin.mcap"
    assert cli("simulate", str(scene), "--t-end", "0.3", "--out", str(log)).returncode == 0
    r = cli("compare", str(log), "--json")
    report = json.loads(r.stdout)
    assert report["max_abs_error"]["phi"] < 1e-7, report["max_abs_error"]
    assert report["max_abs_error"]["phi_rate"] < 1e-6, report["max_abs_error"]
