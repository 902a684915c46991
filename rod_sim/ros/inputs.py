"""The rod_sim node's inputs, without ROS: both command intakes and what a period holds.

``nodal_forces`` (2n values [N]) and ``hinge_torques`` (n values [N m]) each have a
:class:`~rod_sim.ros.commands.CommandIntake` (length check, decoding, validation, counts,
zero-order hold, timeout). A period holds (n, 3) = [X, Y, T]:

- paced (real time, as fast as possible, ``~/step``): per topic the latest valid command, or
  zero once it is older than ``command_timeout`` (:meth:`Inputs.held`);
- lockstep: one period per valid command, in order of arrival (:meth:`Inputs.next_queued`); a
  command of one topic keeps the other topic's last command.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from rod_sim.core.units import NS_PER_S
from rod_sim.ros.commands import FORCES, TORQUES, Command, CommandIntake


class Inputs:
    """The commands of a chain of ``n`` rods; ``timeout_s``: ``command_timeout`` [s]."""

    def __init__(self, n: int, timeout_s: float):
        self.n = n
        self.forces = CommandIntake(n, timeout_s, FORCES)
        self.torques = CommandIntake(n, timeout_s, TORQUES)
        self.intakes = {FORCES: self.forces, TORQUES: self.torques}
        self.queue: deque[Command] = deque()
        """Lockstep: valid commands waiting for their period."""
        self.rejection = ""
        """The latest rejection of either topic, prefixed with the topic."""
        self._queued_held = np.zeros((n, 3))

    def set_timeout(self, seconds: float) -> None:
        for intake in self.intakes.values():
            intake.set_timeout(seconds)

    def clear(self) -> None:
        """A reset: no command held or queued (the counters go on)."""
        for intake in self.intakes.values():
            intake.clear()
        self.queue.clear()
        self._queued_held = np.zeros((self.n, 3))

    def any_command(self) -> bool:
        """Whether a valid command (either topic) is held since the start or the last reset."""
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
        decoded, passed to ``record(msg)`` (rejected ones included; undecodable ones not),
        validated. Returns (the valid command or None, the warning line of a rejection)."""
        msg = intake.decode(data)
        if msg is not None:
            record(msg)
        command = None if msg is None else intake.accept(msg, sim_ns)
        return command, ("" if command is not None else self.note_rejection(intake))

    def held(self, sim_ns: int, wall_age: bool) -> tuple[np.ndarray, list[tuple[str, str]]]:
        """The inputs to hold over the next period (n, 3) [X, Y, T] (command ages: wall time
        if ``wall_age``, else simulated time at ``sim_ns``), and (topic, line) for each topic
        whose command just timed out."""
        held = np.empty((self.n, 3))
        notes = []
        for intake, columns in ((self.forces, slice(0, 2)), (self.torques, 2)):
            was_active = intake.active
            held[:, columns] = intake.held(sim_ns, wall_age)
            if was_active and not intake.active:
                what = "command force" if intake.kind == FORCES else "hinge torques"
                notes.append((intake.kind, f"no valid {intake.kind} command for "
                             f"{intake.timeout_ns / NS_PER_S:g} s: {what} set to zero"))
        return held, notes

    def next_queued(self) -> np.ndarray:
        """Lockstep: the inputs (n, 3) of the oldest queued command's period."""
        command = self.queue.popleft()
        self.intakes[command.kind].active = True
        held = self._queued_held.copy()
        if command.kind == TORQUES:
            held[:, 2] = command.forces
        else:
            held[:, :2] = command.forces
        self._queued_held = held
        return held

    def drain(self, step, running, deadline_ns: int, batch: int) -> bool:
        """Lockstep: ``step(held)`` the periods of up to ``batch`` queued commands while
        ``running()`` and before monotonic ``deadline_ns``; returns whether commands are left
        to step later (so that other callbacks are served in between)."""
        import time

        for _ in range(batch):
            if not self.queue or not running() or time.monotonic_ns() > deadline_ns:
                break
            step(self.next_queued())
        return bool(self.queue) and running()

    def counts(self) -> dict[str, str]:
        """Diagnostics values: received, rejected and active per topic."""
        out = {f"{kind}_{what}": str(getattr(intake, what))
               for kind, intake in self.intakes.items() for what in ("received", "rejected")}
        out.update({f"{kind}_active": "true" if intake.active else "false"
                    for kind, intake in self.intakes.items()})
        return out
