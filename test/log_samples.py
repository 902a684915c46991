"""Payloads of a short simulated log, per topic, read with the mcap library itself: what the
decoding tests (test_payload_check, test_fast_decode) feed to mcap_ros2's decoder, their
oracle, and to the code they check."""
from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader

from rod_sim.tools import cli


def logged_payloads(scene: Path, out: Path, t_end: float, keep: int | None = None) -> dict:
    """``rod-sim simulate scene`` for ``t_end`` [s] into ``out``, then {topic: (its mcap
    Schema record, [payload bytes])}: every message's, or the first ``keep`` of each topic."""
    assert cli.main(["simulate", str(scene), "--t-end", str(t_end), "--out", str(out)]) == 0
    found: dict = {}
    with open(out, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            kept = found.setdefault(channel.topic, (schema, []))[1]
            if keep is None or len(kept) < keep:
                kept.append(bytes(message.data))
    return found
