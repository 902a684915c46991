"""`rod-sim simulate` refuses a run whose log would pass the size limit (4 GiB uncompressed)
before it starts: its estimate must never admit a log larger than the limit, and must not
refuse one that fits by much. The oracle is the log itself, read by the mcap library: every
sample's message records (31 bytes of record header + the payload, per the MCAP
specification) and their message index entries (16 bytes each); the scene, written once, is
left out. The estimate is probed through the command line only: with the limit just below
the log's size the run is refused, with the limit 25 % above it the run goes."""
from pathlib import Path

import pytest
from mcap.reader import make_reader

from rod_sim.app import limits
from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
RECORD = 31 + 16        # MCAP message record header + message index entry [bytes]


def sample_bytes(log: Path) -> int:
    """Bytes of a log's per-sample messages (every topic but /scene) with their records."""
    total = 0
    with open(log, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic != "/scene":
                total += len(message.data) + RECORD
    return total


@pytest.mark.parametrize("scene, options", [
    ("paper_example.yaml", ["--rate", "1000"]),                     # markers every 20th
    ("paper_example.yaml", ["--rate", "100", "--markers-rate", "0"]),
    ("two_wing_deployment.yaml", ["--rate", "200"]),                # odometry, diagnostics
    ("hub_arm_latch.yaml", ["--rate", "100", "--markers-rate", "0"]),
])
def test_the_size_limit_refuses_a_log_just_over_it_and_admits_one_well_under(
        tmp_path, monkeypatch, capsys, scene, options):
    args = ["simulate", str(ROOT / "config" / scene), "--t-end", "0.3", *options]
    assert cli.main([*args, "--out", str(tmp_path / "run.mcap")]) == 0
    size = sample_bytes(tmp_path / "run.mcap")
    capsys.readouterr()

    monkeypatch.setattr(limits, "MAX_OUTPUT_BYTES", int(size * 0.999))
    assert cli.main([*args, "--out", str(tmp_path / "over.mcap")]) == 2
    err = capsys.readouterr().err
    assert "--rate x --t-end: the log would hold" in err, err
    assert not (tmp_path / "over.mcap").exists()

    monkeypatch.setattr(limits, "MAX_OUTPUT_BYTES", int(size * 1.25))
    assert cli.main([*args, "--out", str(tmp_path / "under.mcap")]) == 0, capsys.readouterr()
