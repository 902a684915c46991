"""Start-up of a rod_sim ROS 2 process (issue 27, item 1): what it is doing, said on stderr
when it takes longer than :data:`NOTICE_AFTER_S`, and a stop that does not wait for it.

:func:`phase` names the current step (``run_node`` and :mod:`rod_sim.ros.budget` set it);
:class:`Progress` is a thread that prints ``PROG: starting: PHASE (n s so far)`` after 2 s and
then every :data:`NOTICE_EVERY_S` until the start-up ends. The work it watches is done in
bounded calls (compiled integrator calls return after bounded work), so the thread, and the
signal handler that interrupts the start-up (:class:`rod_sim.ros.process.StopRequest`), get
to run between them."""
from __future__ import annotations

from rod_sim.app.startup import NOTICE_AFTER_S, NOTICE_EVERY_S, Progress, phase  # noqa: F401

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
