"""Issue 21 item 1: one way to open a log (rod_sim.io.log_open.open_log) for compare, replay,
repair, deployment-figure and the series readers, on every storage and layout: an MCAP file, a
rosbag2 bag directory with metadata.yaml (mcap storage, one or two files), a directory of MCAP
files without metadata.yaml, sqlite3 storage, zstd compression (file and message mode, both
storages); and a missing, corrupt or unsupported one gives the one error type with a one-line
message. Bags are written by the independent rosbags library from a small log."""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from rod_sim.io.log_format import LogFormatError
from rod_sim.io.log_open import bag_layout, open_log
from rod_sim.io.log_reader import LogReader
from rod_sim.io.log_source import read_log
from rod_sim.io.log_writer import LogWriter, offered_qos_yaml
from rod_sim.io.msgdefs import SCHEMAS, TYPE_HASHES
from rod_sim.io.playback import PlaybackError, open_source
from rod_sim.io.series import read_rod_states
from rod_sim.tools import cli

rosbags = pytest.importorskip("rosbags")
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,  # noqa: E402
                                QosReliability, QosTime)
from rosbags.rosbag2 import (CompressionFormat, CompressionMode, StoragePlugin,  # noqa: E402
                             Writer)

N = 3
SAMPLES = 40
PERIOD_NS = 10_000_000
STATES, SCENE = "/rod_states", "/scene"
JOINT, STRING = "sensor_msgs/msg/JointState", "std_msgs/msg/String"
LATCHED = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
              QosTime(0, 0), QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)


def joint_state(k: int) -> dict:
    t_ns = k * PERIOD_NS
    return {"header": {"stamp": {"sec": t_ns // 10**9, "nanosec": t_ns % 10**9},
                       "frame_id": "world"},
            "name": [f"rod_{i}" for i in range(1, N + 1)],
            "position": [0.01 * k * i for i in range(1, N + 1)],
            "velocity": [0.5 * i for i in range(1, N + 1)], "effort": []}


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    """A small rod_sim log: SAMPLES JointStates of N rods every 10 ms, a latched /scene."""
    path = tmp_path_factory.mktemp("open") / "small.mcap"
    qos = {SCENE: offered_qos_yaml(depth=1, durability="transient_local")}
    with LogWriter(path, metadata={"scene": "name: s", "model": "reduced",
                                   "integrator": "rk4"}, qos=qos, chunk_size=2048) as w:
        w.write(SCENE, STRING, 0, {"data": "name: s"})
        for k in range(SAMPLES):
            w.write(STATES, JOINT, k * PERIOD_NS, joint_state(k))
    return path


def raw(path) -> list[tuple[str, int, bytes]]:
    """Every message of the log at ``path`` as (topic, log time [ns], CDR bytes)."""
    with open_log(path) as opened:
        return list(opened.messages(raw=True))


def rosbags_bag(log: Path, bag: Path, storage: StoragePlugin,
                compression: CompressionMode | None = None) -> Path:
    """The messages of ``log`` rewritten by rosbags as a rosbag2 bag (version 9)."""
    with LogReader(log) as reader:
        messages = list(reader.raw_messages())
        types = reader.topics()
    writer = Writer(bag, version=9, storage_plugin=storage)
    if compression is not None:
        writer.set_compression(compression, CompressionFormat.ZSTD)
    with writer:
        conns = {topic: writer.add_connection(topic, types[topic], msgdef=SCHEMAS[types[topic]],
                                              rihs01=TYPE_HASHES[types[topic]],
                                              offered_qos_profiles=(
                                                  [LATCHED] if topic == SCENE else []))
                 for topic in sorted(types)}
        for topic, t_ns, data in messages:
            writer.write(conns[topic], t_ns, data)
    return bag


def split_bag(log: Path, bag: Path, metadata: bool) -> Path:
    """``log`` split into two MCAP files (by time) in ``bag``, with or without metadata.yaml."""
    from mcap.writer import Writer as McapWriter

    bag.mkdir()
    with LogReader(log) as reader:
        schemas, channels, _ = reader.definitions()
        records = list(reader.records())
    half = records[len(records) // 2][1].log_time
    for name, part in (("b_0.mcap", [r for r in records if r[1].log_time < half]),
                       ("b_1.mcap", [r for r in records if r[1].log_time >= half])):
        with open(bag / name, "wb") as f:
            w = McapWriter(f, chunk_size=2048)
            w.start(profile="ros2", library="test")
            sids = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in schemas.items()}
            cids = {cid: w.register_channel(c.topic, c.message_encoding, sids[c.schema_id],
                                            dict(c.metadata)) for cid, c in channels.items()}
            for channel, m in part:
                w.add_message(cids[channel.id], m.log_time, m.data, m.publish_time, m.sequence)
            w.finish()
    if metadata:
        (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": {
            "version": 9, "storage_identifier": "mcap", "compression_mode": "",
            "relative_file_paths": ["b_0.mcap", "b_1.mcap"]}}))
    return bag


LAYOUTS = {
    "mcap bag with metadata.yaml": lambda log, d: split_bag(log, d / "bag", True),
    "mcap files without metadata.yaml": lambda log, d: split_bag(log, d / "bag", False),
    "rosbags mcap bag": lambda log, d: rosbags_bag(log, d / "bag", StoragePlugin.MCAP),
    "sqlite3 bag": lambda log, d: rosbags_bag(log, d / "bag", StoragePlugin.SQLITE3),
    "mcap bag, file compression": lambda log, d: rosbags_bag(
        log, d / "bag", StoragePlugin.MCAP, CompressionMode.FILE),
    "mcap bag, message compression": lambda log, d: rosbags_bag(
        log, d / "bag", StoragePlugin.MCAP, CompressionMode.MESSAGE),
    "sqlite3 bag, file compression": lambda log, d: rosbags_bag(
        log, d / "bag", StoragePlugin.SQLITE3, CompressionMode.FILE),
    "sqlite3 bag, message compression": lambda log, d: rosbags_bag(
        log, d / "bag", StoragePlugin.SQLITE3, CompressionMode.MESSAGE),
}
EXPECTED = {  # (storage, compressed, files read directly)
    "mcap bag with metadata.yaml": ("mcap", False, 2),
    "mcap files without metadata.yaml": ("mcap", False, 2),
    "rosbags mcap bag": ("mcap", False, 1),
    "sqlite3 bag": ("sqlite3", False, 0),
    "mcap bag, file compression": ("mcap", True, 0),
    "mcap bag, message compression": ("mcap", True, 0),
    "sqlite3 bag, file compression": ("sqlite3", True, 0),
    "sqlite3 bag, message compression": ("sqlite3", True, 0),
}


def test_an_mcap_file_is_read_as_written(log):
    layout = bag_layout(log)
    assert (layout.storage, layout.compressed, layout.files, layout.copy) == \
        ("mcap", False, (log,), False)
    with open_log(log) as opened, LogReader(log) as reader:
        assert opened.files == [log] and opened.complete
        assert opened.metadata()["model"] == "reduced"
        assert list(opened.messages(raw=True)) == list(reader.raw_messages())
        decoded = [(topic, t) for topic, t, _ in opened.messages([STATES])]
    assert decoded == [(STATES, k * PERIOD_NS) for k in range(SAMPLES)]


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_every_layout_gives_the_same_messages(layout, log, tmp_path):
    """The same (topic, time, CDR bytes) in the same order as the MCAP file, whatever the
    layout; a copied bag's temporary MCAP file is gone after close."""
    bag = LAYOUTS[layout](log, tmp_path)
    storage, compressed, direct = EXPECTED[layout]
    found = bag_layout(bag)
    assert (found.storage, found.compressed, len(found.files)) == (storage, compressed, direct)
    if compressed:
        info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        assert info["compression_format"] == "zstd"
    with open_log(bag) as opened:
        assert list(opened.messages(raw=True)) == raw(log)
        assert opened.complete
        copies = [f for f in opened.files if not f.is_relative_to(bag)]
        assert len(copies) == (1 if found.copy else 0)
    assert not any(f.exists() for f in copies)


@pytest.mark.parametrize("layout", ["mcap bag with metadata.yaml", "sqlite3 bag",
                                    "mcap bag, message compression"])
def test_the_readers_on_top_read_every_layout(layout, log, tmp_path):
    """Series, replay and compare's stream read a bag as they read the file; replay keeps the
    recorded QoS of a latched topic through the rosbags copy."""
    bag = LAYOUTS[layout](log, tmp_path)
    for a, b in zip(read_rod_states(log), read_rod_states(bag)):
        np.testing.assert_array_equal(a, b)
    with open_source(bag) as source:
        assert sorted(source.tracks) == [STATES, SCENE]
        qos = source.tracks[SCENE].qos
        assert (qos.durability, qos.depth) == ("transient_local", 1)
        assert list(source.messages()) == raw(log)
    with read_log(bag) as stream:
        groups = list(stream.groups())
    assert len(groups) == SAMPLES and stream.n == N
    assert groups[-1].state[0].tolist() == joint_state(SAMPLES - 1)["position"]


def test_storage_without_identifier_is_mcap(log, tmp_path):
    bag = split_bag(log, tmp_path / "bag", True)
    meta = bag / "metadata.yaml"
    info = yaml.safe_load(meta.read_text())
    del info["rosbag2_bagfile_information"]["storage_identifier"]
    meta.write_text(yaml.safe_dump(info))
    assert bag_layout(bag).storage == "mcap"
    assert raw(bag) == raw(log)


def one_line_error(path, match: str) -> str:
    """open_log, replay and compare refuse ``path`` with the same one-line LogFormatError."""
    with pytest.raises(LogFormatError, match=match) as info:
        open_log(path)
    text = str(info.value)
    assert "\n" not in text and str(path) in text
    with pytest.raises(PlaybackError) as again:
        open_source(path)
    assert str(again.value) == text
    with pytest.raises(LogFormatError) as again:
        read_log(path)
    assert str(again.value) == text
    return text


def test_missing_and_non_mcap_paths(tmp_path):
    one_line_error(tmp_path / "absent.mcap", "does not exist .no such file or directory.")
    junk = tmp_path / "junk.mcap"
    junk.write_text("not a log\n")
    one_line_error(junk, "is not an MCAP file")
    empty = tmp_path / "empty"
    empty.mkdir()
    one_line_error(empty, "without metadata.yaml or .mcap files is not a rosbag2 bag")


def test_corrupt_logs(log, tmp_path):
    data = bytearray(log.read_bytes())
    cut = tmp_path / "framing.mcap"
    data[8] = 0x55                                  # the header record's opcode: reserved
    cut.write_bytes(bytes(data))
    one_line_error(cut, "corrupt log: invalid record opcode 0x55 at byte 8")
    bag = split_bag(log, tmp_path / "bag", True)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    one_line_error(bag, r"metadata.yaml: not a rosbag2 metadata file \(\w+Error: ")
    (bag / "metadata.yaml").write_text("something_else: 1\n")
    one_line_error(bag, "not a rosbag2 metadata file .KeyError")
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": {
        "storage_identifier": "mcap", "relative_file_paths": ["b_0.mcap", "b_1.mcap"]}}))
    second = bytearray((bag / "b_1.mcap").read_bytes())
    second[8] = 0x55
    (bag / "b_1.mcap").write_bytes(bytes(second))
    assert "b_1.mcap: corrupt log" in one_line_error(bag, "invalid record opcode 0x55 at byte 8")


def test_bags_that_cannot_be_read(log, tmp_path):
    bag = split_bag(log, tmp_path / "bag", True)
    meta = bag / "metadata.yaml"

    def metadata(**info):
        meta.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))

    metadata(storage_identifier="zarr", relative_file_paths=["b_0.zarr"])
    one_line_error(bag, "bag storage 'zarr' is not supported .only 'mcap' and 'sqlite3' bags "
                        "can be read; convert it with rosbags-convert")
    metadata(storage_identifier="mcap", relative_file_paths=["b_0.mcap", "gone.mcap"])
    one_line_error(bag, r"bag file .*gone.mcap listed in metadata.yaml is missing")
    metadata(storage_identifier="mcap", relative_file_paths=[])
    one_line_error(bag, "metadata.yaml lists no files")
    metadata(storage_identifier="sqlite3", relative_file_paths=["b_0.db3"])
    one_line_error(bag, "cannot read the sqlite3 bag")
    metadata(storage_identifier="mcap", relative_file_paths=["b_0.mcap.zstd"],
             compression_mode="FILE", compression_format="zstd")
    one_line_error(bag, "cannot read the compressed bag")


def test_a_copied_bag_needs_rosbags(log, tmp_path, monkeypatch):
    bag = rosbags_bag(log, tmp_path / "bag", StoragePlugin.SQLITE3)
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)
    one_line_error(bag, "reading a sqlite3 bag needs the rosbags library .pip install rosbags")


@pytest.mark.parametrize("command", ["compare", "replay", "repair", "deployment-figure"])
def test_every_command_refuses_a_missing_log_the_same_way(command, tmp_path, capsys):
    missing = tmp_path / "absent.mcap"
    extra = [str(tmp_path / "out.png")] if command == "deployment-figure" else []
    assert cli.main([command, str(missing), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"rod-sim {command}: error: {missing} does not exist (no such file or "
                   "directory)"]


def test_repair_takes_one_file(log, tmp_path, capsys):
    """repair refuses a bag directory (it rewrites one file) and rewrites a cut file with the
    messages of its complete chunks."""
    bag = split_bag(log, tmp_path / "bag", True)
    assert cli.main(["repair", str(bag)]) == 2
    assert "repair rewrites one MCAP file" in capsys.readouterr().err
    cut = tmp_path / "cut.mcap"
    shutil.copy(log, cut)
    data = cut.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    assert cli.main(["repair", str(cut)]) == 0
    assert raw(tmp_path / "cut.repaired.mcap") == raw(cut)
