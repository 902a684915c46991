"""Issue 20 item 8: logs that survive the standard tools. The node records its scene (and its
URDF) on latched topics; converted to a rosbag2 sqlite3 bag with `rosbags-convert` (which drops
MCAP metadata records), the log still compares (scene from /scene) and replays (its QoS kept),
and a storage rod_sim cannot read names the tool to convert it with. Each step is a separate
process as a user runs it. ROS domain id from ros_domains (LOCALHOST)."""
from __future__ import annotations

import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("rosbags")

from ros_domains import next_domain  # noqa: E402
from procs import ros_env  # noqa: E402
from rod_sim.io.log_reader import LogReader  # noqa: E402
from rod_sim.io.playback import parse_offered_qos  # noqa: E402
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml  # noqa: E402
from ros_graph import Client, NodeProcess, unique_namespace, wait_for_states  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(240)]

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "paper_example.yaml"
DOMAIN = next_domain()
CONVERT = Path(sys.executable).parent / "rosbags-convert"


def rod_sim(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", *args], cwd=REPO,
                          env=ros_env(DOMAIN), capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_a_node_log_converted_to_sqlite3_compares_and_replays(tmp_path, monkeypatch):
    ns = unique_namespace()
    log = tmp_path / "node.mcap"
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"], scene_file=PAPER,
                       record_path=log)
    try:
        node.wait_for_output("recording to")
        wait_for_states(DOMAIN, 120, node, namespace=ns)      # recorded: every one and more
        assert node.stop(signal.SIGINT) == 0, node.stderr
    finally:
        node.kill()
    scene_yaml = scene_to_yaml(load_scene(PAPER))
    with LogReader(log) as reader:
        channels = reader.channels()
        for name in ("scene", "robot_description"):
            qos = parse_offered_qos(channels[f"{ns}/{name}"].metadata["offered_qos_profiles"])
            assert (qos.durability, qos.depth) == ("transient_local", 1), name
        latched = {topic: (t, msg.data) for topic, t, msg in
                   reader.messages([f"{ns}/scene", f"{ns}/robot_description"])}
    assert latched[f"{ns}/scene"] == (0, scene_yaml)
    assert latched[f"{ns}/robot_description"][1].startswith('<?xml version="1.0"?>\n<robot')

    bag = tmp_path / "bag"
    done = subprocess.run([str(CONVERT), "--src", str(log), "--dst", str(bag),
                           "--dst-storage", "sqlite3"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert list(bag.glob("*.db3"))

    compared = rod_sim("compare", str(bag))
    assert compared.returncode == 0, compared.stdout + compared.stderr
    assert "from the log's /scene topic" in compared.stdout and "PASS" in compared.stdout

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    client = Client(DOMAIN, namespace=ns)
    states, scenes = [], []
    client.node.create_subscription(JointState, "rod_states", states.append, 100)
    client.node.create_subscription(String, "scene", lambda m: scenes.append(m.data),
                                    QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    player = subprocess.Popen([sys.executable, "-m", "rod_sim.tools.cli", "replay", str(bag),
                               "--topics", f"{ns}/rod_states", f"{ns}/scene", "--rate", "4",
                               "--wait-for-subscribers"], cwd=REPO, env=ros_env(DOMAIN),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        client.spin_until(lambda: player.poll() is not None, 60.0, "the end of the replay")
        client.spin_for(0.3)
    finally:
        if player.poll() is None:
            player.kill()
        client.close()
    assert player.returncode == 0, player.stderr.read()
    assert scenes == [scene_yaml]
    with LogReader(log) as reader:
        recorded = sum(1 for _ in reader.messages([f"{ns}/rod_states"]))
    assert len(states) == recorded > 100


@pytest.mark.slow
def test_a_simulate_log_converted_to_sqlite3_is_self_contained(tmp_path):
    log = tmp_path / "run.mcap"
    assert rod_sim("simulate", str(PAPER), "--t-end", "0.5", "--out", str(log)).returncode == 0
    bag = tmp_path / "bag"
    subprocess.run([str(CONVERT), "--src", str(log), "--dst", str(bag), "--dst-storage",
                    "sqlite3"], check=True, capture_output=True, timeout=120)
    done = rod_sim("compare", str(bag), "--json")
    assert done.returncode == 0, done.stderr
    assert '"scene": "paper_example"' in done.stdout
    other = tmp_path / "other"
    other.mkdir()
    (other / "metadata.yaml").write_text("rosbag2_bagfile_information:\n"
                                         "  storage_identifier: zarr\n"
                                         "  relative_file_paths: [x.zarr]\n")
    refused = rod_sim("compare", str(other))
    assert refused.returncode == 2 and "rosbags-convert" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_deployment_figure_finds_the_scene_of_a_converted_bag(tmp_path, storage):
    """Issue 27, item 7: on a rosbags-convert copy (no MCAP metadata, the /scene topic kept)
    deployment-figure said "metadata holds no scene" while compare read the scene from
    /scene. Every tool finds a log's scene one way (LogStream.scene)."""
    pytest.importorskip("matplotlib")
    log = tmp_path / "run.mcap"
    deployment = REPO / "config" / "deployment.yaml"
    assert rod_sim("simulate", str(deployment), "--t-end", "0.2", "--out",
                   str(log)).returncode == 0
    bag = tmp_path / "bag"
    subprocess.run([str(CONVERT), "--src", str(log), "--dst", str(bag), "--dst-storage",
                    storage], check=True, capture_output=True, timeout=120)
    png = tmp_path / "fig.png"
    done = rod_sim("deployment-figure", str(bag), str(png))
    assert done.returncode == 0, done.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    compared = rod_sim("compare", str(bag), "--json")
    assert '"scene": "deployment"' in compared.stdout, compared.stdout[:300]


def test_replay_skips_and_counts_the_corrupt_messages_of_a_sqlite3_bag(tmp_path):
    """Issue 27, item 6: on a sqlite3 bag (no CRCs) whose payloads are corrupt every third
    message, replay republished all of them, exit 0, no warning. Now each payload is checked
    against its type before it is published (payload_check): the corrupt ones (cut short,
    padded, random bytes) are skipped, counted per topic and reported, exit 1; the others are
    all published."""
    import random
    import sqlite3

    log = tmp_path / "run.mcap"
    assert rod_sim("simulate", str(PAPER), "--t-end", "0.5", "--rate", "50", "--out",
                   str(log)).returncode == 0
    bag = tmp_path / "bag"
    subprocess.run([str(CONVERT), "--src", str(log), "--dst", str(bag), "--dst-storage",
                    "sqlite3"], check=True, capture_output=True, timeout=120)
    db = next(bag.glob("*.db3"))
    rng = random.Random(27)
    with sqlite3.connect(db) as con:
        rows = con.execute("SELECT id, data FROM messages ORDER BY id").fetchall()
        damaged = 0
        for k, (mid, data) in enumerate(rows):
            if k % 3 != 2:
                continue
            kind = damaged % 3
            bad = (data[:len(data) // 2] if kind == 0 else data + bytes(8) if kind == 1
                   else bytes(rng.randrange(256) for _ in data))
            con.execute("UPDATE messages SET data = ? WHERE id = ?", (bad, mid))
            damaged += 1
    assert damaged > 30
    done = rod_sim("replay", str(bag), "--rate", "20", "--no-clock")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"rod-sim replay: skipped {damaged} corrupt message(s), not "
                           "published ("), last
    published = re.search(r"end of log: (\d+) messages", done.stderr)
    assert published and int(published.group(1)) == len(rows) - damaged, done.stderr
