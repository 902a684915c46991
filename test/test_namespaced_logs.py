"""Logs whose topics carry a namespace (a node started with ``-r __ns:=/arm1`` records
``/arm1/rod_states``): compare, replay's topic selection and the readers find our topics under
any namespace, and refuse to guess between two (issue 13 item 2, the reader side)."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_compare import rewrite

from rod_sim.io.hinge_events import read_hinge_events
from rod_sim.io.log_format import LogFormatError
from rod_sim.io.series import read_rod_states
from rod_sim.io.topic_names import resolve_topics
from rod_sim.io.playback import PlaybackError, Track, QosSpec, open_source, select_topics
from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "config" / "small_chain.yaml"


def rod_sim(*args) -> int:
    return cli.main([str(a) for a in args])


def renamed(src: Path, dst: Path, namespaces: list[str]) -> Path:
    """Copy ``src`` with every topic ``/x`` written once under each namespace (``/ns/x``),
    as two recorded nodes would give; the metadata records are kept."""
    def under(items):
        return [(schema, replace(channel, topic=ns + channel.topic, id=channel.id + 1000 * k),
                 msg) for k, ns in enumerate(namespaces) for schema, channel, msg in items]
    rewrite(src, dst, under)
    return dst


@pytest.fixture(scope="module")
def plain_log(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ns") / "plain.mcap"
    assert rod_sim("simulate", SMALL, "--model", "reduced", "--t-end", "0.5", "--out", out) == 0
    return out


def compare_json(capsys, *args) -> tuple[int, dict | None, str]:
    code = rod_sim("compare", *args, "--json")
    out = capsys.readouterr()
    return code, (json.loads(out.out) if out.out.strip() else None), out.err


def test_compare_finds_namespaced_topics(tmp_path, capsys, plain_log):
    code, plain, _ = compare_json(capsys, plain_log)
    ns_log = renamed(plain_log, tmp_path / "arm1.mcap", ["/arm1"])
    code_ns, rep, _ = compare_json(capsys, ns_log)
    assert code == code_ns == 0
    assert rep["samples_compared"] == plain["samples_compared"] == 51
    assert rep["max_abs_error"] == plain["max_abs_error"]
    assert any("/arm1/rod_states" in n for n in rep["notes"])
    t, phi, _ = read_rod_states(ns_log)
    t0, phi0, _ = read_rod_states(plain_log)
    assert np.array_equal(phi, phi0) and np.array_equal(t, t0)
    assert read_hinge_events(ns_log) == []


def test_two_namespaces_need_a_choice(tmp_path, capsys, plain_log):
    two = renamed(plain_log, tmp_path / "two.mcap", ["/arm1", "/arm2"])
    code = rod_sim("compare", two)
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert "/arm1, /arm2" in err and "--namespace" in err
    code, rep, _ = compare_json(capsys, two, "--namespace", "/arm2")
    assert code == 0 and rep["samples_compared"] == 51
    code = rod_sim("compare", two, "--namespace", "/arm3")
    err = capsys.readouterr().err
    assert code == 2 and "rod_states" in err


def test_resolve_topics_rules():
    logged = ["/arm1/rod_states", "/arm1/applied_forces", "/clock", "/rosout"]
    assert resolve_topics(logged, ["/rod_states", "applied_forces", "bending"]) == {
        "rod_states": "/arm1/rod_states", "applied_forces": "/arm1/applied_forces"}
    assert resolve_topics(["/rod_states"], ["rod_states"]) == {"rod_states": "/rod_states"}
    assert resolve_topics(logged + ["/rod_states"], ["rod_states"], namespace="/") == {
        "rod_states": "/rod_states"}
    with pytest.raises(LogFormatError, match="2 namespaces"):
        resolve_topics(logged + ["/rod_states"], ["rod_states"])


def test_replay_selects_namespaced_topics_by_base_name(tmp_path, plain_log):
    ns_log = renamed(plain_log, tmp_path / "arm1.mcap", ["/arm1"])
    with open_source(ns_log) as source:
        assert select_topics(source.tracks, ["rod_states"]) == ["/arm1/rod_states"]
        assert select_topics(source.tracks, ["/arm1/rod_states", "bending"]) == [
            "/arm1/bending", "/arm1/rod_states"]
        everything = select_topics(source.tracks, None, ["rod_states"])
        assert "/arm1/rod_states" not in everything and "/arm1/bending" in everything
        with pytest.raises(PlaybackError, match="not in the log"):
            select_topics(source.tracks, ["/rod_states"])
    tracks = {t: Track(t, "x/msg/Y", "cdr", QosSpec()) for t in ("/a/rod_states", "/b/rod_states")}
    with pytest.raises(PlaybackError, match="ambiguous.*/a/rod_states, /b/rod_states"):
        select_topics(tracks, ["rod_states"])
