"""The parts the node is built from, without a ROS graph: command intake (length check,
decoding, validation, counts, hold and timeout), the node's log (refusal of an existing file,
rolling to the next free name, a write error, its metadata, received commands as they came),
parameter texts and the /clock QoS."""
from __future__ import annotations

import struct
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray

from rod_sim.api import load_scene
from rod_sim.io.log_reader import LogReader
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import scene_to_yaml
from rod_sim.ros.commands import COMMAND_SLACK_BYTES, CommandIntake
from rod_sim.ros.errors import NodeConfigError
from rod_sim.ros.parameters import PARAMETERS, parameter_error, validate_change
from rod_sim.ros.outputs import OUTPUTS
from rod_sim.ros.qos import LOCKSTEP_STATE_DEPTH, clock_qos
from rod_sim.ros.recording import NodeRecording, create_log, node_log_opener, offered_qos

SMALL = Path(__file__).resolve().parents[1] / "config" / "small_chain.yaml"

TOPIC, TYPE = "/nodal_forces", "std_msgs/msg/Float64MultiArray"
META = {"scene": "name: t", "model": "reduced", "integrator": "dop853-jit"}


def command(values) -> Float64MultiArray:
    msg = Float64MultiArray()
    msg.data = [float(v) for v in values]
    return msg


# ----- commands -----

def test_oversize_and_undecodable_commands_are_counted_and_not_decoded():
    intake = CommandIntake(n=3, timeout_s=0.5)
    assert intake.max_bytes == 16 * 6 + COMMAND_SLACK_BYTES
    assert intake.decode(b"\x00" * (intake.max_bytes + 1)) is None
    assert intake.last_rejection.startswith(f"{intake.max_bytes + 1} bytes, more than the")
    assert intake.decode(b"\x00\x01\x00\x00\x05") is None
    assert "cannot be decoded" in intake.last_rejection
    msg = intake.decode(serialize_message(command(range(6))))
    assert list(msg.data) == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert (intake.received, intake.rejected, intake.latest) == (2, 2, None)


def test_an_invalid_command_keeps_the_last_valid_one():
    intake = CommandIntake(n=2, timeout_s=0.0)
    first = intake.accept(command([1, 2, 3, 4]), sim_ns=5)
    assert first.sim_ns == 5 and first.forces.tolist() == [[1, 2], [3, 4]]
    assert intake.accept(command([1, 2, 3]), sim_ns=6) is None
    assert intake.accept(command([1, 2, float("nan"), 4]), sim_ns=7) is None
    assert intake.latest is first
    assert (intake.received, intake.rejected) == (3, 2)
    assert "non-finite" in intake.last_rejection


def test_the_held_command_times_out_in_simulated_or_wall_time():
    intake = CommandIntake(n=1, timeout_s=0.1)
    assert not intake.held(0, wall_age=False).any() and not intake.active
    intake.accept(command([3, 4]), sim_ns=1_000_000_000)
    assert intake.held(1_100_000_000, wall_age=False).tolist() == [[3, 4]] and intake.active
    assert not intake.held(1_100_000_001, wall_age=False).any() and not intake.active
    intake.set_timeout(0.0)                                   # hold forever
    assert intake.held(10**15, wall_age=False).tolist() == [[3, 4]]
    intake.set_timeout(0.01)
    time.sleep(0.02)
    assert not intake.held(0, wall_age=True).any()            # wall age: 20 ms > 10 ms
    intake.clear()
    assert intake.latest is None and not intake.active and intake.received == 1


# ----- recording -----

class Lines:
    """A stand-in for the node's rclpy logger."""

    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def info(self, text):
        self.lines.append(("info", text))

    def error(self, text):
        self.lines.append(("error", text))


def test_create_log_refuses_an_existing_file_in_one_line(tmp_path):
    taken = tmp_path / "run.mcap"
    taken.write_bytes(b"keep me")
    with pytest.raises(NodeConfigError, match=r"^record_path: .*run.mcap exists; remove it"):
        create_log(taken, META, {})
    assert taken.read_bytes() == b"keep me"
    (tmp_path / "file").write_text("")
    with pytest.raises(NodeConfigError, match=r"^record_path: ") as err:
        create_log(tmp_path / "file" / "run.mcap", META, {})    # a file where a folder should be
    assert "\n" not in str(err.value)


def test_recording_rolls_to_the_next_free_name_and_stops_on_errors(tmp_path):
    base = tmp_path / "sub" / "run.mcap"
    base.parent.mkdir()
    (tmp_path / "sub" / "run_1.mcap").write_bytes(b"someone else's")
    logger = Lines()
    rec = NodeRecording(lambda path: create_log(path, META, {}), logger)
    assert rec.roll() == "" and rec.path is None               # not recording: nothing to roll
    rec.start(base)
    rec.record(TOPIC, TYPE, 5, {"data": [1.0]})
    assert rec.roll() == f"; recording continues in {tmp_path / 'sub' / 'run_2.mcap'}"
    assert rec.path == tmp_path / "sub" / "run_2.mcap"
    assert (tmp_path / "sub" / "run_1.mcap").read_bytes() == b"someone else's"
    with LogReader(base) as reader:                            # the first log was closed whole
        assert [t for _, t, _ in reader.messages()] == [5]

    rec.writer.close()                                        # a write to a closed log fails
    rec.record(TOPIC, TYPE, 6, {"data": [2.0]})
    assert rec.writer is None and rec.error and "\n" not in rec.error
    assert ("error", f"recording stopped: {rec.error}") in logger.lines


def test_a_log_that_cannot_be_opened_after_a_reset_is_reported(tmp_path):
    logger = Lines()
    opened: list[LogWriter] = []

    def open_log(path):
        if opened:
            raise NodeConfigError(f"record_path: cannot create {path}")
        opened.append(create_log(path, META, {}))
        return opened[-1]

    rec = NodeRecording(open_log, logger)
    rec.start(tmp_path / "run.mcap")
    note = rec.roll()
    assert note == f"; recording stopped: record_path: cannot create {tmp_path / 'run_1.mcap'}"
    assert rec.writer is None and rec.error.startswith("record_path: cannot create")
    assert opened[0].closed


def test_offered_qos_keeps_hinge_events_deeper():
    names = {"applied_forces": "/ns/applied_forces", "hinge_events": "/ns/hinge_events"}
    qos = offered_qos(names, ("applied_forces", "hinge_events"))
    assert set(qos) == {"/ns/applied_forces", "/ns/hinge_events"}
    assert "\n  depth: 100\n" in qos["/ns/hinge_events"]
    assert "\n  depth: 1\n" in qos["/ns/applied_forces"]
    assert all("\n  durability: transient_local\n" in text for text in qos.values())


def test_a_received_command_is_recorded_as_it_came_when_little_endian(tmp_path):
    """Little-endian CDR: the bytes as they came (not the decoded message, which differs here
    on purpose); big-endian CDR: the decoded message, re-encoded little-endian."""
    rec = NodeRecording(lambda path: create_log(path, META, {}), Lines())
    rec.start(tmp_path / "run.mcap")
    little = serialize_message(command([1.0, 2.0]))
    rec.record_received(TOPIC, TYPE, 5, command([9.0]), little)
    big = (b"\x00\x00\x00\x00" + struct.pack(">III", 0, 0, 2) + b"\x00" * 4
           + struct.pack(">dd", 3.0, 4.0))                   # the same message, big-endian
    rec.record_received(TOPIC, TYPE, 6, command([3.0, 4.0]), big)
    rec.close()
    with LogReader(tmp_path / "run.mcap") as reader:
        raw = list(reader.raw_messages())
        decoded = [list(msg.data) for _, _, msg in reader.messages()]
    assert [(topic, t) for topic, t, _ in raw] == [(TOPIC, 5), (TOPIC, 6)]
    assert raw[0][2] == little
    assert raw[1][2][:2] == b"\x00\x01" and decoded == [[1.0, 2.0], [3.0, 4.0]]


def test_a_node_log_has_the_run_metadata_and_the_mode_when_it_opens(tmp_path):
    scene = load_scene(SMALL)
    settings = SimpleNamespace(rtol=1e-8, rate_hz=250.0, sync_mode=True)
    modes = iter(["lockstep", "real time x2"])
    names = {o.name: f"/ns/{o.name}" for o in OUTPUTS}
    open_log = node_log_opener(scene, "reduced", "dop853-jit rtol=1e-08", settings,
                               lambda: next(modes), "/ns/rod_sim", names)
    for name in ("first.mcap", "second.mcap"):
        log = open_log(tmp_path / "sub" / name)
        log.write("/ns/applied_forces", TYPE, 0, {"data": [1.0]})
        log.write("/ns/joint_states", "sensor_msgs/msg/JointState", 0, {"name": ["a"]})
        log.write(TOPIC, TYPE, 0, {"data": [1.0]})
        log.close()
    for name, mode in (("first.mcap", "lockstep"), ("second.mcap", "real time x2")):
        with LogReader(tmp_path / "sub" / name) as reader:
            meta, channels = reader.metadata(), reader.channels()
        assert {k: meta[k] for k in ("scene", "model", "integrator", "rtol", "rate_hz", "mode",
                                     "node", "source")} == {
            "scene": scene_to_yaml(scene), "model": "reduced",
            "integrator": "dop853-jit rtol=1e-08", "rtol": "1e-08", "rate_hz": "250.0",
            "mode": mode, "node": "/ns/rod_sim", "source": "rod_sim node"}
        qos = {topic: info.metadata["offered_qos_profiles"] for topic, info in channels.items()}
        assert "\n  depth: 1\n" in qos["/ns/applied_forces"]
        assert f"\n  depth: {LOCKSTEP_STATE_DEPTH}\n" in qos["/ns/joint_states"]
        assert "transient_local" in qos["/ns/joint_states"]
        assert "durability: volatile" in qos[TOPIC]


# ----- parameters and QoS -----

def test_parameter_errors_lead_with_the_name_and_hint_at_doubles():
    spec = next(p for p in PARAMETERS if p.name == "rate_hz")
    exc = ParameterException("Trying to set a parameter of type 'INTEGER' to 'DOUBLE'", "rate_hz")
    assert parameter_error(spec, exc) == ("rate_hz: Trying to set a parameter of type 'INTEGER'"
                                          " to 'DOUBLE' (write a double, e.g. 100.0)")


def test_an_empty_frame_id_is_refused_at_run_time():
    assert not validate_change([Parameter("frame_id", value="")]).successful
    assert validate_change([Parameter("frame_id", value="map")]).successful


def test_clock_qos_follows_clock_reliability():
    for name, policy in (("reliable", ReliabilityPolicy.RELIABLE),
                         ("best_effort", ReliabilityPolicy.BEST_EFFORT)):
        qos = clock_qos(name)
        assert (qos.depth, qos.reliability, qos.durability) == (1, policy,
                                                                DurabilityPolicy.VOLATILE)
