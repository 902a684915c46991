"""Issue 20 item 3: the chain as URDF for the standard tools, met as a user meets it:
`rod-sim urdf SCENE` parses with a URDF parser from PyPI (yourdfpy) with the masses of a hand
calculation, and the node's latched ``robot_description`` + ``joint_states`` give, by forward
kinematics in that parser, the node positions of ``node_poses`` to 1e-9 m. ROS domain id from
ros_domains."""
from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from ros_domains import next_domain  # noqa: E402

yourdfpy = pytest.importorskip("yourdfpy")

REPO = Path(__file__).resolve().parents[1]
SMALL = REPO / "config" / "small_chain.yaml"
PAPER = REPO / "config" / "paper_example.yaml"
DOMAIN = next_domain()


def parse(text: str):
    return yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False,
                              build_collision_scene_graph=False)


def urdf_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "urdf", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=60)


def rotation(axis, angle: float) -> np.ndarray:
    """4x4 rotation by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    x, y, z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    out = np.eye(4)
    out[:3, :3] = np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)
    return out


def node_positions(robot, joint_names, q) -> np.ndarray:
    """(n+1, 3) positions [m] of the frames of rod_1..rod_n and tip in the root frame:
    forward kinematics over the joints as the parser read them (origin, axis, parent, child).
    (yourdfpy's own update_cfg/get_transform goes through trimesh's cached scene graph, which
    left joint angles of ~1e-9 rad unapplied: errors of 1e-8 m at the first periods.)"""
    angle = dict(zip(joint_names, q))
    frames = {robot.base_link: np.eye(4)}
    pending = list(robot.robot.joints)
    while pending:
        joint = next(j for j in pending if j.parent in frames)
        pending.remove(joint)
        origin = np.eye(4) if joint.origin is None else joint.origin
        motion = rotation(joint.axis, angle[joint.name]) if joint.type == "revolute" else np.eye(4)
        frames[joint.child] = frames[joint.parent] @ origin @ motion
    links = [f"rod_{k}" for k in range(1, len(q) + 1)] + ["tip"]
    return np.array([frames[link][:3, 3] for link in links])


def test_rod_sim_urdf_parses_with_the_hand_calculated_masses(tmp_path):
    done = urdf_cli(str(SMALL))
    assert done.returncode == 0, done.stderr
    robot = parse(done.stdout)
    assert robot.base_link == "world"
    assert set(robot.link_map) == {"world", "rod_1", "rod_2", "rod_3", "tip"}
    assert robot.actuated_joint_names == ["hinge_0", "hinge_1", "hinge_2"]
    assert all(robot.joint_map[j].type == "revolute" for j in robot.actuated_joint_names)
    # rod 1: l = 1 m, 2 kg/m, node mass 1 kg at its end: M = 3 kg, x_c = 2/3 m,
    # I_c = 2/12 + 2 (1/2 - 2/3)^2 + 1 (1/3)^2 = 1/3 kg m^2
    inertial = robot.link_map["rod_1"].inertial
    assert inertial.mass == pytest.approx(3.0)
    assert inertial.origin[:3, 3] == pytest.approx([2 / 3, 0.0, 0.0])
    assert inertial.inertia[2, 2] == pytest.approx(1 / 3)
    # straight chain (all hinge angles 0): the tip at l1 + l2 + l3 = 2.4 m on x
    tip = node_positions(robot, robot.actuated_joint_names, [0.0, 0.0, 0.0])[-1]
    assert tip == pytest.approx([2.4, 0.0, 0.0])

    out = tmp_path / "chain.urdf"
    assert urdf_cli(str(SMALL), "--out", str(out), "--frame-id", "map").returncode == 0
    assert parse(out.read_text()).base_link == "map"
    again = urdf_cli(str(SMALL), "--out", str(out))
    assert again.returncode == 2 and "exists" in again.stderr


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_robot_description_and_joint_states_reproduce_node_poses(tmp_path, monkeypatch):
    rclpy = pytest.importorskip("rclpy")
    from geometry_msgs.msg import PoseArray
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from ros_graph import Client, NodeProcess, stamp_ns, unique_namespace

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    ns = unique_namespace()
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"], scene_file=PAPER)
    client = Client(DOMAIN, namespace=ns)
    try:
        node.wait_for_output("commands on")
        joints: dict[int, JointState] = {}
        poses: dict[int, PoseArray] = {}
        description: list[str] = []
        c = client.node
        c.create_subscription(JointState, "joint_states",
                              lambda m: joints.setdefault(stamp_ns(m), m), 10)
        c.create_subscription(PoseArray, "node_poses",
                              lambda m: poses.setdefault(stamp_ns(m), m), 10)
        c.create_subscription(String, "robot_description", lambda m: description.append(m.data),
                              QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        client.spin_until(lambda: description and len(set(joints) & set(poses)) >= 100, 30.0,
                          lambda: f"robot_description and 100 states ({len(description)}, "
                          f"{len(joints)}, {len(poses)})", node)
    finally:
        client.close()
        node.kill()
    robot = parse(description[0])
    assert robot.base_link == "world"
    common = sorted(set(joints) & set(poses))
    worst, moved = 0.0, 0.0
    for t in common:
        js = joints[t]
        assert list(js.name) == robot.actuated_joint_names
        fk = node_positions(robot, list(js.name), list(js.position))
        logged = np.array([[p.position.x, p.position.y, p.position.z] for p in poses[t].poses])
        worst = max(worst, float(np.max(np.abs(fk - logged))))
        moved = max(moved, float(np.max(np.abs(np.asarray(js.position)))))
    assert worst <= 1e-9
    assert moved > 1e-3, "the chain should have moved (the scripted pulse)"
