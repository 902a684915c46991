"""Intake of the rod_sim node's commands (``nodal_forces``: 2 n values, ``hinge_torques``: n
values, n + 1 with a reaction wheel, ``base_wrench``: a geometry_msgs/WrenchStamped; what they
hold per chain: :mod:`rod_sim.ros.command_layout`; one :class:`CommandIntake` per topic): the
serialized command is refused by its length before it is decoded (an array command in plain
little-endian CDR straight from its bytes, :mod:`rod_sim.ros.command_cdr`; anything else by
rclpy), then validated; refusals are counted with their last reason; the latest valid command
is held (zero-order hold) until ``command_timeout``.

ROS-light: it decodes the messages but creates no ROS entity and logs nothing; the node
subscribes, records, logs and steps."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64MultiArray

from rod_sim.core.units import NS_PER_S
from rod_sim.ros.command_cdr import decode_float64_array
from rod_sim.ros.command_layout import CommandLayout
from rod_sim.ros.conversions import CommandError

COMMAND_SLACK_BYTES = 4096
"""Bytes a serialized command may carry beyond its 2 n (torques: n) doubles (header, layout,
labels)."""

FORCES, TORQUES, WRENCH = "nodal_forces", "hinge_torques", "base_wrench"
"""The command topics (relative names) and the kinds of :class:`CommandIntake`."""
MESSAGE_TYPES = {FORCES: "std_msgs/msg/Float64MultiArray",
                 TORQUES: "std_msgs/msg/Float64MultiArray",
                 WRENCH: "geometry_msgs/msg/WrenchStamped"}
"""Each command topic's ROS type name."""
_CLASSES = {FORCES: Float64MultiArray, TORQUES: Float64MultiArray, WRENCH: WrenchStamped}
_WIDTH = {FORCES: 2, TORQUES: 1}
_FAST = {FORCES: decode_float64_array, TORQUES: decode_float64_array}
"""Decoders straight from the bytes (None: not understood, decoded by rclpy instead)."""
WRENCH_VALUES = 6
"""Doubles in a WrenchStamped (force x, y, z and torque x, y, z)."""


@dataclass(frozen=True)
class Command:
    """A valid command: ``forces`` = nodal forces (n, 2) [N] (``kind`` nodal_forces), hinge
    torques (n,) [N m] followed by the wheel's motor torque with a wheel (``kind``
    hinge_torques), or the base wrench [Fx, Fy, M] [N, N, N m] (``kind`` base_wrench, in the
    base frame when ``body``, else in Oxy), received at wall ``wall_ns`` (monotonic) and at
    simulated time ``sim_ns``."""

    forces: np.ndarray
    wall_ns: int
    sim_ns: int
    kind: str = FORCES
    body: bool = False


class CommandIntake:
    """Commands of a scene of ``n`` rods on one topic (``kind``: :data:`FORCES`, 2 n values
    -> (n, 2) [N], :data:`TORQUES`, n values (n + 1 with a wheel) -> (n,) [N m], or
    :data:`WRENCH` -> [Fx, Fy, M]): counters, the latest valid command and its hold.
    ``layout``: the scene's :class:`~rod_sim.ros.command_layout.CommandLayout` (default: one
    chain of n rods on the ground); ``inertial_frame``: the ``frame_id`` of a wrench in Oxy.

    ``received`` and ``rejected`` count commands; ``last_rejection`` is the last reason;
    ``latest`` is the latest valid :class:`Command`; ``active`` says whether the last
    :meth:`held` force was a command (False once it timed out)."""

    def __init__(self, n: int, timeout_s: float, kind: str = FORCES,
                 layout: CommandLayout | None = None, inertial_frame: str = "world"):
        self.n = n
        self.kind = kind
        self.layout = CommandLayout.single(n) if layout is None else layout
        if self.layout.n != n:
            raise ValueError(f"layout of {self.layout.n} rods for an intake of {n}")
        self.inertial_frame = inertial_frame
        self.message_class = _CLASSES[kind]
        self._fast_decode = _FAST.get(kind)
        self.values = (WRENCH_VALUES if kind == WRENCH
                       else self.layout.values(_WIDTH[kind]))
        """Values a valid command holds."""
        self.max_bytes = 16 * self.values + COMMAND_SLACK_BYTES
        self.received = 0
        self.rejected = 0
        self.last_rejection = ""
        self.latest: Command | None = None
        self.active = False
        self.timeout_ns = 0
        self.set_timeout(timeout_s)
        self.zero = (np.zeros(3) if kind == WRENCH else np.zeros((n, 2)) if kind == FORCES
                      else np.zeros(self.values))

    def set_timeout(self, seconds: float) -> None:
        """``command_timeout`` [s]; 0 = hold forever."""
        self.timeout_ns = int(round(seconds * NS_PER_S))

    def clear(self) -> None:
        """Forget the held command (a reset); the counters go on."""
        self.latest = None
        self.active = False

    def decode(self, data: bytes):
        """The message in the serialized ``data``, or None (counted as received and rejected)
        when it is too long for a command of :attr:`values` values (checked before any
        decoding: an 80 MB message must not stall the node) or cannot be decoded.

        An array command in plain little-endian CDR is decoded straight from the bytes
        (:func:`~rod_sim.ros.command_cdr.decode_float64_array`: an object with the message's
        fields, ``data`` a read-only float64 view); anything that decoder does not read
        exactly, and a wrench, is decoded by rclpy's ``deserialize_message``."""
        if len(data) > self.max_bytes:
            self.received += 1
            self.reject(f"{len(data)} bytes, more than the {self.max_bytes} a command "
                        f"of {self.values} values may take (not recorded)")
            return None
        if self._fast_decode is not None:
            msg = self._fast_decode(data)
            if msg is not None:
                return msg
        try:
            return deserialize_message(data, self.message_class)
        except Exception as exc:  # noqa: BLE001 -- any undecodable payload is one rejection
            self.received += 1
            self.reject(f"cannot be decoded ({type(exc).__name__}; not recorded)")
            return None

    def reject(self, reason: str) -> None:
        """Count a refused command and keep its ``reason``."""
        self.rejected += 1
        self.last_rejection = reason

    def accept(self, msg, sim_ns: int) -> Command | None:
        """Count and validate a decoded command received at simulated time ``sim_ns``: the
        new latest command, or None (rejected, the last valid one is kept)."""
        self.received += 1
        body = False
        try:
            if self.kind == WRENCH:
                forces, body = self.layout.wrench(msg, self.inertial_frame)
            elif self.kind == FORCES:
                forces = self.layout.forces(msg)
            else:
                forces = self.layout.torques(msg)
        except CommandError as exc:
            self.reject(str(exc))
            return None
        self.latest = Command(forces, time.monotonic_ns(), sim_ns, self.kind, body)
        return self.latest

    def held(self, sim_ns: int, wall_age: bool) -> np.ndarray:
        """The command (n, 2) [N], torques (n,) or (n + 1,) [N m] or wrench (3,) to hold over
        the next period: the latest valid command, or zero once it is older than
        ``command_timeout`` (wall age if ``wall_age``, else simulated age at ``sim_ns``)."""
        cmd = self.latest
        active = cmd is not None
        if active and self.timeout_ns > 0:
            age = (time.monotonic_ns() - cmd.wall_ns) if wall_age else (sim_ns - cmd.sim_ns)
            active = age <= self.timeout_ns
        self.active = active
        return cmd.forces if active else self.zero
