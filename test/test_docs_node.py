"""Every runnable code block of docs/node.md, run as a user would:
the shell commands (real-time node with the shipped params file, the same in a namespace in
lockstep, the one-process demo) and the lockstep Python client against the namespaced node.
Only the domain id (from ros_domains) and the output directory are replaced (LOCALHOST)."""
from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from ros_domains import next_domains  # noqa: E402
from procs import Child, ros_env  # noqa: E402
from rod_sim.io.log_reader import LogReader  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "node.md"
DOMAIN_REALTIME, DOMAIN_LOCKSTEP, DOMAIN_DEMO, DOMAIN_TORQUES = next_domains(4)
STARTUP_S = 60.0


def node_section() -> str:
    return PAGE.read_text(encoding="utf-8")


def code_blocks(language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", node_section(), re.M | re.S)


def shell_commands() -> list[str]:
    """The commands of the section's sh blocks: continuation lines joined, comments dropped."""
    out = []
    for block in code_blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                out.append(" ".join(line.split()))
    return out


def localized(command: str, domain: int, out_dir: Path) -> str:
    """The page's command with this test's domain id and output directory."""
    assert "out/" in command, command
    return (command.replace("ROS_DOMAIN_ID=7", f"ROS_DOMAIN_ID={domain}")
            .replace("out/", f"{out_dir}/"))


class Shell(Child):
    """One command of the page under bash (``exec env``: signals reach the program itself)."""

    def __init__(self, command: str, domain: int, tmp_path: Path, name: str):
        super().__init__(["bash", "-c", "exec env " + command], domain,
                         tmp_path / f"{name}.err")

    def wait_for(self, text: str, timeout: float = STARTUP_S) -> None:
        deadline = time.monotonic() + timeout
        while text not in self.stderr:
            assert self.proc.poll() is None, self.stderr
            assert time.monotonic() < deadline, f"no {text!r} in:\n{self.stderr}"
            time.sleep(0.05)

    def interrupt(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        return self.proc.wait(timeout=30)


@pytest.fixture
def shell(tmp_path):
    started = []

    def start(command, domain, name) -> Shell:
        started.append(Shell(localized(command, domain, tmp_path), domain, tmp_path, name))
        return started[-1]

    yield start
    for s in started:
        s.kill()


def ctl_commands() -> list[str]:
    """The page's `rod-sim ctl` lines (run against the real-time node)."""
    return [c for c in shell_commands() if "rod-sim ctl" in c]


def test_the_section_has_the_blocks_this_module_runs():
    commands = [c for c in shell_commands() if "rod-sim ctl" not in c]
    assert len(commands) == 3, commands
    assert len(ctl_commands()) == 7
    assert "rod-sim node" in commands[0] and "record_path:=out/run.mcap" in commands[0]
    assert "__ns:=/arm1" in commands[1] and "sync_mode:=true" in commands[1]
    assert "rod_sim.ros.demo" in commands[2]
    blocks = code_blocks("python")     # the lockstep clients (run here) and the torque helpers
    assert len(blocks) == 3 and "hinge_forces" in blocks[2]   # (run by test_controller_api.py)
    assert '"hinge_torques"' in blocks[1]


def test_realtime_node_with_the_params_file_records_and_answers_ctl(shell, tmp_path):
    node = shell(shell_commands()[0], DOMAIN_REALTIME, "realtime")
    node.wait_for("recording to")
    time.sleep(1.0)
    for command in ctl_commands():         # as the page shows them, each a process
        done = subprocess.run(["bash", "-c", "exec env " + command.replace(
            "ROS_DOMAIN_ID=7", f"ROS_DOMAIN_ID={DOMAIN_REALTIME}")], cwd=REPO,
            env=ros_env(DOMAIN_REALTIME), capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, f"{command}: {done.stdout}{done.stderr}"
        assert done.stdout.strip(), command
    assert node.interrupt() == 0, node.stderr
    assert "Traceback" not in node.stderr
    with LogReader(tmp_path / "run.mcap") as reader:
        assert reader.complete
        assert sum(topic == "/rod_states" for topic, _, _ in reader.messages()) > 10


def test_lockstep_python_client_drives_the_namespaced_node(shell, tmp_path):
    node = shell(shell_commands()[1], DOMAIN_LOCKSTEP, "lockstep")
    node.wait_for("lockstep: waiting for the first nodal_forces command on /arm1/nodal_forces")
    states = 30
    script = tmp_path / "client.py"
    script.write_text(
        "import sys\n"
        f"calls = 0\n"
        "def my_control_law(q, q_rate):\n"
        "    global calls\n"
        "    calls += 1\n"
        f"    if calls > {states}:\n"
        f"        print('answered {states} states'); sys.exit(0)\n"
        "    return [0.0] * 16\n"
        + code_blocks("python")[0])
    client = subprocess.run([sys.executable, str(script), "--ros-args", "-r", "__ns:=/arm1"],
                            cwd=REPO, env=ros_env(DOMAIN_LOCKSTEP), capture_output=True, text=True,
                            timeout=120)
    assert client.returncode == 0, client.stderr
    assert f"answered {states} states" in client.stdout
    assert node.interrupt() == 0, node.stderr
    with LogReader(tmp_path / "arm1.mcap") as reader:
        topics = [topic for topic, _, _ in reader.messages()]
    assert topics.count("/arm1/nodal_forces") == states
    assert topics.count("/arm1/rod_states") == states + 1        # t = 0 and one per command


def test_demo_command_runs(shell, tmp_path):
    demo = shell(shell_commands()[2], DOMAIN_DEMO, "demo")
    assert demo.proc.wait(timeout=150) == 0, demo.stderr
    with LogReader(tmp_path / "demo.mcap") as reader:
        assert reader.complete


def test_hinge_torque_controller_drives_the_namespaced_node(shell, tmp_path):
    """The page's joint-space controller: 300 hinge_torques commands, one lockstep period
    each, recorded with the applied torques of every period; the PD law damps the chain."""
    node = shell(shell_commands()[1], DOMAIN_TORQUES, "lockstep")
    node.wait_for("/arm1/hinge_torques")
    script = tmp_path / "torque_client.py"
    script.write_text(code_blocks("python")[1])
    client = subprocess.run([sys.executable, str(script), "--ros-args", "-r", "__ns:=/arm1"],
                            cwd=REPO, env=ros_env(DOMAIN_TORQUES), capture_output=True,
                            text=True, timeout=150)
    assert client.returncode == 0, client.stderr
    assert "sent 300 hinge_torques commands" in client.stdout
    assert node.interrupt() == 0, node.stderr
    with LogReader(tmp_path / "arm1.mcap") as reader:
        msgs = [(topic, t, m) for topic, t, m in reader.messages()]
    topics = [topic for topic, _, _ in msgs]
    assert topics.count("/arm1/hinge_torques") == 300
    assert topics.count("/arm1/rod_states") == 301              # t = 0 and one per command
    applied = [list(m.data) for topic, _, m in msgs if topic == "/arm1/applied_torques"]
    commands = [list(m.data) for topic, _, m in msgs if topic == "/arm1/hinge_torques"]
    assert len(applied) == 300 and applied == commands         # each period applies its own
    assert all(len(a) == 8 for a in applied) and max(abs(v) for a in applied for v in a) > 1.0
