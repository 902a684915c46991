"""deployment-figure's output and scene checks, and compare without matplotlib: one line,
exit status 2, no existing file touched, never a numpy or import traceback."""
import sys
from pathlib import Path

import pytest
from mcap.writer import Writer as McapWriter

from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import scene_from_yaml_text, scene_to_yaml
from rod_sim.tools import cli

SCENE = """
rods: {count: 3, length: 1.0, mass_per_length: 1.0, bending_stiffness: 1.0e3}
nodes: {mass: 1.0}
hinges: {stiffness: 10.0, damping: 0.1}
loads:
  - {node: 3, axis: y, shape: raised_cosine_pulse, amplitude: 5.0, duration: 0.2}
"""
OTHER = SCENE.replace("count: 3", "count: 2").replace("node: 3", "node: 2")


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    """A 0.3 s reduced-model log of SCENE."""
    path = tmp_path_factory.mktemp("fig") / "run.mcap"
    scene_file = path.with_suffix(".yaml")
    scene_file.write_text(SCENE)
    assert cli.main(["simulate", str(scene_file), "--t-end", "0.3", "--out", str(path)]) == 0
    return path


def figure(*args) -> int:
    return cli.main(["deployment-figure", *map(str, args)])


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_figure_is_drawn(log, tmp_path, capsys):
    assert figure(log, tmp_path / "a.png") == 0
    assert (tmp_path / "a.png").stat().st_size > 1000


def test_figure_refuses_to_overwrite(log, tmp_path, capsys):
    png = tmp_path / "a.png"
    png.write_bytes(b"keep me")
    assert figure(log, png) == 2
    assert "refusing to overwrite" in error_line(capsys)
    assert png.read_bytes() == b"keep me"


def test_figure_into_a_missing_directory(log, tmp_path, capsys):
    assert figure(log, tmp_path / "no" / "a.png") == 2
    assert "does not exist" in error_line(capsys)


def test_figure_times_must_be_finite(log, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        figure(log, tmp_path / "a.png", "--times", "nan")
    assert info.value.code == 2
    assert "--times" in capsys.readouterr().err
    assert not (tmp_path / "a.png").exists()


@pytest.mark.parametrize("times, bad", [(["0.1", "99"], "99"), (["0.5", "0.2"], "0.5")])
def test_figure_times_outside_the_log_are_refused(log, tmp_path, capsys, times, bad):
    """A time is drawn at its nearest sample; one after the 0.3 s log by more than a sample's
    spacing (10 ms) is not in it: exit 2, one line, no picture (it drew the last sample,
    labelled with that sample's time)."""
    png = tmp_path / "f.png"
    assert figure(log, png, "--times", *times) == 2
    line = error_line(capsys)
    assert f"--times: {bad} s is outside the log (t = 0..0.3 s)" in line, line
    assert not png.exists()
    assert figure(log, png, "--times", "0.1", "0.305") == 0       # within a sample of the end


def test_figure_of_a_log_without_a_scene(tmp_path, capsys):
    path = tmp_path / "noscene.mcap"
    with open(path, "wb") as fh:
        writer = McapWriter(fh)
        writer.start(profile="ros2", library="test")
        writer.add_metadata("rod_sim", {"model": "reduced"})
        writer.finish()
    assert figure(path, tmp_path / "a.png") == 2
    assert "holds no scene" in error_line(capsys)
    assert not (tmp_path / "a.png").exists()


def test_figure_of_a_log_whose_scene_does_not_match(tmp_path, capsys):
    scene, other = scene_from_yaml_text(SCENE), scene_from_yaml_text(OTHER)
    path = tmp_path / "mismatch.mcap"
    meta = {"scene": scene_to_yaml(other), "model": "reduced", "integrator": "x"}
    with LogWriter(path, metadata=meta) as writer:
        sim = Simulator(make_model("reduced", scene))
        writer.write_snapshot(sim.snapshot(), scene)
    assert figure(path, tmp_path / "a.png") == 2
    assert "has 3 rods but the scene" in error_line(capsys)


def test_figure_without_matplotlib(log, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)      # import matplotlib fails
    assert figure(log, tmp_path / "a.png") == 2
    assert "rod_sim[plot]" in error_line(capsys)


def test_compare_without_matplotlib_prints_its_verdict(log, tmp_path, capsys, monkeypatch):
    """The same exit status and verdict line as the run without --plot, and one line on
    stderr instead of the plot."""
    expected_status = cli.main(["compare", str(log)])
    expected = [line for line in capsys.readouterr().out.splitlines()
                if line.startswith(("PASS", "FAIL"))]
    assert len(expected) == 1
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)
    status = cli.main(["compare", str(log), "--plot", str(tmp_path / "c.png")])
    out, err = capsys.readouterr()
    assert status == expected_status
    assert [line for line in out.splitlines() if line.startswith(("PASS", "FAIL"))] == expected
    assert "rod_sim[plot]" in err and "Traceback" not in err
    assert not (tmp_path / "c.png").exists()


def yaml_bomb() -> str:
    """A scene whose rods.length is a mapping of nested aliases: 9**9 strings if expanded."""
    levels = ["a: &a [" + ", ".join(["lol"] * 9) + "]"]
    for prev, name in zip("abcdefgh", "bcdefghi"):
        levels.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 9) + "]")
    return ("rods: {count: 2, mass_per_length: 1, bending_stiffness: 1, length: {"
            + ", ".join(levels) + "}}\nnodes: {mass: 1}\nhinges: {stiffness: 1, damping: 1}\n")


@pytest.mark.timing
@pytest.mark.parametrize("command", ["deployment-figure", "compare"])
def test_a_yaml_bomb_in_the_log_metadata_is_quoted_briefly(tmp_path, capsys, command):
    import time
    scene = scene_from_yaml_text(SCENE)
    path = tmp_path / "bomb.mcap"
    with LogWriter(path, metadata={"scene": yaml_bomb(), "model": "reduced",
                                   "integrator": "x"}) as writer:
        writer.write_snapshot(Simulator(make_model("reduced", scene)).snapshot(), scene)
    started = time.process_time()          # CPU time: not stretched by other processes
    args = [path, tmp_path / "a.png"] if command == "deployment-figure" else [path]
    assert cli.main([command, *map(str, args)]) == 2
    line = error_line(capsys)
    assert time.process_time() - started < 10.0
    # refused either by the metadata guard (expansion counted before anything walks it) or
    # by the scene validation naming the key; never a repr() of the whole value
    assert ("YAML nodes" in line or "rods.length" in line) and len(line) < 400, line


def test_a_long_chains_figure_stays_readable(tmp_path, capsys, monkeypatch):
    """A 32-rod chain: the hinge panel drew 32 lines with a 32-column legend (1200 entries
    over the plot for a 1200-rod scene, 15 s to draw). Now the 10 hinges of the largest
    range (as recomputed here from the logged angles) are drawn one by one, the rest as one
    min..max band; the end time is one snapshot, not two."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.figure
    import numpy as np

    from rod_sim.io.series import read_rod_states

    scene = Path(__file__).resolve().parents[1] / "config" / "bench" / "chain_n32.yaml"
    log = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(scene), "--t-end", "0.3", "--out", str(log)]) == 0
    saved = []
    savefig = matplotlib.figure.Figure.savefig
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda fig, *a, **k: (saved.append(fig), savefig(fig, *a, **k))[1])
    assert figure(log, tmp_path / "a.png") == 0
    chain_ax, hinge_ax = saved[0].axes[:2]
    snapshots = [ln for ln in chain_ax.get_lines() if ln.get_label().startswith("t = ")]
    assert len(snapshots) == 8 and len({ln.get_label() for ln in snapshots}) == 8
    assert all(ln.get_marker() == "o" for ln in snapshots)         # nodes marked up to 50
    _, phi, _ = read_rod_states(log)
    theta = np.diff(phi, prepend=0.0, axis=1)            # hinge angles of a fixed-base chain
    ranges = theta.max(axis=0) - theta.min(axis=0)
    expected = sorted(np.argsort(-ranges, kind="stable")[:10])
    labels = [ln.get_label() for ln in hinge_ax.get_lines()]
    assert labels == [f"hinge {h}" for h in expected]
    legend = hinge_ax.get_legend()
    assert len(legend.get_texts()) == 11 and "the 10 hinges of the largest range" in \
        legend.get_title().get_text()
    assert "all 32 hinges (min .. max)" in [t.get_text() for t in legend.get_texts()]


def test_the_figure_checks_its_log_once(log, tmp_path, monkeypatch):
    """deployment-figure opens its log four times (scene, states, events, base); the
    integrity pass (every record and CRC) ran each time. Inside the command it runs once;
    outside such a command every open checks the file again."""
    from rod_sim.io import log_reader

    calls = []
    check = log_reader.LogReader._check_data_section

    def counted(self):
        calls.append(self.path)
        return check(self)

    monkeypatch.setattr(log_reader.LogReader, "_check_data_section", counted)
    assert figure(log, tmp_path / "a.png") == 0
    assert calls == [log]
    calls.clear()
    for _ in range(2):
        log_reader.LogReader(log).close()
    assert calls == [log, log]
