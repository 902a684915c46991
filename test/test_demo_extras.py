"""`make demo` installs only the `ros` and `plot` extras (the Makefile's DEMO_EXTRAS): the
demo's three steps (table1, the node with the controller in lockstep, compare with its plot)
must run without any package of the other extras. Each step runs in a child whose imports of
those packages fail as if they were not installed."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from ros_domains import next_domain

ROOT = Path(__file__).resolve().parents[1]

OTHER_EXTRAS = ("pytest", "_pytest", "pytest_timeout", "rosbags", "sympy", "yourdfpy",
                "websockets", "foxglove", "mujoco", "pinocchio", "Basilisk", "dask",
                "distributed", "pyarrow", "tqdm")
"""Top-level modules of the extras `make demo` does not install (setup.py: test, peer, sweep,
view)."""

BLOCKED_RUN = """
import runpy, sys
class Absent:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
sys.meta_path.insert(0, Absent())
module, sys.argv = sys.argv[1], sys.argv[1:]
runpy.run_module(module, run_name="__main__", alter_sys=True)
"""


def run_without_other_extras(module: str, *args: str, env=None) -> subprocess.CompletedProcess:
    code = f"BLOCKED = {set(OTHER_EXTRAS)!r}\n" + BLOCKED_RUN
    return subprocess.run([sys.executable, "-c", code, module, *args], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=600)


def test_the_blocker_blocks():
    """The oracle itself: a blocked package cannot be imported in the child."""
    done = run_without_other_extras("rosbags")
    assert done.returncode != 0 and "No module named 'rosbags'" in done.stderr


def test_the_demo_extras_are_the_makefiles():
    text = (ROOT / "Makefile").read_text()
    demo = re.search(r"^DEMO_EXTRAS = (.*)$", text, re.M).group(1).split(",")
    assert sorted(demo) == ["plot", "ros"]
    assert re.search(r"^demo: \$\(STAMP_DEMO\)", text, re.M)


@pytest.mark.ros
def test_the_demo_runs_with_the_demo_extras_only(tmp_path):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(next_domain()), MPLBACKEND="Agg")
    table = run_without_other_extras("rod_sim.tools.launch", "table1", env=env)
    assert table.returncode == 0, table.stderr[-2000:]
    assert table.stdout.startswith("Table 1 of the paper")
    log = tmp_path / "demo.mcap"
    node = run_without_other_extras("rod_sim.ros.demo", "--out", str(log), "--duration", "0.2",
                                    "--sync", env=env)
    assert node.returncode == 0, node.stderr[-2000:]
    plot = tmp_path / "demo_compare.png"
    compare = run_without_other_extras("rod_sim.tools.launch", "compare", str(log), "--plot",
                                       str(plot), env=env)
    assert compare.returncode == 0, compare.stdout[-2000:] + compare.stderr[-2000:]
    assert "PASS" in compare.stdout and plot.stat().st_size > 10_000
