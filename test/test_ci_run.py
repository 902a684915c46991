""".ci/run, with a stand-in ``make`` on PATH (each target's exit status from the environment):
it warms first, runs both suites, shows both logs and fails when any step fails."""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FAKE_MAKE = """#!/usr/bin/env bash
echo "make $1" >> "$CALLS"
echo "output of $1"
var="STATUS_${1//-/_}"
exit "${!var:-0}"
"""


def run_ci(tmp_path: Path, **statuses: int) -> tuple[subprocess.CompletedProcess, list[str]]:
    (tmp_path / ".ci").mkdir()
    shutil.copy(REPO / ".ci" / "run", tmp_path / ".ci" / "run")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "make").write_text(FAKE_MAKE)
    (bin_dir / "make").chmod(0o755)
    calls = tmp_path / "calls"
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", CALLS=str(calls),
               **{f"STATUS_{k}": str(v) for k, v in statuses.items()})
    done = subprocess.run(["bash", str(tmp_path / ".ci" / "run")], env=env, capture_output=True,
                          text=True, timeout=60)
    return done, calls.read_text().split("\n")[:-1] if calls.exists() else []


def test_both_suites_run_after_the_warm_up_and_their_logs_are_shown(tmp_path):
    done, calls = run_ci(tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert calls[0] == "make warm" and sorted(calls[1:]) == ["make test", "make test-slow"]
    assert "output of test\n" in done.stdout and "output of test-slow\n" in done.stdout


@pytest.mark.parametrize("failing", ["test", "test_slow"])
def test_a_failing_or_empty_suite_fails_the_run(tmp_path, failing):
    done, calls = run_ci(tmp_path, **{failing: 5})
    assert done.returncode != 0 and len(calls) == 3
    assert "output of test\n" in done.stdout and "output of test-slow\n" in done.stdout


def test_a_failed_warm_up_runs_no_suite(tmp_path):
    done, calls = run_ci(tmp_path, warm=2)
    assert done.returncode == 2 and calls == ["make warm"]
