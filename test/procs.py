"""Child processes of the tests that start ROS graphs: the environment of one ROS domain
(localhost discovery only) and a process started in the repository whose stderr goes to a
file (so that a test can wait for a line and show it on failure)."""
from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def ros_env(domain: int) -> dict[str, str]:
    """This process's environment with ROS domain ``domain`` on localhost, unbuffered."""
    return dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")


class Child:
    """``args`` run in the repository in ROS domain ``domain``: stderr into ``err_path``,
    stdout into ``out_path`` (None: discarded)."""

    def __init__(self, args: list[str], domain: int, err_path: Path,
                 out_path: Path | None = None):
        self.err_path = err_path
        with open(err_path, "w") as err, open(out_path or os.devnull, "w") as out:
            self.proc = subprocess.Popen(args, cwd=REPO, env=ros_env(domain), stdout=out,
                                         stderr=err)

    @property
    def stderr(self) -> str:
        return self.err_path.read_text()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)


def terminal_signals() -> None:
    """preexec_fn for a child that is sent Ctrl-C or SIGTERM: the dispositions and mask a
    terminal gives a command (SIG_DFL, unblocked), whatever the test process accumulated."""
    import signal as _signal

    for s in (_signal.SIGINT, _signal.SIGTERM):
        _signal.signal(s, _signal.SIG_DFL)
    _signal.pthread_sigmask(_signal.SIG_UNBLOCK, {_signal.SIGINT, _signal.SIGTERM})


def cpu_seconds(pid: int) -> float:
    """CPU time [s] process ``pid`` has used so far (all threads, waited-for children)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(f) for f in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def wait_with_usage(proc: subprocess.Popen, timeout: float):
    """Reap ``proc`` within ``timeout`` [s] of wall time: its resource usage (None: still
    running, then it is killed)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid == proc.pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return usage
        time.sleep(0.01)
    proc.kill()
    proc.wait()
    return None
