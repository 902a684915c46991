"""Command lines of the node and the demo controller (issues 11 and 13): bad ROS arguments and
scenes that cannot start exit 2 with one line, errors name the command the user typed, ROS
arguments without --ros-args get a hint, pd_controller has --help and says what it does at
start. ROS domain ids from ros_domains (LOCALHOST)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from ros_domains import next_domains  # noqa: E402

pytest.importorskip("rclpy")

REPO = Path(__file__).resolve().parents[1]
SMALL = REPO / "config" / "small_chain.yaml"
DOMAIN_BAD, DOMAIN_CONTROLLER = next_domains(2)


def run(args: list[str], timeout: float = 120.0, limit: int | None = None
        ) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(DOMAIN_BAD), PYTHONUNBUFFERED="1")
    if limit is not None:
        env["ROD_SIM_MEMORY_LIMIT"] = str(limit)
    return subprocess.run([sys.executable, "-m", *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)


def error_lines(done: subprocess.CompletedProcess) -> list[str]:
    """stderr without rcl's own warnings (e.g. its deprecation notice for a bare FROM:=TO)."""
    return [line for line in done.stderr.splitlines() if not line.startswith("[WARN]")]


@pytest.mark.ros
@pytest.mark.parametrize("args, message", [
    (["--ros-args", "-p"], "rod-sim node: error: invalid ROS arguments: Failed to parse ROS "
                           "arguments: Couldn't parse trailing -p flag"),
    (["-p", "scene_file:=config/small_chain.yaml"],
     "(ROS arguments go after --ros-args, e.g. --ros-args -p scene_file:=SCENE.yaml)"),
    (["--ros-args", "-p", "scene_file:=PHI308"],
     "initial.phi: magnitude must be <= 1e+12"),     # refused by the scene validation
    (["--ros-args", "-p", "scene_file:=HUGE"],          # issue 19 item 5: was a MemoryError
     "rods.count: a chain of 100000 rods needs about"),  # traceback; simulate's estimate
])
def test_rod_sim_node_refuses_in_one_line(args, message, tmp_path):
    scene = tmp_path / "phi308.yaml"
    scene.write_text(SMALL.read_text().replace("phi: [0.0, 0.1, 0.2]", "phi: [1.0e308, 0.1, 0.2]"))
    huge = tmp_path / "huge.yaml"
    huge.write_text("rods: {count: 100000, length: 1.0, mass_per_length: 1.0, "
                    "bending_stiffness: 100.0}\nnodes: {mass: 1.0}\n"
                    "hinges: {stiffness: 10.0, damping: 0.1}\n")
    args = [a.replace("PHI308", str(scene)).replace("HUGE", str(huge)) for a in args]
    done = run(["rod_sim.tools.cli", "node", *args], limit=1024 ** 3)   # 1 GiB: 100000 rods
    assert done.returncode == 2, done.stderr                           # need ~1.9 GiB
    lines = error_lines(done)
    assert len(lines) == 1 and message in lines[0], done.stderr
    assert lines[0].startswith("rod-sim node: error:")


def test_sim_node_keeps_its_own_name():
    done = run(["rod_sim.ros.node", "--ros-args", "-p"])
    assert done.returncode == 2 and error_lines(done)[0].startswith("sim_node: error:")


def test_pd_controller_help():
    done = run(["rod_sim.ros.controller", "--help"], timeout=60)
    assert done.returncode == 0
    assert done.stdout.startswith("usage: pd_controller") and "kp [N m/rad]" in done.stdout


@pytest.mark.ros
def test_pd_controller_says_what_it_does_at_start(monkeypatch):
    import rclpy
    from rclpy.parameter import Parameter

    from rod_sim.ros.controller import HingePDController

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_CONTROLLER))
    context = rclpy.Context()
    rclpy.init(args=["test", "--ros-args", "-r", "__ns:=/arm1"], context=context,
               domain_id=DOMAIN_CONTROLLER)
    try:
        node = HingePDController(context=context, parameter_overrides=[
            Parameter("scene_file", value=str(SMALL)), Parameter("kp", value=1500.0)])
        summary = node.summary
        node.destroy_node()
    finally:
        context.try_shutdown()
    assert "kp 1500 N m/rad" in summary and "kd 200 N m s/rad" in summary
    assert str(SMALL) in summary
    assert "/arm1/joint_states" in summary and "/arm1/nodal_forces" in summary


def test_simulate_help_states_defaults_and_documents_integrator_and_frame_id(capsys):
    from rod_sim.tools import cli

    with pytest.raises(SystemExit) as exc:
        cli.main(["simulate", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "(default reduced)" in text and "(default world)" in text
    assert "compiled adaptive Dormand- Prince" in text or "compiled adaptive Dormand-Prince" in text
    assert "scipy's RK45" in text and "(default 100)" in text
