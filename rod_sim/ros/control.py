"""Whether the rod_sim node runs, and its services' logic, without ROS.

:class:`RunControl` holds the run state the services change: paused (``~/pause``, or
``start_paused`` until ``~/pause`` false or the first valid command), failed (an integration
error pauses until ``~/reset`` or ``~/pause`` false), stepping (a ``~/step`` call in progress)
and the count of resets. :meth:`RunControl.step` is ``~/step``'s body: ``count`` periods while
paused, in slices of at most ``slice_s`` of wall time; between slices it awaits ``yield_turn()``
so the executor serves the other callbacks (``~/pause``, ``~/reset``, diagnostics, commands),
which may interrupt it. Every call gets an answer: done, refused (busy, not paused) or
interrupted. :func:`answering` and :func:`executor_turn` adapt these to rclpy's service
callbacks.
"""
from __future__ import annotations

import time
from typing import Awaitable, Callable

STEP_SLICE_S = 0.1
"""[s] of wall time a ``~/step`` call steps before the executor serves others (the slice of
:meth:`RunControl.step`, at most ``max_period_cost``)."""
WAITING_LOG_PERIOD_S = 3.0
"""[s] wall period of the :meth:`RunControl.waiting_line` log line while waiting at t = 0."""
WAITING_REPUBLISH_PERIOD_S = 0.5
"""[s] wall period of the waiting state published again in lockstep before the first
command."""


class NextTurn:
    """Awaited in a service coroutine: hands control back to rclpy's executor once (the task
    stays pending and is resumed on the executor's next turn)."""

    def __await__(self):
        yield


def executor_turn(wake) -> Callable[[], Awaitable]:
    """``yield_turn`` of :meth:`RunControl.step` in an rclpy service coroutine: trigger the
    guard condition ``wake`` (so that the executor wakes up to resume the coroutine), then
    hand control back to the executor once (:class:`NextTurn`)."""
    async def yield_turn():
        wake.trigger()
        await NextTurn()
    return yield_turn


def answering(action: Callable[[object], str]):
    """An rclpy callback of a std_srvs ``Trigger`` or ``SetBool`` service that always
    succeeds: its response's message is ``action(request)``."""
    def callback(request, response):
        response.success, response.message = True, action(request)
        return response
    return callback


class RunControl:
    """The run state of a node in lockstep (``sync_mode``) or paced at ``rtf`` (0: as fast as
    possible), paused from the start if ``start_paused``."""

    def __init__(self, sync_mode: bool, start_paused: bool, rtf: float):
        self.sync_mode = sync_mode
        self.rtf = rtf
        self.paused = start_paused
        self.start_hold = start_paused
        """Paused by start_paused only: the first valid command resumes."""
        self.error: str | None = None
        """The cause of the last integration failure (None when running normally)."""
        self.stepping = False
        self.resets = 0

    def running(self) -> bool:
        return not self.paused and self.error is None

    def mode(self) -> str:
        if self.sync_mode:
            return "lockstep"
        return "as fast as possible" if self.rtf == 0.0 else f"real time x{self.rtf:g}"

    def state(self, any_command: bool) -> str:
        if self.error:
            return "error"
        if self.start_hold:
            return "paused at start (start_paused): waiting for ~/pause false or a command"
        if self.paused:
            return "paused"
        if self.sync_mode and not any_command:
            return "waiting for the first command"
        return "running"

    def first_command(self) -> bool:
        """A valid command arrived: ends the start hold. Returns whether it did."""
        if not self.start_hold:
            return False
        self.start_hold = self.paused = False
        return True

    def fail(self, reason: str) -> str:
        """An integration failure (``reason``) pauses the run; returns the ERROR line."""
        self.paused = True
        self.error = reason
        return (f"integration failed: {reason}; simulation paused (call ~/reset, or ~/pause "
                "false to retry)")

    def reset(self) -> None:
        self.resets += 1
        self.error = None

    def pause(self, pause: bool, t: float) -> str:
        """``~/pause``: the answer's message."""
        self.start_hold = False
        if pause:
            self.paused = True
            return f"paused at t = {t:.9g} s"
        note = f" (after the integration error: {self.error})" if self.error else ""
        self.paused = False
        self.error = None
        return f"resumed at t = {t:.9g} s{note}"

    async def step(self, count: int, step_once: Callable[[], bool], now_t: Callable[[], float],
                   yield_turn: Callable[[], Awaitable], slice_s: float) -> tuple[bool, str]:
        """``~/step``: ``count`` periods (``step_once()`` -> success), only while paused;
        returns (success, message)."""
        if self.stepping:
            return False, (f"busy: a ~/step call is in progress (t = {now_t():.9g} s); call "
                           "again when it has answered")
        if not self.paused:
            return False, "~/step works only while paused: call ~/pause with data: true first"
        self.stepping = True
        try:
            remaining, resets, ok = count, self.resets, True
            while remaining and ok:
                started = time.monotonic()
                while remaining and ok and time.monotonic() - started < slice_s:
                    ok = step_once()
                    remaining -= 1
                if remaining and ok:
                    await yield_turn()           # the executor runs what is ready, then us
                    if self.resets != resets or not self.paused:
                        why = "~/reset" if self.resets != resets else "~/pause false"
                        return False, (f"interrupted by {why} after {count - remaining} of "
                                       f"{count} periods (t = {now_t():.9g} s)")
            return ok, (f"stepped to t = {now_t():.9g} s" if ok else
                        f"step failed: {self.error}")
        finally:
            self.stepping = False

    def waiting_line(self, t: float, forces: str, torques: str, any_command: bool) -> str | None:
        """What a node waiting at its start waits for (None when it does not wait);
        ``forces``, ``torques``: the resolved command topics."""
        if self.start_hold:
            return (f"paused at t = {t:g} s (start_paused): waiting for ~/pause false or the "
                    f"first {forces} or {torques} command")
        if self.sync_mode and not any_command and self.running():
            return (f"lockstep: waiting for the first nodal_forces command on {forces} (or "
                    f"hinge_torques on {torques}; the t = {t:g} s state is published transient "
                    "local)")
        return None
