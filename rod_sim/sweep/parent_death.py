"""A helper process that dies with its parent, even when the parent is SIGKILLed (issue 27,
item 8: SIGKILL of ``rod-sim sweep`` left its forkserver and workers running for minutes; a
worker busy in a compiled run reads no pipe, so only the kernel can stop it in time)."""
from __future__ import annotations

import os
import signal
import sys

PR_SET_PDEATHSIG = 1
"""prctl(2) option: the signal a process gets when its parent dies (Linux)."""


def die_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when its parent dies (Linux ``prctl``; a no-op
    returning False elsewhere); if the parent is already gone (the process was adopted by
    init before the request), exit now. Returns whether the request was made."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() == 1:
        os._exit(1)
    return True
