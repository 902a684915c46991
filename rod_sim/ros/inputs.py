"""The rod_sim node's inputs, without ROS: the command intakes and what a period holds.

``nodal_forces`` (2n values [N]), ``hinge_torques`` (n values [N m], n + 1 with a reaction
wheel) and ``base_wrench`` (geometry_msgs/WrenchStamped) each have a
:class:`~rod_sim.ros.commands.CommandIntake` (length check, decoding, validation per chain,
counts, zero-order hold, timeout; :mod:`rod_sim.ros.command_layout`). A period holds (n, 3) =
[X, Y, T] for the chains, and with a free base (n + 2, 3): row n the base wrench [Fx, Fy, M]
in Oxy (a base-frame wrench turned by the base's angle at the period's start), row n + 1 the
wheel motor torque in column 2 (the kernels' load-table rows):

- paced (real time, as fast as possible, ``~/step``): per topic the latest valid command, or
  zero once it is older than ``command_timeout`` (:meth:`Inputs.held`);
- lockstep: one period per valid command, in order of arrival (:meth:`Inputs.next_queued`); a
  command of one topic keeps the other topics' last commands.
"""
from __future__ import annotations

from collections import deque
from typing import Callable

import numpy as np

from rod_sim.core.units import NS_PER_S
from rod_sim.ros.command_layout import CommandLayout, to_inertial
from rod_sim.ros.commands import FORCES, TORQUES, WRENCH, Command, CommandIntake

_WHAT = {FORCES: "command force", TORQUES: "hinge torques", WRENCH: "base wrench"}
SYNC_BATCH = 16
"""Lockstep periods stepped per callback (:meth:`Inputs.drain`) before yielding to others."""


class Inputs:
    """The commands of a scene of ``n`` rods; ``timeout_s``: ``command_timeout`` [s];
    ``layout``: what the commands hold (default: one chain of n rods on the ground);
    ``base_angle()``: the base's angle psi [rad] now (turns a base-frame wrench into Oxy);
    ``inertial_frame``: the ``frame_id`` of a wrench given in Oxy."""

    def __init__(self, n: int, timeout_s: float, layout: CommandLayout | None = None,
                 base_angle: Callable[[], float] | None = None, inertial_frame: str = "world"):
        self.n = n
        self.layout = CommandLayout.single(n) if layout is None else layout
        self.forces = CommandIntake(n, timeout_s, FORCES, self.layout)
        self.torques = CommandIntake(n, timeout_s, TORQUES, self.layout)
        self.wrench = CommandIntake(n, timeout_s, WRENCH, self.layout, inertial_frame)
        self.intakes = {FORCES: self.forces, TORQUES: self.torques, WRENCH: self.wrench}
        self.queue: deque[Command] = deque()
        """Lockstep: valid commands waiting for their period."""
        self.rejection = ""
        """The latest rejection of any topic, prefixed with the topic."""
        self._base_angle = base_angle if base_angle is not None else (lambda: 0.0)
        self._queued: dict[str, Command] = {}
        """Lockstep: the last command of each topic taken from the queue."""

    def set_inertial_frame(self, frame_id: str) -> None:
        """The ``frame_id`` parameter changed: a wrench in Oxy now names this frame."""
        self.wrench.inertial_frame = frame_id

    def set_timeout(self, seconds: float) -> None:
        for intake in self.intakes.values():
            intake.set_timeout(seconds)

    def clear(self) -> None:
        """A reset: no command held or queued (the counters go on)."""
        for intake in self.intakes.values():
            intake.clear()
        self.queue.clear()
        self._queued = {}

    def named_topics(self) -> tuple[str, ...]:
        """The command topics the node's start-up line names: base_wrench only with a free
        base (it is subscribed in any case, so that a wrench sent to another base is
        counted)."""
        return (FORCES, TORQUES) + ((WRENCH,) if self.layout.free_base else ())

    def any_command(self) -> bool:
        """Whether a valid command (any topic) is held since the start or the last reset."""
        return any(intake.latest is not None for intake in self.intakes.values())

    def note_rejection(self, intake: CommandIntake) -> str:
        """Remember ``intake``'s last rejection; returns the warning line."""
        self.rejection = f"{intake.kind}: {intake.last_rejection}"
        return (f"rejected a {intake.kind} command: {intake.last_rejection} "
                f"({intake.rejected} rejected so far); keeping the last valid command")

    def receive(self, data: bytes, intake: CommandIntake, sim_ns: int, record
                ) -> tuple[Command | None, str]:
        """A serialized command of ``intake``'s topic received at simulated time ``sim_ns``:
        refused by its length before decoding (an 80 MB message must not stall the node),
        decoded, passed to ``record(msg, data)`` (rejected ones included; undecodable ones
        not), validated. Returns (the valid command or None, the warning line of a
        rejection)."""
        msg = intake.decode(data)
        if msg is not None:
            record(msg, data)
        command = None if msg is None else intake.accept(msg, sim_ns)
        return command, ("" if command is not None else self.note_rejection(intake))

    def held(self, sim_ns: int, wall_age: bool) -> tuple[np.ndarray, list[tuple[str, str]]]:
        """The inputs to hold over the next period ((n, 3) [X, Y, T], (n + 2, 3) with a free
        base: module docstring; command ages: wall time if ``wall_age``, else simulated time
        at ``sim_ns``), and (topic, line) for each topic whose command just timed out."""
        values, notes = {}, []
        for kind, intake in self.intakes.items():
            was_active = intake.active
            values[kind] = intake.held(sim_ns, wall_age)
            if was_active and not intake.active:
                notes.append((kind, f"no valid {kind} command for "
                              f"{intake.timeout_ns / NS_PER_S:g} s: {_WHAT[kind]} set to zero"))
        body = self.wrench.active and self.wrench.latest.body
        return self._compose(values[FORCES], values[TORQUES], values[WRENCH], body), notes

    def _compose(self, forces, torques, wrench, body: bool) -> np.ndarray:
        """The held inputs (rows: :attr:`CommandLayout.rows`) of the chains' forces (n, 2),
        the torques (n,) or (n + 1,) (the wheel last) and the wrench (3,) (in the base frame
        if ``body``: turned by the base's angle now)."""
        n = self.n
        held = np.zeros((self.layout.rows, 3))
        held[:n, :2] = forces
        held[:n, 2] = torques[:n]
        if self.layout.free_base:
            held[n] = to_inertial(wrench, body, self._base_angle() if body else 0.0)
            if self.layout.wheel:
                held[n + 1, 2] = torques[n]
        return held

    def next_queued(self) -> np.ndarray:
        """Lockstep: the inputs of the oldest queued command's period (as :meth:`held`)."""
        command = self.queue.popleft()
        self.intakes[command.kind].active = True
        self._queued[command.kind] = command
        latest = {kind: (self._queued[kind].forces if kind in self._queued else intake.zero)
                  for kind, intake in self.intakes.items()}
        wrench = self._queued.get(WRENCH)
        return self._compose(latest[FORCES], latest[TORQUES], latest[WRENCH],
                             wrench is not None and wrench.body)

    def drain(self, step, running, deadline_ns: int, batch: int = SYNC_BATCH) -> bool:
        """Lockstep: ``step(held)`` the periods of up to ``batch`` queued commands while
        ``running()`` and before monotonic ``deadline_ns``; returns whether commands are left
        to step later (so that other callbacks are served in between)."""
        import time

        for _ in range(batch):
            if not self.queue or not running() or time.monotonic_ns() > deadline_ns:
                break
            step(self.next_queued())
        return bool(self.queue) and running()

    def total(self, what: str) -> int:
        """Commands ``what`` (``received`` or ``rejected``) so far, on every command topic."""
        return sum(getattr(intake, what) for intake in self.intakes.values())

    def counts(self) -> dict[str, str]:
        """Diagnostics values: received, rejected and active per topic (``base_wrench_*``
        too: a wrench sent to a scene without a free base is rejected and counted)."""
        out = {f"{kind}_{what}": str(getattr(intake, what))
               for kind, intake in self.intakes.items() for what in ("received", "rejected")}
        out.update({f"{kind}_active": "true" if intake.active else "false"
                    for kind, intake in self.intakes.items()})
        return out
