"""rod_sim/tools/heartbeat.py, which the Makefile wraps around ``pip install -q`` (silent for a
minute on a fresh clone): a line every --every seconds while the command runs, the command's
exit status, and Ctrl-C passed on so that it stops within about a second."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "rod_sim" / "tools" / "heartbeat.py"


def run(*args, **kwargs):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=60, **kwargs)


def test_a_line_every_interval_and_the_commands_status():
    done = run("--every", "0.5", "installing", "--", sys.executable, "-c",
               "import time, sys; time.sleep(1.8); sys.exit(3)")
    assert done.returncode == 3, done.stderr
    lines = [line for line in done.stdout.splitlines() if line.startswith("make: installing (")]
    assert 2 <= len(lines) <= 4, done.stdout
    assert lines[0].endswith("s so far)")


def test_a_quick_command_prints_nothing_and_a_bad_call_is_refused():
    done = run("installing", "--", sys.executable, "-c", "pass")
    assert done.returncode == 0 and done.stdout == ""
    assert run("installing").returncode == 2


@pytest.mark.timing
def test_ctrl_c_is_passed_on_and_ends_it_within_a_second():
    proc = subprocess.Popen([sys.executable, str(SCRIPT), "--every", "0.5", "waiting", "--",
                             sys.executable, "-c", "import time; time.sleep(30)"],
                            stdout=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(1.2)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    code = proc.wait(timeout=10)
    assert code == 130
    assert time.monotonic() - sent < 5.0            # 1 s contract; margin for a loaded machine
