"""What a test may assert on in a command's output: the lines the command prints whatever the
machine's speed. ``rod-sim simulate`` prints a notice (``COMPILE_NOTICE``) when loading or
compiling its kernels takes more than 2 s of wall time, which a loaded machine reaches with a
warm cache too; a test that counts the lines of stderr counts them without it."""
from __future__ import annotations

from rod_sim.app.common import COMPILE_NOTICE


def untimed_lines(text: str) -> list[str]:
    """The lines of ``text`` (stderr of a command) without the timed compile notice."""
    return [line for line in text.splitlines() if COMPILE_NOTICE not in line]
