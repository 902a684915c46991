"""compare and chaos (issue 13 item 10), streaming (issue 11 item 13) and untrusted metadata
(issue 11 item 8).

The shipped paper example is lightly damped: after the 1200 N pulse its trajectories separate
exponentially, so a reduced-model log agrees with the full model only up to a predictability
horizon. compare must say "PASS up to t = ..., then INCONCLUSIVE: chaotic" for it (exit 0),
a plain PASS for a strongly damped run of the same chain over the same time, and still FAIL
a log that is wrong before the horizon or departs faster than the chaos explains after it.
"""
from __future__ import annotations

import json
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from rod_sim.io.log_source import read_log
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
from rod_sim.compare import comparison
from rod_sim.tools import cli
from rod_sim.compare.comparison import compare_log

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"
SMALL = ROOT / "config" / "small_chain.yaml"
T_END = "8"


def rod_sim(*args) -> int:
    return cli.main([str(a) for a in args])


def compare_json(capsys, *args):
    code = rod_sim("compare", *args, "--json")
    out = capsys.readouterr()
    return code, json.loads(out.out)


@pytest.fixture(scope="module")
def chaotic_log(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("chaos") / "paper_reduced_8s.mcap"
    assert rod_sim("simulate", PAPER, "--model", "reduced", "--t-end", T_END, "--out", out) == 0
    return out


@pytest.mark.slow
def test_chaotic_log_passes_up_to_the_horizon_then_is_inconclusive(tmp_path, capsys,
                                                                   chaotic_log):
    png = tmp_path / "chaos.png"
    code = rod_sim("compare", chaotic_log, "--plot", png)
    text = capsys.readouterr().out
    assert code == 0, text
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= 100
    verdict = "\n".join(lines[next(i for i, l in enumerate(lines) if l.startswith("PASS")):])
    assert verdict.startswith("PASS up to t = ") and "INCONCLUSIVE: chaotic" in verdict
    assert "Lyapunov" in text and "predictability horizon: t = " in text
    assert png.read_bytes()[:4] == b"\x89PNG"
    code, rep = compare_json(capsys, chaotic_log)
    assert code == 0 and rep["pass"] and rep["verdict"] == "PASS_THEN_INCONCLUSIVE"
    # the SPEC keys keep their meaning: the max over the whole log, far above the tolerance
    assert rep["max_abs_error"]["phi"] > 10 * rep["tolerance"] and not rep["within_tolerance"]
    assert 1.0 < rep["horizon"] < 4.0                   # after the 1 s pulse, before ~3.1 s
    assert rep["max_abs_error_within_horizon"]["phi"] <= rep["tolerance"]
    chaos = rep["chaos"]
    assert chaos["lyapunov_exponent"] > 0.2 and chaos["gain"] > 20
    assert chaos["onset"] < rep["horizon"]
    # the horizon is where the log's error before the onset, amplified, reaches the tolerance
    assert chaos["horizon_cause"] == "log_precision"
    beyond = chaos["beyond_horizon"]
    assert beyond["t_start"] == rep["horizon"] and beyond["max_deamplified_phi_error"] <= 0.01
    assert rep["tolerance_first_exceeded_at"] > rep["horizon"]
    assert rep["reference"]["converged"]


@pytest.mark.slow
def test_damped_long_log_gets_a_plain_pass(tmp_path, capsys):
    scene = load_scene(PAPER).with_changes(hinge_damping=np.full(8, 100.0))
    path = tmp_path / "damped.yaml"
    path.write_text(scene_to_yaml(scene))
    log = tmp_path / "damped.mcap"
    assert rod_sim("simulate", path, "--model", "reduced", "--t-end", T_END, "--out", log) == 0
    capsys.readouterr()
    code, rep = compare_json(capsys, log)
    assert code == 0 and rep["verdict"] == "PASS" and rep["horizon"] is None
    assert rep["t_end"] == 8.0 and rep["chaos"]["gain"] < comparison.ONSET_GAIN
    assert rep["chaos"]["lyapunov_exponent"] < 0
    rod_sim("compare", log)
    out = capsys.readouterr().out
    assert "INCONCLUSIVE" not in out and "\nPASS: max |phi error|" in out


def perturbed_copy(src: Path, dst: Path, t_from: float, delta: float) -> Path:
    """``src`` with every /rod_states phi_1 at t >= t_from shifted by ``delta`` [rad]."""
    from rod_sim.io.log_reader import LogReader
    from rod_sim.io import topics

    with LogReader(src) as reader:
        meta = reader.metadata()
        items = list(reader.messages())
    with LogWriter(dst, metadata=meta) as out:
        for topic, t_ns, msg in items:
            name = topic.lstrip("/")
            if name not in ("rod_states", "applied_forces"):
                continue
            if name == "rod_states":
                phi = list(msg.position)
                if t_ns >= t_from * 1e9:
                    phi[0] += delta
                d = {"header": {"stamp": {"sec": msg.header.stamp.sec,
                                          "nanosec": msg.header.stamp.nanosec},
                                "frame_id": msg.header.frame_id},
                     "name": list(msg.name), "position": phi, "velocity": list(msg.velocity),
                     "effort": list(msg.effort)}
            else:
                d = {"data": list(msg.data)}
            out.write(topic, topics.TOPIC_TYPES[name], t_ns, d)
    return dst


@pytest.mark.slow
def test_negative_controls_still_fail_on_a_chaotic_log(tmp_path, capsys, chaotic_log):
    """Wrong before the horizon: FAIL. A jump of 2 rad late in the run (beyond the horizon)
    is more than the chaos amplification explains there: FAIL."""
    early = perturbed_copy(chaotic_log, tmp_path / "early.mcap", 0.5, 0.05)
    code, rep = compare_json(capsys, early)
    assert code == 1 and rep["verdict"] == "FAIL"
    assert any("before the horizon" in r or "exceeds" in r for r in rep["reasons"])
    late = perturbed_copy(chaotic_log, tmp_path / "late.mcap", 4.0, 2.0)
    code, rep = compare_json(capsys, late)
    assert code == 1 and rep["verdict"] == "FAIL"
    assert any("faster than the dynamics amplify" in r for r in rep["reasons"])


def test_windows_give_the_same_numbers(tmp_path, monkeypatch):
    """Streaming in windows of 7 samples gives what one window gives (the reference runs are
    continued across windows; restarts change them by integration error only)."""
    log = tmp_path / "small.mcap"
    assert rod_sim("simulate", SMALL, "--model", "reduced", "--t-end", "1.5", "--out", log) == 0
    scene = load_scene(SMALL)
    with read_log(log) as source:
        one = compare_log(source, scene, keep_samples=True)
    monkeypatch.setattr(comparison, "WINDOW_SAMPLES", 7)
    with read_log(log) as source:
        many = compare_log(source, scene, keep_samples=True)
    assert many.samples == one.samples == 151
    for q in ("phi", "phi_rate", "node_position", "alpha", "beta"):
        np.testing.assert_allclose(many.quantities[q].err, one.quantities[q].err,
                                   rtol=1e-6, atol=1e-9)
        assert many.quantities[q].scd == pytest.approx(one.quantities[q].scd, abs=1e-6)
    assert many.forces == one.forces


REST = {"name": "rest_chain", "rods": {"count": 3, "length": 1.0, "mass_per_length": 2.0,
                                        "bending_stiffness": 5e3},
        "nodes": {"mass": 1.0}, "hinges": {"stiffness": 50.0, "damping": 0.5}}


def synthetic_log(path: Path, seconds: float, rate: float = 1000.0) -> Path:
    """A log at ``rate`` Hz of a straight chain at rest (no loads; phi logged 1e-6 rad off):
    cheap to re-run, as long as wanted."""
    from rod_sim.core.scene import Scene

    scene = Scene.from_dict(REST)
    n = scene.n
    y = np.zeros(n)
    meta = {"scene": scene_to_yaml(scene), "model": "full", "integrator": "synthetic",
            "rate_hz": repr(rate)}
    with LogWriter(path, metadata=meta) as log:
        for i in range(int(seconds * rate) + 1):
            t_ns = round(i * 1e9 / rate)
            log.write("/rod_states", "sensor_msgs/msg/JointState", t_ns, {
                "header": {"stamp": {"sec": t_ns // 10**9, "nanosec": t_ns % 10**9}},
                "name": [f"rod_{k}" for k in range(1, n + 1)],
                "position": list(y[:n] + 1e-6), "velocity": [0.0] * n})
            log.write("/applied_forces", "std_msgs/msg/Float64MultiArray", t_ns,
                      {"data": [0.0] * (2 * n)})
    return path


def peak_bytes(path: Path):
    from rod_sim.core.scene import Scene

    scene = Scene.from_dict(REST)
    tracemalloc.start()
    try:
        with read_log(path) as source:
            report = compare_log(source, scene, check_rtol=None)
        return tracemalloc.get_traced_memory()[1], report
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_memory_is_bounded_independently_of_the_log_length(tmp_path, monkeypatch):
    """tracemalloc peak of compare (without the check run) on a 2 s and a 20 s log at 1 kHz
    (2001 vs 20001 samples): the long one needs at most 30 % more than the short one (the
    messages of the chunk being read, up to one 256 KiB chunk, come on top of the windows)
    and less than 2 MB, where holding its 40002 decoded messages would take tens of MB (a
    first run compiles and imports, so the short log is compared twice). Windows and the plot
    buffer are made small, so that both logs fill them (the default sizes' memory is
    measured in docs/compare.md)."""
    monkeypatch.setattr(comparison, "WINDOW_SAMPLES", 400)
    monkeypatch.setattr(comparison, "PLOT_POINTS", 300)
    short = synthetic_log(tmp_path / "short.mcap", 2.0)
    long = synthetic_log(tmp_path / "long.mcap", 20.0)
    peak_bytes(short)
    peak_short, rep_short = peak_bytes(short)
    peak_long, rep_long = peak_bytes(long)
    assert rep_short.samples == 2001 and rep_long.samples == 20001
    assert rep_long.reasons() == ["the reference is not converged (estimated phi error 0 rad)"]
    assert rep_long.quantities["phi"].max == pytest.approx(1e-6, rel=1e-6)
    print(f"peak traced memory: 2 s log {peak_short / 1e6:.2f} MB, "
          f"20 s log {peak_long / 1e6:.2f} MB")
    assert peak_long < 1.3 * peak_short and peak_long < 2e6


def bomb_metadata(path: Path, levels: int = 9) -> Path:
    text = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [" + ", ".join([f"*{chr(97 + i)}"] * 9) + "]\n"
        for i in range(levels))
    text += "rods: {count: *" + chr(97 + levels) + "}\n"
    meta = {"scene": text, "model": "reduced", "integrator": "x" * 10_000_000}
    with LogWriter(path, metadata=meta) as log:
        log.write("/rod_states", "sensor_msgs/msg/JointState", 0,
                  {"name": ["rod_1"], "position": [0.0], "velocity": [0.0]})
    return path


@pytest.mark.timing
def test_yaml_bomb_in_metadata_is_refused_quickly(tmp_path, capsys):
    log = bomb_metadata(tmp_path / "bomb.mcap")
    for args in (["compare", log], ["deployment-figure", log, tmp_path / "f.png"]):
        started = time.process_time()      # CPU time: not stretched by other processes
        code = rod_sim(*args)
        err = capsys.readouterr().err
        assert time.process_time() - started < 10
        assert code == 2 and len(err.strip().splitlines()) == 1 and len(err) < 400, err
        assert "YAML bomb" in err


@pytest.mark.parametrize("where", ["decode", "window"])
def test_out_of_memory_is_never_called_corrupt(tmp_path, capsys, monkeypatch, where):
    from rod_sim.io import log_source

    log = synthetic_log(tmp_path / "rest.mcap", 0.05)

    def boom(*args, **kwargs):
        raise MemoryError

    if where == "decode":
        monkeypatch.setattr(log_source.LogStream, "_decode", boom)
    else:
        monkeypatch.setattr(comparison._Comparison, "window", boom)
    code = rod_sim("compare", log)
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "out of memory" in err and "corrupt or" not in err and "not known to be corrupt" in err
