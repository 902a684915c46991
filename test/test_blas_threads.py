"""rod_sim's own processes run one BLAS thread (rod_sim/app/blas.py): the ``rod-sim`` entry
point and the node module set OPENBLAS_NUM_THREADS=1 before numpy loads, so numpy's and
scipy's OpenBLAS start no worker thread; a value the user set is kept; ``import rod_sim``
alone changes nothing."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from procs import REPO

PROBE = ("import os, {module}, numpy, scipy.linalg, scipy.sparse.linalg; "
         "numpy.dot(numpy.ones(100000), numpy.ones(100000)); "
         "print(os.environ.get('OPENBLAS_NUM_THREADS'), len(os.listdir('/proc/self/task')))")


def _probe(module: str, preset: str | None = None) -> tuple[str, int]:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    out = subprocess.run([sys.executable, "-c", PROBE.format(module=module)], cwd=REPO,
                         env=env, capture_output=True, text=True, timeout=120, check=True)
    value, threads = out.stdout.split()
    return value, int(threads)


@pytest.mark.parametrize("module", ("rod_sim.tools.launch", "rod_sim.ros.node"))
def test_the_entry_points_load_blas_with_one_thread(module):
    """The variable is set, and the process has the threads it has with the variable set by
    hand (rclpy starts two of its own): no BLAS worker (the command's process: none at all)."""
    value, threads = _probe(module)
    assert value == "1" and threads == _probe(module, preset="1")[1]
    if module == "rod_sim.tools.launch":
        assert threads == 1


def test_a_count_the_user_set_is_kept():
    assert _probe("rod_sim.tools.launch", preset="2")[0] == "2"


def test_importing_rod_sim_changes_nothing():
    assert _probe("rod_sim")[0] == "None"
