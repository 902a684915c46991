"""A demo attitude controller: PD control of a free base's angle psi through ``base_wrench``.

For every state the node publishes it sends one ``base_wrench`` command (frame ``world``,
force 0, torque z)

    M = clip(kp (psi_ref - psi) - kd psi_dot, -max_moment, max_moment)   [N m]

so it drives a lockstep simulator one period per state, as the hinge PD controller does
(:mod:`rod_sim.ros.controller`); while no state has arrived and the simulator listens it sends
a zero wrench every ``kickoff_period`` [s] to start it. A state repeated with the same stamp
(a lockstep node waiting for its first command) is answered once.

The base's attitude is read from the node's ``base_odometry`` (nav_msgs/Odometry, one message
per state): psi = 2 atan2(q_z, q_w) of its pose, psi_dot = ``twist.angular.z``
(:func:`odometry_angle`).

Gains: the default kp 5000 N m/rad, kd 3000 N m s/rad hold the bus of
config/two_wing_deployment.yaml (J_B 900 kg m^2, ~6000 kg m^2 with the wings out) within a few
hundredths of a radian while the wings deploy; kd dt must stay well below the base's inertia
(dt the control period).
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node

from rod_sim.ros.controller import _ranged
from rod_sim.ros.process import parse_cli, run_node

ATTITUDE_NAME = "rod_sim_attitude"


def attitude_moment(psi: float, psi_rate: float, psi_ref: float, kp: float, kd: float,
                    max_moment: float = math.inf) -> float:
    """The PD moment on the base [N m]: kp (psi_ref - psi) - kd psi_rate, limited to
    +-``max_moment``; angles [rad] (the error wrapped into [-pi, pi)), rates [rad/s]."""
    error = (psi_ref - psi + math.pi) % (2.0 * math.pi) - math.pi
    return float(np.clip(kp * error - kd * psi_rate, -max_moment, max_moment))


def odometry_angle(msg) -> tuple[float, float]:
    """(psi [rad] in (-pi, pi], psi_dot [rad/s]) of a ``base_odometry`` message."""
    q = msg.pose.pose.orientation
    return 2.0 * math.atan2(q.z, q.w), float(msg.twist.twist.angular.z)


class AttitudePDController(Node):
    """The controller node (parameters: kp, kd, target, max_moment, kickoff_period; ``chain``
    is kept for compatibility and no longer used).
    ``node_kwargs`` go to :class:`rclpy.node.Node`. ``psi_history``: (t [s], psi [rad])
    of every state answered."""

    def __init__(self, **node_kwargs):
        super().__init__(ATTITUDE_NAME, **node_kwargs)
        self.kp = self.declare_parameter("kp", 5000.0, _ranged(
            0.0, 1e9, "proportional gain [N m/rad]")).value
        self.kd = self.declare_parameter("kd", 3000.0, _ranged(
            0.0, 1e9, "derivative gain [N m s/rad]")).value
        self.target = self.declare_parameter("target", 0.0, _ranged(
            -math.pi, math.pi, "target base angle psi [rad]")).value
        self.max_moment = self.declare_parameter("max_moment", 1e4, _ranged(
            0.0, 1e9, "largest base moment asked for [N m]")).value
        self.chain = self.declare_parameter("chain", "", _text_parameter(
            "unused (psi comes from base_odometry); kept so that old launch files load")).value
        kickoff = self.declare_parameter("kickoff_period", 0.5, _ranged(
            0.01, 60.0, "[s] between zero commands sent to start a lockstep simulator")).value
        self.commands_sent = 0
        self.psi_history: list[tuple[float, float]] = []
        self._states_seen = 0
        self._answered: tuple[int, int] | None = None
        self._pub = self.create_publisher(WrenchStamped, "base_wrench", 10)
        self.create_subscription(Odometry, "base_odometry", self._on_state, 10)
        self.create_timer(kickoff, self._kickoff)
        self.summary = (
            f"PD on the base angle: kp {self.kp:g} N m/rad, kd {self.kd:g} N m s/rad, target "
            f"{self.target:g} rad, max moment {self.max_moment:g} N m; reads "
            f"{self.resolve_topic_name('base_odometry')}, writes "
            f"{self.resolve_topic_name('base_wrench')}")
        self.get_logger().info(self.summary)

    def _on_state(self, msg: Odometry) -> None:
        self._states_seen += 1
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        if stamp == self._answered:
            return      # a lockstep node waiting for its first command repeats its state
        self._answered = stamp
        psi, psi_rate = odometry_angle(msg)
        self.psi_history.append((stamp[0] + 1e-9 * stamp[1], psi))
        self._send(attitude_moment(psi, psi_rate, self.target, self.kp, self.kd,
                                   self.max_moment))

    def _kickoff(self) -> None:
        if self._states_seen == 0 and self._pub.get_subscription_count():
            self._send(0.0)

    def _send(self, moment: float) -> None:
        msg = WrenchStamped()
        msg.header.frame_id = "world"
        msg.wrench.torque.z = float(moment)
        self._pub.publish(msg)
        self.commands_sent += 1


def _text_parameter(description: str):
    from rcl_interfaces.msg import ParameterDescriptor

    return ParameterDescriptor(description=description, read_only=True)


def build_parser() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(
        prog="attitude_controller", description="rod_sim's demo attitude controller (node "
        f"{ATTITUDE_NAME}): PD control of a free base's angle (from base_odometry) "
        "through base_wrench, one command per state, so it also drives a "
        "lockstep simulator. Configure it with ROS arguments, e.g. --ros-args -p kp:=5000.0 "
        "-p kd:=3000.0",
        epilog="parameters: kp [N m/rad] (default 5000.0), kd [N m s/rad] (3000.0), target "
        "[rad] (0.0), max_moment [N m] (1e4), kickoff_period [s] (0.5)")


def main(argv: list[str] | None = None) -> int:
    """Run the controller until SIGINT/SIGTERM; 2 for bad arguments."""
    args = list(sys.argv[1:] if argv is None else argv)
    parse_cli(build_parser(), args)
    return run_node("attitude_controller", AttitudePDController, args, ValueError)


if __name__ == "__main__":
    sys.exit(main())
