"""``rod-sim replay --remap FROM:=TO`` and ``--ros-args ...`` (issue 13): recorded topics
published under other names, the player node in a namespace, ROS arguments no longer parsed
as replay options, and bad ones refused in one line. ROS domain ids from ros_domains
(LOCALHOST)."""
from __future__ import annotations

import pytest

from rod_sim.tools import cli
from rod_sim.tools.replay import ros_arguments
from test_replay import ALL_TOPICS, STARTUP_S, log_path, recorded  # noqa: F401 (fixture)
from ros_domains import next_domains  # noqa: E402

DOMAIN_REMAP, DOMAIN_BAD_REMAP = next_domains(2)


def test_ros_args_are_not_replay_options_and_remaps_become_ros_arguments():
    args = cli.build_parser().parse_args(
        ["replay", "x.mcap", "--remap", "/rod_states:=/arm1/rod_states", "--rate", "2",
         "--ros-args", "-r", "__ns:=/arm1"])
    assert args.rate == 2.0 and args.ros_args == ["-r", "__ns:=/arm1"]
    assert ros_arguments(args) == ["--ros-args", "-r", "/rod_states:=/arm1/rod_states",
                                   "-r", "__ns:=/arm1"]
    assert ros_arguments(cli.build_parser().parse_args(["replay", "x.mcap"])) == []


@pytest.mark.parametrize("argv, message", [
    (["--remap", "rod_states"], "not a remapping FROM:=TO"),
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--live-view", "0"], "must be a port 1..65535 (got 0)"),
    (["--live-view", "http"], "not a port number: 'http'"),
    (["--delay", "-1"], "must be a finite number >= 0 (got -1)"),
    (["--start-offset", "nan"], "must be a finite number >= 0 (got nan)"),
    (["--start-offset", "inf"], "must be a finite number >= 0 (got inf)"),
    (["--delay", "soon"], "not a number: 'soon'"),
])
def test_bad_options_print_replay_usage(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["replay", "x.mcap", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: rod-sim replay") and message in err


def test_invalid_ros_arguments_are_one_line_and_status_2(log_path, capsys):  # noqa: F811
    assert cli.main(["replay", str(log_path), "--ros-args", "-p"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rod-sim replay: error: invalid ROS arguments")


rclpy = pytest.importorskip("rclpy")

from std_srvs.srv import SetBool  # noqa: E402

from test_replay import listener, replay  # noqa: E402,F401 (fixtures)


@pytest.mark.ros
@pytest.mark.timeout(90)
def test_remap_and_namespace(log_path, listener, replay):  # noqa: F811
    lis = listener(DOMAIN_REMAP, [("/arm1/rod_states", ALL_TOPICS["/rod_states"])], clock=False)
    proc = replay(DOMAIN_REMAP, log_path, "--topics", "/rod_states", "--no-clock",
                  "--remap", "/rod_states:=/arm1/rod_states", "--wait-for-subscribers",
                  "--ros-args", "-r", "__ns:=/arm1")
    lis.spin_until(lambda: len(lis.received["/arm1/rod_states"]) >= 51, STARTUP_S,
                   "the remapped rod_states", proc.proc)
    assert proc.wait() == 0, proc.stderr
    assert [d for _, d in lis.received["/arm1/rod_states"]] == \
        [d for _, d in recorded(log_path, "/rod_states")]
    names = dict(lis.node.get_topic_names_and_types())
    assert "/rod_states" not in names
    assert "__ns" not in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.ros
@pytest.mark.timeout(90)
def test_pause_service_in_the_namespace(log_path, listener, replay):  # noqa: F811
    lis = listener(DOMAIN_BAD_REMAP, [], clock=False)
    proc = replay(DOMAIN_BAD_REMAP, log_path, "--topics", "/rod_states", "--no-clock",
                  "--start-paused", "--ros-args", "-r", "__ns:=/arm1")
    client = lis.node.create_client(SetBool, "/arm1/rod_sim_replay/pause")
    lis.spin_until(client.service_is_ready, STARTUP_S, "the namespaced pause service",
                   proc.proc)
    answer = lis.call_idempotent(client, SetBool.Request(data=False), 10.0, "the pause service",
                                 proc.proc)
    assert answer is None or answer.success     # None: resumed, its answer lost (see there)
    assert proc.wait() == 0, proc.stderr        # started paused: it ends only once resumed
    assert "]: playing" in proc.stderr
