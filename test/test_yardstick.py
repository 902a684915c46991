"""The machine's yardstick (rod_sim.bench.yardstick): three workloads timed in turns, each
reported as its minimum and median over the rounds, before and after every rate_bench run. No timing
is asserted (the machine's load decides the values): their structure and ordering are."""
from __future__ import annotations

import json
import math
import subprocess
import sys

from procs import REPO

WORKLOADS = {"python", "numpy_small", "rhs_1024"}


def run_yardstick(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.bench.yardstick", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=300)


def test_each_workload_has_a_positive_minimum_no_larger_than_its_median():
    done = run_yardstick("--rounds", "3", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert set(result) == WORKLOADS
    for name, value in result.items():
        assert set(value) == {"min_ms", "median_ms"}, name
        assert math.isfinite(value["median_ms"]) and 0.0 < value["min_ms"] <= value["median_ms"]


def test_the_line_names_every_workload_and_bad_rounds_are_one_line_and_status_2():
    done = run_yardstick("--rounds", "1")
    assert done.returncode == 0, done.stderr
    line, = done.stdout.splitlines()
    assert line.startswith("yardstick (min / median of the rounds): ")
    assert all(f"{name} " in line for name in WORKLOADS), line
    bad = run_yardstick("--rounds", "0")
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr.splitlines()[-1] == ("python -m rod_sim.bench.yardstick: error: --rounds: "
                                          "at least 1 (got 0)")


def test_rate_bench_reports_the_yardstick_beside_its_figures_unless_told_not_to(capsys):
    from rod_sim.ros.rate_bench import main

    assert main(["--period-cost", "9", "--rate", "500", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result["yardstick"]) == {"before", "after"} and result["period_ms"] > 0.0
    assert all(set(result["yardstick"][when]) == WORKLOADS for when in ("before", "after"))
    assert main(["--period-cost", "9", "--rate", "500", "--no-yardstick"]) == 0
    out = capsys.readouterr().out
    assert "period" in out and "yardstick" not in out
    assert main(["--period-cost", "9", "--rate", "500"]) == 0
    first, before, after = capsys.readouterr().out.splitlines()
    assert first.startswith("n = 8 reduced")
    assert before.startswith("before the run: yardstick (min / median")
    assert after.startswith("after the run: yardstick (min / median")
