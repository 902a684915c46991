"""A command's start-up, said on stderr when it takes longer than :data:`NOTICE_AFTER_S`:
:func:`phase` names the current step, :class:`Progress` is a thread that prints ``PROG:
starting: PHASE (n s so far)`` after 2 s and then every :data:`NOTICE_EVERY_S` until the
start-up ends (a ROS process's, :mod:`rod_sim.ros.startup`; ``rod-sim simulate``'s)."""
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


class Progress(progress.Progress):
    """Context manager around a start-up (:class:`rod_sim.app.progress.Progress`): a daemon
    thread prints what it is doing after :data:`NOTICE_AFTER_S` and every
    :data:`NOTICE_EVERY_S` after that, until the block ends. ``prog`` names the process;
    ``what`` (e.g. 'scene big, n = 100000') is printed with the first line."""

    def __init__(self, prog: str, what=lambda: "", stream=None,
                 first_phase: str = "creating the node"):
        self.prog = prog
        self.what = what
        self.first_phase = first_phase
        self.lines = 0
        super().__init__(self._line, NOTICE_AFTER_S, NOTICE_EVERY_S, "rod-sim-startup", stream)

    def __enter__(self) -> "Progress":
        phase(self.first_phase)
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
