"""``rod-sim simulate --markers-rate``: ``/markers`` (display only) with every k-th sample of the
log, k = max(1, round(rate / markers-rate)) from t = 0, as the node's ``markers_rate_hz``
(docs/interface.md section 2); every other topic with every sample, unchanged.

The oracle is a second run of the same scene with ``--markers-rate 0`` (markers with every
sample): the run is deterministic, so its messages are the expected bytes."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "config" / "paper_example.yaml"


def simulate(out: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(SCENE),
                           "--t-end", "0.25", "--out", str(out), *args], cwd=REPO,
                          capture_output=True, text=True, timeout=600)


def messages(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            out.setdefault(channel.topic, []).append((message.log_time, message.data))
    return out


@pytest.fixture(scope="module")
def every_sample(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("markers") / "every.mcap"
    r = simulate(out, "--rate", "200", "--markers-rate", "0")
    assert r.returncode == 0, r.stderr
    return messages(out)


@pytest.mark.parametrize("args, every", [((), 4),                      # 200 / 50 Hz
                                         (("--markers-rate", "30"), 7),  # round(6.67)
                                         (("--markers-rate", "500"), 1)])
def test_markers_come_with_every_kth_sample_and_nothing_else_changes(tmp_path, every_sample,
                                                                     args, every):
    out = tmp_path / "run.mcap"
    r = simulate(out, "--rate", "200", *args)
    assert r.returncode == 0, r.stderr
    got = messages(out)
    states = [t for t, _ in every_sample["/rod_states"]]
    assert len(states) == 51 and states[4] == 20_000_000
    want = [m for m in every_sample["/markers"] if states.index(m[0]) % every == 0]
    assert got["/markers"] == want
    assert len(want) == (50 // every) + 1
    assert {k: v for k, v in got.items() if k != "/markers"} == \
        {k: v for k, v in every_sample.items() if k != "/markers"}


@pytest.mark.parametrize("value, says", [("-1", "a finite number >= 0"),
                                         ("nan", "a finite number >= 0"),
                                         ("20000", "more than 10000")])
def test_a_bad_markers_rate_is_refused_in_one_line(tmp_path, value, says):
    out = tmp_path / "bad.mcap"
    r = simulate(out, "--markers-rate", value)
    assert r.returncode == 2
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("rod-sim simulate: error:") and "--markers-rate" in last, r.stderr
    assert says in last
    assert not out.exists()
