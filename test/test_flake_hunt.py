"""test/flake_hunt.py (``make flake``): a repeat whose pytest crashes (a segfault, as one in
rclpy's node teardown was seen) is counted as a failure where it crashed, and the hunt goes on
to its other repeats instead of stopping."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def test_a_crashing_repeat_is_a_failure_and_the_hunt_goes_on(tmp_path):
    crash = tmp_path / "test_boom.py"
    crash.write_text("import os, signal\n\n\ndef test_boom():\n"
                     "    os.kill(os.getpid(), signal.SIGSEGV)\n")
    done = subprocess.run([sys.executable, str(HERE / "flake_hunt.py"), "--repeats", "2",
                           "--burners", "0", "--marker", "not nothing", "--out",
                           str(tmp_path / "out"), "--", str(crash), "-p", "no:randomly"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr
    runs = [line for line in done.stdout.splitlines() if line.startswith("run ")]
    assert len(runs) == 2 and all("1 failed" in line for line in runs), done.stdout
    assert "CRASH in test_boom.py:5 in test_boom" in done.stdout
    assert "pytest killed by signal 11" in done.stdout
