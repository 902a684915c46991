"""The console script's first signal handler (rod_sim.tools.launch), called directly in a
child process so that the moment does not matter: its one line names the subcommand only
when the first word is one (as rod_sim.tools.cli does), and its status is 128 + signal."""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CALL = ("import signal, sys; sys.argv = ['rod-sim'] + sys.argv[1:]; "
        "from rod_sim.tools import launch; launch._stop_at_once(signal.{sig}, None)")


@pytest.mark.parametrize("argv, sig, line, status", [
    (["simulate", "x.yaml"], "SIGINT", "rod-sim simulate: interrupted", 130),
    (["node", "--ros-args"], "SIGTERM", "rod-sim node: interrupted (SIGTERM)", 143),
    (["simulat", "x.yaml"], "SIGINT", "rod-sim: interrupted", 130),        # a typo
    (["--help"], "SIGINT", "rod-sim: interrupted", 130),
    ([], "SIGTERM", "rod-sim: interrupted (SIGTERM)", 143),
])
def test_the_early_handler_names_only_a_real_subcommand(argv, sig, line, status):
    done = subprocess.run([sys.executable, "-c", CALL.format(sig=sig), *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == status
    assert done.stderr == line + "\n"
    assert getattr(signal, sig) + 128 == status
