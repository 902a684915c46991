"""The statistics of rod_sim.ros.rate_bench on arrivals whose answers are known by hand."""
import numpy as np
import pytest

from rod_sim.ros.rate_bench import dropped_in_window, ros_arg, summarize


def test_summary_of_a_steady_stream_with_one_late_and_one_missing_message():
    # 1 kHz stamps, period 2 (stamp 2 ms) never arrives; arrivals 1 ms apart except one 5 ms gap
    stamps = np.array([0, 1, 3, 4, 5, 6, 7, 8, 9, 10], dtype=np.int64) * 1_000_000
    wall = np.array([0, 1, 2, 3, 8, 9, 10, 11, 12, 13], dtype=np.int64) * 1_000_000
    s = summarize(wall, stamps, rate_hz=1000.0)
    assert s["messages"] == 10 and s["missing_periods"] == 1
    assert s["rate_hz"] == pytest.approx(9 / 0.013)
    assert s["rtf"] == pytest.approx(10 / 13)          # 10 ms simulated in 13 ms of arrivals
    assert s["interarrival_ms"]["median"] == pytest.approx(1.0)
    assert s["interarrival_ms"]["max"] == pytest.approx(5.0)
    assert 1.0 < s["interarrival_ms"]["p99"] <= 5.0


def test_periods_dropped_by_the_node_in_the_window_come_from_its_running_total():
    reports = [(0.5, 0), (1.5, 3), (2.5, 3), (3.5, 10), (4.5, 12)]    # (receipt [s], total)
    assert dropped_in_window(reports, start=2.0) == 12 - 3
    assert dropped_in_window(reports, start=0.0) == 12         # no report before: from 0
    assert dropped_in_window(reports[:2], start=2.0) is None   # none inside the window


def test_parameter_values_are_written_as_ros_yaml():
    assert [ros_arg(v) for v in (True, False, "", "a.yaml", 1000.0)] == [
        "true", "false", "''", "a.yaml", "1000.0"]


def test_period_cost_runs_the_node_parts_without_ros(capsys):
    """--period-cost K: CPU per period of the integration, the period and the period with its
    outputs (a log written) are reported (no timing is asserted: each is a positive number)."""
    import json

    from rod_sim.ros.rate_bench import main

    assert main(["--period-cost", "30", "--rate", "500", "--record", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["n"] == 8 and result["periods"] == 10 and result["record"]
    for key in ("integration_ms", "period_ms", "period_with_outputs_ms"):
        assert result[key] > 0.0, result


def test_node_cpu_counts_its_live_children(tmp_path):
    """A parent that only waits, with a child that burns ~0.4 s of CPU and stays alive: the
    parent's CPU as rate_bench counts it includes the child's (the node's log writer)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from rod_sim.ros.rate_bench import process_cpu_s

    burn = ("import time\nt = time.process_time()\nwhile time.process_time() - t < 0.4: pass\n"
            "open(r'%s', 'w').close()\ntime.sleep(30)\n" % (tmp_path / "burnt"))
    parent = subprocess.Popen([sys.executable, "-c",
                               "import subprocess, sys; subprocess.run([sys.executable, '-c', "
                               f"{burn!r}])"], start_new_session=True)
    try:
        deadline = time.monotonic() + 30
        while not (tmp_path / "burnt").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert (tmp_path / "burnt").exists()
        assert 0.35 <= process_cpu_s(parent.pid) < 5.0
    finally:
        os.killpg(parent.pid, signal.SIGKILL)       # the child too
        parent.wait()


# ----- the bench end to end: a node process, this process its subscriber or controller -----

def _bench_json(capsys, argv) -> dict:
    import json
    import os
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    from ros_domains import next_domain

    from rod_sim.ros.rate_bench import main

    pytest.importorskip("rclpy")

    status = main(argv + ["--json", "--no-yardstick", "--domain", str(next_domain())])
    result = json.loads(capsys.readouterr().out)
    result["status"] = status
    return result


@pytest.mark.ros
@pytest.mark.timeout(240)
@pytest.mark.parametrize("executor", ["bare", "rclpy"])
def test_lockstep_bench_runs_its_round_trips_and_keeps_the_log(executor, capsys, tmp_path):
    """--lockstep 40 --record --keep-log: 40 round trips complete whether the controller takes
    its messages with a bare wait set or rclpy's executor (the LeanExecutor has its own tests:
    test_lean_executor.py); the kept log (read by the mcap package) holds the states of periods
    0..40 of the 1 ms period and the 40 commands; every CPU figure is a positive number (none
    asserted against a time)."""
    from mcap.reader import make_reader

    log = tmp_path / "lockstep.mcap"
    argv = ["--lockstep", "40", "--rate", "1000", "--record", "--keep-log", str(log)]
    result = _bench_json(capsys, argv + ["--bench-executor", executor])
    assert result["status"] == 0 and result["complete"] and result["round_trips"] == 40
    assert result["controller_executor"] == executor
    for key in ("node_cpu_ms_per_round_trip", "node_main_thread_ms_per_round_trip",
                "controller_cpu_ms_per_round_trip", "round_trips_per_s"):
        assert result[key] > 0.0, (key, result)
    stamps, commands = set(), 0
    with open(log, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic == "/rod_states":
                stamps.add(message.log_time)
            elif channel.topic == "/nodal_forces":
                commands += 1
    assert stamps == {k * 1_000_000 for k in range(41)}
    assert commands == 40


@pytest.mark.ros
@pytest.mark.timeout(240)
def test_real_time_bench_reports_the_node_and_its_own_cpu(capsys):
    """A short real-time run (200 Hz, 1 s window): states arrive, and the node's CPU, its main
    thread's and this subscriber's own (a bare wait set by default) are reported."""
    result = _bench_json(capsys, ["--rate", "200", "--duration", "1", "--warmup", "0.5"])
    assert result["status"] == 0 and result["messages"] > 0
    assert result["bench_executor"] == "bare"
    for key in ("node_cpu_fraction", "node_main_thread_cpu_fraction", "bench_cpu_fraction"):
        assert result[key] > 0.0, (key, result)
