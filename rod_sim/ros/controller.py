"""A demo controller node: PD control of the hinge angles, acting through nodal forces; and the
documented helpers between hinge torques and nodal forces (:func:`hinge_forces`: torques ->
``nodal_forces`` command, :func:`hinge_torques`: nodal forces -> equivalent hinge torques,
:func:`hinge_moments`: the PD law), usable from any controller.

For each hinge h = 0..n-1 it asks for the moment M_h = kp (q_ref_h - q_h) - kd q_dot_h [N m]
(q_h, q_dot_h from ``joint_states``) and realises it with nodal forces: rod k receives the
couple C_k = M_{k-1} - M_k (M_n = 0) as a force C_k / l_k perpendicular to the rod at node k
and the opposite force at node k-1 (none at node 0, the ground). These forces do the same
virtual work as ideal hinge actuators: the generalized force on each hinge angle is M_h.

The default gains (kp 2000 N m/rad, kd 200 N m s/rad) suit the paper's example
(config/paper_example.yaml): with a zero target they damp the chain and pull it back toward
straight; they are far too soft to hold it straight against the scripted tip pulse (1200 N at
16 m), which swings the chain through several radians. Much stiffer gains (e.g. kp 2e4, kd 300
at 100 Hz) excite the rods' bending, and ``rod-sim compare`` then shows the reduced model off
by radians: a good test of the comparison, not a good controller.
Gains must fit the scene: with the command held over a control period dt, kd dt must stay
well below the smallest effective inertia [kg m^2] of the chain's fast modes, or the loop
goes unstable.

It publishes one ``nodal_forces`` command per received ``joint_states`` state (a state
repeated with the same stamp is answered once), so it works
both at a real-time pace and in the simulator's lockstep mode. In lockstep the simulator waits
for a first command: while no state has arrived and the simulator listens, the controller sends
a zero command every ``kickoff_period`` [s] to start it.

Rod lengths l_k [m] come from the ``scene_file`` parameter, or, when it is empty, from the
first ``node_poses`` message (chords are inextensible, so they never change).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from rod_sim.core.scene import SceneError
from rod_sim.io import topics
from rod_sim.io.scene_yaml import load_scene
from rod_sim.ros.conversions import to_message
from rod_sim.ros.process import parse_cli, run_node

CONTROLLER_NAME = "rod_sim_controller"


def hinge_moments(q, q_rate, q_ref, kp: float, kd: float) -> np.ndarray:
    """PD hinge moments M_h = kp (q_ref_h - q_h) - kd q_dot_h [N m], each (n,); angles [rad],
    rates [rad/s], kp [N m/rad], kd [N m s/rad]."""
    q, q_rate, q_ref = (np.asarray(a, dtype=float) for a in (q, q_rate, q_ref))
    return kp * (q_ref - q) - kd * q_rate


def hinge_forces(moments, phi, lengths) -> np.ndarray:
    """Nodal forces (n, 2) [N] at nodes 1..n equivalent to hinge moments ``moments`` (n,) [N m]
    acting between consecutive rods (hinge 0 between the ground and rod 1), for rod angles
    ``phi`` (n,) [rad] and rod lengths ``lengths`` (n,) [m].

    Public API (torques -> forces): a moment M_h at hinge h acts +M_h on rod h+1 and -M_h on
    rod h (hinge 0: rod 1 against the ground); rod k then carries the couple C_k = M_{k-1} - M_k,
    realised as the force C_k / l_k perpendicular to rod k at node k and its opposite at node
    k-1 (none at the ground). The forces do the same virtual work as the moments for every
    virtual motion of the chord angles (:func:`hinge_torques` of the result gives ``moments``
    back); flatten the result (``.ravel()``) for a ``nodal_forces`` command."""
    m = np.asarray(moments, dtype=float)
    phi = np.asarray(phi, dtype=float)
    lengths = np.asarray(lengths, dtype=float)
    couples = m - np.append(m[1:], 0.0)                 # C_k = M_{k-1} - M_k
    normal = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
    push = (couples / lengths)[:, None] * normal        # on node k (array row k-1)
    forces = push.copy()
    forces[:-1] -= push[1:]                             # reaction at node k-1, k >= 2
    return forces


def hinge_torques(forces, phi, lengths) -> np.ndarray:
    """The hinge moments (n,) [N m] equivalent to nodal forces ``forces`` (n, 2) or flat (2n,)
    [N] at nodes 1..n, for rod angles ``phi`` (n,) [rad] and rod lengths ``lengths`` (n,) [m]:
    the generalized forces of the relative hinge angles q_h (hinges 0..n-1, the ``joint_states``
    positions), i.e. the Jacobian transpose of the node positions,
    tau_h = sum_{j > h} l_j (-sin phi_j, cos phi_j) . sum_{k >= j} F_k.

    Public API (forces -> torques), the inverse direction of :func:`hinge_forces`:
    ``hinge_torques(hinge_forces(M, phi, l), phi, l) == M`` to rounding. Forces along the chords
    have no hinge moment (they load the inextensible chords)."""
    f = np.asarray(forces, dtype=float).reshape(-1, 2)
    phi = np.asarray(phi, dtype=float)
    lengths = np.asarray(lengths, dtype=float)
    outboard = np.cumsum(f[::-1], axis=0)[::-1]         # sum_{k >= j} F_k for rod j (row j-1)
    normal = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
    rod_moment = lengths * np.einsum("ij,ij->i", normal, outboard)   # generalized force on phi_j
    return np.cumsum(rod_moment[::-1])[::-1]            # tau_h = sum_{j >= h+1} Q_phi_j


def pd_forces(q, q_rate, q_ref, lengths, kp: float, kd: float,
              max_moment: float = np.inf) -> np.ndarray:
    """Nodal forces (n, 2) [N] of the hinge PD law for relative hinge angles ``q`` [rad] and
    rates [rad/s] (as ``joint_states`` publishes them), each hinge moment limited to
    +-``max_moment`` [N m] (limiting moments, not force components, keeps the couples pure)."""
    phi = np.cumsum(np.asarray(q, dtype=float))
    moments = np.clip(hinge_moments(q, q_rate, q_ref, kp, kd), -max_moment, max_moment)
    return hinge_forces(moments, phi, lengths)


def _ranged(low: float, high: float, description: str) -> ParameterDescriptor:
    return ParameterDescriptor(description=description, floating_point_range=[
        FloatingPointRange(from_value=low, to_value=high, step=0.0)])


class HingePDController(Node):
    """The controller node (parameters: kp, kd, target, max_moment, scene_file,
    kickoff_period). ``node_kwargs`` go to :class:`rclpy.node.Node`."""

    def __init__(self, **node_kwargs):
        super().__init__(CONTROLLER_NAME, **node_kwargs)
        self.kp = self.declare_parameter("kp", 2000.0, _ranged(
            0.0, 1e7, "proportional gain [N m/rad]")).value
        self.kd = self.declare_parameter("kd", 200.0, _ranged(
            0.0, 1e7, "derivative gain [N m s/rad]")).value
        self.target = np.asarray(self.declare_parameter("target", [0.0], ParameterDescriptor(
            description="target hinge angles [rad]: one value for every hinge, or one per "
                        "hinge 0..n-1")).value, dtype=float)
        self.max_moment = self.declare_parameter("max_moment", 1e5, _ranged(
            0.0, 1e9, "largest hinge moment asked for [N m]")).value
        scene_file = self.declare_parameter("scene_file", "", ParameterDescriptor(
            description="scene YAML giving the rod lengths; '' = learn them from node_poses",
            read_only=True)).value
        kickoff = self.declare_parameter("kickoff_period", 0.5, _ranged(
            0.01, 60.0, "[s] between zero commands sent to start a lockstep simulator")).value
        self.lengths = np.asarray(load_scene(scene_file).length) if scene_file else None
        self.n = len(self.lengths) if self.lengths is not None else None
        self.commands_sent = 0
        self._states_seen = 0
        self._answered: tuple[int, int] | None = None
        """Stamp of the last state answered (each state gets one command)."""
        self._pub = self.create_publisher(Float64MultiArray, "nodal_forces", 10)
        self.create_subscription(JointState, "joint_states", self._on_joint_states, 10)
        self.create_subscription(PoseArray, "node_poses", self._on_node_poses, 10)
        self.create_timer(kickoff, self._kickoff)
        self.summary = (
            f"PD on the hinge angles: kp {self.kp:g} N m/rad, kd {self.kd:g} N m s/rad, target "
            f"{', '.join(f'{v:g}' for v in self.target)} rad, max moment {self.max_moment:g} "
            f"N m; rod lengths from {scene_file or 'the first node_poses message'}; reads "
            f"{self.resolve_topic_name('joint_states')}, writes "
            f"{self.resolve_topic_name('nodal_forces')}")
        """The start-up INFO line: gains, scene and topics."""
        self.get_logger().info(self.summary)

    def _on_node_poses(self, msg: PoseArray) -> None:
        if self.lengths is not None or len(msg.poses) < 2:
            return
        p = np.array([[pose.position.x, pose.position.y] for pose in msg.poses])
        self.lengths = np.linalg.norm(np.diff(p, axis=0), axis=1)
        self.n = len(self.lengths)

    def _on_joint_states(self, msg: JointState) -> None:
        self._states_seen += 1
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        if stamp == self._answered:
            return      # a lockstep node waiting for its first command repeats its state
        self._answered = stamp
        if self.lengths is None or len(msg.position) != self.n or len(msg.velocity) != self.n:
            return
        if self.target.size not in (1, self.n):
            self.get_logger().error(f"target: {self.target.size} values for {self.n} hinges "
                                    "(give one, or one per hinge); no command sent",
                                    throttle_duration_sec=2.0)
            return
        q_ref = np.broadcast_to(self.target, (self.n,))
        forces = pd_forces(msg.position, msg.velocity, q_ref, self.lengths, self.kp, self.kd,
                           self.max_moment)
        self._send(forces)

    def _kickoff(self) -> None:
        if self._states_seen == 0 and self.n is not None and self._pub.get_subscription_count():
            self._send(np.zeros((self.n, 2)))

    def _send(self, forces: np.ndarray) -> None:
        self._pub.publish(to_message("std_msgs/msg/Float64MultiArray",
                                     topics.force_array(forces)))
        self.commands_sent += 1


def build_parser() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(
        prog="pd_controller", description="rod_sim's demo PD controller (node "
        f"{CONTROLLER_NAME}): PD control of the hinge angles (joint_states) through nodal "
        "force couples (nodal_forces), one command per state, so it also drives a lockstep "
        "simulator. Configure it with ROS arguments, e.g. --ros-args -p "
        "scene_file:=config/paper_example.yaml -p kp:=2000.0 -p kd:=200.0",
        epilog="parameters: kp [N m/rad] (default 2000.0), kd [N m s/rad] (200.0), target "
        "[rad] (one value or one per hinge, [0.0]), max_moment [N m] (1e5), scene_file "
        "('' = rod lengths from node_poses), kickoff_period [s] (0.5)")


def main(argv: list[str] | None = None) -> int:
    """Run the controller until SIGINT/SIGTERM; 2 for bad arguments or a bad scene_file."""
    args = list(sys.argv[1:] if argv is None else argv)
    parse_cli(build_parser(), args)
    return run_node("pd_controller", HingePDController, args, SceneError)

if __name__ == "__main__":
    sys.exit(main())
