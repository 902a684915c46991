"""Start-up of a rod_sim ROS 2 process (issue 27, item 1): what it is doing, said on stderr
when it takes longer than :data:`NOTICE_AFTER_S`, and a stop that does not wait for it.

:func:`phase` names the current step (``run_node`` and :mod:`rod_sim.ros.budget` set it);
:class:`Progress` is a thread that prints ``PROG: starting: PHASE (n s so far)`` after 2 s and
then every :data:`NOTICE_EVERY_S` until the start-up ends. The work it watches is done in
bounded calls (compiled integrator calls return after bounded work), so the thread, and the
signal handler that interrupts the start-up (:class:`rod_sim.ros.process.StopRequest`), get
to run between them."""
from __future__ import annotations

from rod_sim.app import progress

NOTICE_AFTER_S = 2.0
"""[s] of start-up after which the first progress line is printed."""
NOTICE_EVERY_S = 5.0
"""[s] between later progress lines."""

_phase = "starting"


def phase(text: str) -> None:
    """Name what the start-up is doing now (e.g. 'calibrating the work budget')."""
    global _phase
    _phase = text


_on_started = None


def on_started(callback) -> None:
    """``callback()`` (or None) is what :func:`started` calls: the process's stop handler
    (:class:`rod_sim.ros.process.StopRequest`) ends its start-up state there."""
    global _on_started
    _on_started = callback


def started() -> None:
    """The node is built and about to say so (its start line): from here a signal stops a
    running node (exit 0), not a start-up (130 / 143). Called before the line is printed,
    so that whoever has read the line and then signals gets the running node's stop."""
    if _on_started is not None:
        _on_started()


class Progress(progress.Progress):
    """Context manager around a start-up (:class:`rod_sim.app.progress.Progress`): a daemon
    thread prints what it is doing after :data:`NOTICE_AFTER_S` and every
    :data:`NOTICE_EVERY_S` after that, until the block ends. ``prog`` names the process;
    ``what`` (e.g. 'scene big, n = 100000') is printed with the first line."""

    def __init__(self, prog: str, what=lambda: "", stream=None):
        self.prog = prog
        self.what = what
        self.lines = 0
        super().__init__(self._line, NOTICE_AFTER_S, NOTICE_EVERY_S, "rod-sim-startup", stream)

    def __enter__(self) -> "Progress":
        phase("creating the node")
        return super().__enter__()

    def _line(self, elapsed: float) -> str:
        extra = ""
        if not self.lines:
            try:
                extra = self.what() or ""
            except Exception:  # noqa: BLE001 -- a description is never worth a failure
                extra = ""
        self.lines += 1
        text = f"{self.prog}: starting: {_phase} ({elapsed:.0f} s so far"
        return text + (f"; {extra})" if extra else ")")
