"""python -m rod_sim.ros.executor_cost: runs in a ROS domain of its own, prints one line per node,
executor and round, refuses bad settings (the figures are the machine's and are not asserted)."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from procs import REPO, ros_env  # noqa: E402
from ros_domains import next_domain  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


def test_prints_the_cost_of_a_wake_up_for_both_nodes_and_executors_in_turns():
    domain = next_domain()
    done = subprocess.run([sys.executable, "-m", "rod_sim.ros.executor_cost", "--seconds", "0.2",
                           "--rounds", "2", "--domain", str(domain)], cwd=REPO,
                          env=ros_env(domain), capture_output=True, text=True, timeout=100)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert [line.split(":")[0] for line in lines] == [
        "bare, rclpy's executor", "bare, lean executor", "rod_sim node, rclpy's executor",
        "rod_sim node, lean executor"] * 2
    for line in lines:
        m = re.fullmatch(r"[^:]+: (\d+) us of main-thread CPU per wake-up \((\d+) wake-ups of a "
                         r"1 ms timer\)", line)
        assert m and int(m.group(1)) > 0 and int(m.group(2)) > 0, line


@pytest.mark.parametrize("bad", [["--seconds", "0"], ["--rounds", "0"], ["--domain", "233"]])
def test_bad_settings_exit_2(bad, capsys):
    from rod_sim.ros import executor_cost

    with pytest.raises(SystemExit) as e:
        executor_cost.main(bad)
    assert e.value.code == 2
    assert "must be" in capsys.readouterr().err
