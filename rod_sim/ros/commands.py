"""Intake of the rod_sim node's commands (``nodal_forces``: 2 n values, ``hinge_torques``: n
values; one :class:`CommandIntake` per topic): the serialized command is refused by its length
before it is decoded, then validated; refusals are counted with their last reason; the latest
valid command is held (zero-order hold) until ``command_timeout``.

ROS-light: it decodes a ``std_msgs/Float64MultiArray`` but creates no ROS entity and logs
nothing; the node subscribes, records, logs and steps."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64MultiArray

from rod_sim.core.units import NS_PER_S
from rod_sim.ros.conversions import CommandError, command_forces, command_torques

COMMAND_SLACK_BYTES = 4096
"""Bytes a serialized command may carry beyond its 2 n (torques: n) doubles (header, layout,
labels)."""

FORCES, TORQUES = "nodal_forces", "hinge_torques"
"""The command topics (relative names) and the kinds of :class:`CommandIntake`."""
_KINDS = {FORCES: (2, command_forces), TORQUES: (1, command_torques)}


@dataclass(frozen=True)
class Command:
    """A valid command: ``forces`` = nodal forces (n, 2) [N] (``kind`` nodal_forces) or hinge
    torques (n,) [N m] (``kind`` hinge_torques), received at wall ``wall_ns`` (monotonic) and
    at simulated time ``sim_ns``."""

    forces: np.ndarray
    wall_ns: int
    sim_ns: int
    kind: str = FORCES


class CommandIntake:
    """Commands of a chain of ``n`` nodes on one topic (``kind``: :data:`FORCES`, 2 n values
    -> (n, 2) [N], or :data:`TORQUES`, n values -> (n,) [N m]): counters, the latest valid
    command and its hold.

    ``received`` and ``rejected`` count commands; ``last_rejection`` is the last reason;
    ``latest`` is the latest valid :class:`Command`; ``active`` says whether the last
    :meth:`held` force was a command (False once it timed out)."""

    def __init__(self, n: int, timeout_s: float, kind: str = FORCES):
        self.n = n
        self.kind = kind
        self.width, self._parse = _KINDS[kind]
        self.values = self.width * n
        """Values a valid command holds."""
        self.max_bytes = 16 * self.values + COMMAND_SLACK_BYTES
        self.received = 0
        self.rejected = 0
        self.last_rejection = ""
        self.latest: Command | None = None
        self.active = False
        self.timeout_ns = 0
        self.set_timeout(timeout_s)
        self._zero = np.zeros((n, 2)) if self.width == 2 else np.zeros(n)

    def set_timeout(self, seconds: float) -> None:
        """``command_timeout`` [s]; 0 = hold forever."""
        self.timeout_ns = int(round(seconds * NS_PER_S))

    def clear(self) -> None:
        """Forget the held command (a reset); the counters go on."""
        self.latest = None
        self.active = False

    def decode(self, data: bytes) -> Float64MultiArray | None:
        """The message in the serialized ``data``, or None (counted as received and rejected)
        when it is too long for a command of 2 n (torques: n) values (checked before any decoding: an 80 MB
        message must not stall the node) or cannot be decoded."""
        if len(data) > self.max_bytes:
            self.received += 1
            self.reject(f"{len(data)} bytes, more than the {self.max_bytes} a command "
                        f"of {self.values} values may take (not recorded)")
            return None
        try:
            return deserialize_message(data, Float64MultiArray)
        except Exception as exc:  # noqa: BLE001 -- any undecodable payload is one rejection
            self.received += 1
            self.reject(f"cannot be decoded ({type(exc).__name__}; not recorded)")
            return None

    def reject(self, reason: str) -> None:
        """Count a refused command and keep its ``reason``."""
        self.rejected += 1
        self.last_rejection = reason

    def accept(self, msg: Float64MultiArray, sim_ns: int) -> Command | None:
        """Count and validate a decoded command received at simulated time ``sim_ns``: the
        new latest command, or None (rejected, the last valid one is kept)."""
        self.received += 1
        try:
            forces = self._parse(msg, self.n)
        except CommandError as exc:
            self.reject(str(exc))
            return None
        self.latest = Command(forces, time.monotonic_ns(), sim_ns, self.kind)
        return self.latest

    def held(self, sim_ns: int, wall_age: bool) -> np.ndarray:
        """The command (n, 2) [N] or torques (n,) [N m] to hold over the next period: the latest valid command,
        or zero once it is older than ``command_timeout`` (wall age if ``wall_age``, else
        simulated age at ``sim_ns``)."""
        cmd = self.latest
        active = cmd is not None
        if active and self.timeout_ns > 0:
            age = (time.monotonic_ns() - cmd.wall_ns) if wall_age else (sim_ns - cmd.sim_ns)
            active = age <= self.timeout_ns
        self.active = active
        return cmd.forces if active else self._zero
