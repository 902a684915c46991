"""What a test may assert on in a command's output: the lines the command prints whatever the
machine's speed. ``rod-sim simulate`` prints a notice (``COMPILE_NOTICE``) when loading or
compiling its kernels takes more than 2 s of wall time, which a loaded machine reaches with a
warm cache too, and every command's start-up says what it is doing after 2 s (``PROG:
starting: ...``); a test that counts the lines of stderr counts them without these."""
from __future__ import annotations

from rod_sim.app.common import COMPILE_NOTICE

STARTUP_NOTICE = ": starting: "
"""In every start-up progress line (rod_sim.app.startup.Progress)."""


def untimed_lines(text: str) -> list[str]:
    """The lines of ``text`` (stderr of a command) without the timed notices."""
    return [line for line in text.splitlines()
            if COMPILE_NOTICE not in line and STARTUP_NOTICE not in line]
