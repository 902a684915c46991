"""Progress lines of long commands (rod_sim.app.progress) and what could hide them.

``rod-sim compare`` of a long or stiff log ran for minutes without a word (the brief: every
start shows progress after 2 s); worse, while it decoded the log it swapped ``sys.stderr`` for a
``StringIO`` around every message (to drop a print of mcap_ros2's schema parser), so a line any
other thread wrote meanwhile (a compile notice, a progress line) was lost: with a 1200-rod log
the first progress line came at 12 s instead of 2 s. These tests fail on that code.
"""
from __future__ import annotations

import json
import math
import re
import sys
import threading
import time
from pathlib import Path

import pytest

from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"
CHAIN32 = ROOT / "config" / "bench" / "chain_n32.yaml"


def test_progress_writes_each_line_whole_until_its_block_ends():
    from rod_sim.app.progress import Progress

    calls = []
    enough = threading.Event()

    class Stream:
        def __init__(self):
            self.writes = []

        def write(self, text):
            self.writes.append(text)

        def flush(self):
            pass

    def line(elapsed):
        calls.append(elapsed)
        if len(calls) >= 3:
            enough.set()
        return None if len(calls) == 2 else f"line {len(calls)}"

    stream = Stream()
    with Progress(line, 0.0, 0.01, stream=stream):
        assert enough.wait(30)
    after = len(calls)
    threading.Event().wait(0.1)
    assert len(calls) <= after + 1                 # at most the one being made at the end
    # the second call returned None: no line; every write is one whole line
    assert stream.writes[:2] == ["line 1\n", "line 3\n"]
    assert all(w.endswith("\n") and w.count("\n") == 1 for w in stream.writes)
    assert calls == sorted(calls) and calls[0] >= 0.0


def test_pace_uses_the_simulated_time_then_the_steps(monkeypatch):
    from rod_sim.app import progress

    clock = iter([100.0, 101.0, 103.0, 104.0])
    monkeypatch.setattr(progress.time, "perf_counter", lambda: next(clock))
    pace = progress.Pace(10.0, 0.0, 0)                     # wall 100
    assert pace.left(2.0, 50) == pytest.approx(4.0)          # wall 101: 2 s in 1 s, 8 to go
    # wall 103: the time stood still (one long stretch); 400 steps of 1e-3 s in 2 s
    assert pace.left(2.0, 450, 1e-3) == pytest.approx(8.0 / 1e-3 / 200.0)
    assert math.isinf(pace.left(2.0, 450, 1e-3))             # wall 104: nothing moved


def test_a_long_run_reports_the_time_its_integration_has_reached(monkeypatch):
    """Inside one long ``Simulator.run`` (simulate integrates half a second of samples at a
    time) the simulator's own time moves only at the end; the progress line's time is the
    integration's, after each bounded call of the compiled integrator. It stood at 0 for the
    first 80 s of a stiff 2 s run, and the pace then read ~30 s left of ~4 min."""
    from rod_sim.api import Simulator, load_scene, make_integrator, make_model
    from rod_sim.app import progress
    from rod_sim.core import integrators

    monkeypatch.setattr(integrators, "MIN_CALL_RHS", 1)
    monkeypatch.setattr(integrators, "CALL_WORK", 16 * 50)    # ~50 rhs a call (state size 16)
    sim = Simulator(make_model("reduced", load_scene(PAPER)), make_integrator())
    cls = type(sim.integrator)
    advance = cls.advance
    calls = []          # (sim.t and the progress reading as a call begins, the call's end time)

    def watched(self, carry, *args):
        begun = (sim.t, progress.run_state(sim)[0])
        out = advance(self, carry, *args)
        calls.append((*begun, out.t))
        return out

    monkeypatch.setattr(cls, "advance", watched)
    sim.run(0.5, 100.0)
    assert len(calls) > 5
    assert all(t_sim == 0.0 for t_sim, _, _ in calls)          # the simulator's time waits
    # each call begins where the progress line says the integration is: the last call's end
    assert [read for _, read, _ in calls[1:]] == [end for _, _, end in calls[:-1]]
    assert 0.0 < calls[1][1] < calls[-1][1] < 0.5
    assert progress.run_state(sim)[0] == 0.5


def test_decoding_a_log_leaves_stderr_to_the_other_threads(tmp_path, monkeypatch):
    """Every message of the log is read with ``sys.stderr`` untouched."""
    from rod_sim.io import log_source
    from rod_sim.io.log_source import read_log

    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(PAPER), "--t-end", "0.05", "--out", str(out)]) == 0
    original = sys.stderr
    seen = []
    messages = log_source.LogStream._messages

    def watched(self):
        for item in messages(self):
            seen.append(sys.stderr is original)
            yield item

    monkeypatch.setattr(log_source.LogStream, "_messages", watched)
    with read_log(out) as log:
        groups = sum(1 for _ in log.groups())
    assert groups == 6 and len(seen) > 6 and all(seen)


def test_the_schema_parsers_print_is_dropped_and_its_error_raised(capsys):
    """mcap_ros2's vendored .msg parser prints before it raises; that print is dropped (the
    readers report the error as one line of their own), without touching sys.stderr."""
    import rod_sim.io.log_reader  # noqa: F401  (installs the parser's print)
    from mcap.records import Schema
    from mcap_ros2.decoder import DecoderFactory

    schema = Schema(id=1, name="bad_msgs/msg/Bad", encoding="ros2msg", data=b"float64\n")
    with pytest.raises(Exception):
        DecoderFactory().decoder_for("cdr", schema)
    assert capsys.readouterr().err == ""


def test_a_compare_says_how_far_its_reruns_are(tmp_path, capsys, monkeypatch):
    """With the first line due at once, a compare prints it before its first window is
    compared (the window waits for it): the re-runs' time out of the log's end, after how
    long, their integrator and which runs; the report on stdout is whole."""
    from rod_sim.app import progress
    from rod_sim.compare import command, comparison

    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(PAPER), "--t-end", "0.3", "--out", str(out)]) == 0
    capsys.readouterr()
    written = threading.Event()
    write_line = progress.write_line

    def noted(text, stream):
        write_line(text, stream)
        if text.startswith("rod-sim compare: full-model"):     # not the stiffness probe's
            written.set()

    window = comparison._Comparison.window

    def after_a_line(self, t_cut):
        assert written.wait(60)
        return window(self, t_cut)

    monkeypatch.setattr(command, "PROGRESS_FIRST_S", 0.0)
    monkeypatch.setattr(progress, "write_line", noted)
    monkeypatch.setattr(comparison._Comparison, "window", after_a_line)
    assert cli.main(["compare", str(out)]) == 0
    res = capsys.readouterr()
    lines = [ln for ln in res.err.splitlines() if ln.startswith("rod-sim compare: full-model")]
    assert lines, res.err
    pattern = (r"rod-sim compare: full-model re-runs at t = ([0-9.e+-]+) of 0.3 s after \d+ s "
               r"\(dop853-jit: reference rtol 1e-10, check 1e-12, chaos twin; the reference at \d+ steps"
               r"( of ~[0-9.e+-]+ s)?; (~\d+ (s|min) more at this pace|no estimate yet)\)$")
    for ln in lines:
        m = re.match(pattern, ln)
        assert m, ln
        assert 0.0 <= float(m.group(1)) <= 0.3
    assert res.out.splitlines()[0].startswith("log: ") and "PASS" in res.out


def test_a_long_chains_table_lists_its_worst_rods(tmp_path, capsys):
    """n = 32: the text table lists the 20 rods of the largest phi error (per the JSON
    report's per-rod maxima), in rod order, and says so; every line fits 100 columns."""
    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(CHAIN32), "--t-end", "0.2", "--out", str(out)]) == 0
    capsys.readouterr()
    cli.main(["compare", str(out), "--json"])
    report = json.loads(capsys.readouterr().out)
    per_rod = {row["rod"]: row["phi"] for row in report["per_rod"]}
    assert len(per_rod) == 32
    cli.main(["compare", str(out)])
    text = capsys.readouterr().out
    assert "the 20 rods of the largest phi error of 32 (--json has every rod):" in " ".join(
        text.split())
    rows = [ln for ln in text.splitlines() if re.match(r"^\s*\d+\s+[0-9.]+e[+-]\d+", ln)]
    shown = [int(ln.split()[0]) for ln in rows]
    assert shown == sorted(shown) and len(shown) == 20
    worst = sorted(per_rod, key=lambda k: -per_rod[k])[:20]
    assert set(shown) == set(worst)
    for k in shown:
        assert float(rows[shown.index(k)].split()[1]) == pytest.approx(per_rod[k], rel=1e-3)
    assert max(len(ln) for ln in text.splitlines()) <= 100


def test_an_advise_says_which_run_is_under_way(capsys, monkeypatch):
    """advise runs 12 simulations (the reference, its check, 10 candidates) and said nothing
    for minutes on a long chain: its lines name the run under way, its time and steps and
    the runs done (the first runs wait until a line has described them)."""
    from rod_sim.app import progress
    from rod_sim.tools import advise

    lines = []
    write_line = progress.write_line

    def noted(text, stream):
        write_line(text, stream)
        lines.append(text)

    running = advise.Watch.running

    def wait_described(self, label, sim):
        # the stiffness probe and the reference's check wait until a line has described them
        running(self, label, sim)
        if "probe" in label or "check" in label:
            deadline = time.monotonic() + 60
            while not any(f"now {label}:" in ln for ln in lines):
                assert time.monotonic() < deadline
                time.sleep(0.002)

    monkeypatch.setattr(advise, "PROGRESS_FIRST_S", 0.0)
    monkeypatch.setattr(advise, "PROGRESS_EVERY_S", 0.01)
    monkeypatch.setattr(progress, "write_line", noted)
    monkeypatch.setattr(advise.Watch, "running", wait_described)
    assert cli.main(["advise", str(PAPER), "--tolerance", "0.01", "--t-end", "0.05",
                     "--repeats", "1"]) == 0
    res = capsys.readouterr()
    assert "recommended:" in res.out and "rod-sim advise" not in res.out
    pattern = (r"rod-sim advise: (?P<done>\d+) of 12 runs done after \d+ s; now (?P<run>a probe "
               r"of the full model's stiffness \(dop853-jit, 1000 steps at most\)|the "
               r"full-model reference's check \(dop853-jit rtol 1e-10\)|the full-model "
               r"reference \(dop853-jit rtol 1e-11\)|candidate (rigid|reduced|full) dop853-jit "
               r"rtol 1e-\d+): t = (?P<t>[0-9.e+-]+) of 0.05 s, \d+ steps( of ~[0-9.e+-]+ s)? "
               r"\((no estimate yet|~\d+ (s|min) more for it at this pace)\)$")
    described_lines = [ln for ln in lines if "; now " in ln]
    assert described_lines and all(re.match(pattern, ln) for ln in described_lines), lines
    first = re.match(pattern, described_lines[0])
    assert first.group("done") == "0" and "probe" in first.group("run")
    check = next(re.match(pattern, ln) for ln in described_lines if "check" in ln)
    assert check.group("done") == "0"
    done = [int(re.match(r"rod-sim advise: (\d+) of 12", ln).group(1)) for ln in lines]
    assert done == sorted(done) and max(done) <= 12
    assert all(0.0 <= float(re.match(pattern, ln).group("t")) <= 0.05 for ln in described_lines)


def test_a_long_chains_plot_draws_its_worst_rods(tmp_path, capsys, monkeypatch):
    """n = 32: the plot draws the 12 rods of the largest phi error (per the JSON report),
    each solid (log) and dashed (reference), instead of 32 of each in a 32-entry legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.figure

    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(CHAIN32), "--t-end", "0.2", "--out", str(out)]) == 0
    capsys.readouterr()
    saved = []
    savefig = matplotlib.figure.Figure.savefig
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda fig, *a, **k: (saved.append(fig), savefig(fig, *a, **k))[1])
    assert cli.main(["compare", str(out), "--json", "--plot", str(tmp_path / "c.png")]) == 0
    report = json.loads(capsys.readouterr().out)
    per_rod = {row["rod"]: row["phi"] for row in report["per_rod"]}
    worst = sorted(sorted(per_rod, key=lambda k: -per_rod[k])[:12])
    ax = saved[0].axes[0]
    labels = [ln.get_label() for ln in ax.get_lines() if not ln.get_label().startswith("_")]
    assert labels == [f"rod {k}" for k in worst]
    assert len(ax.get_lines()) == 24 and "the 12 of 32 rods of the largest phi error" in \
        ax.get_title()


def test_opening_a_log_says_which_file_and_how_far_its_check_is(tmp_path):
    """A log's integrity pass (every record and its CRC; ~80 s for a 1.2 GB log) was silent:
    the reader now says which file it checks and how far (CHECKING, read by the commands'
    progress thread) and clears it when done; the line names the file and the megabytes."""
    from rod_sim.app import progress
    from rod_sim.io import log_reader

    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(PAPER), "--t-end", "0.5", "--out", str(out)]) == 0
    seen = []
    records = log_reader.LogReader._records

    def watched(self):
        for item in records(self):
            c = log_reader.CHECKING
            seen.append((c.path, c.done, c.size))
            yield item

    log_reader.LogReader._records = watched
    try:
        log_reader.LogReader(out).close()
    finally:
        log_reader.LogReader._records = records
    size = out.stat().st_size
    assert seen and all(p == str(out) for p, _, _ in seen)
    done = [d for _, d, _ in seen]
    assert done == sorted(done) and 0 < seen[0][2] <= size and done[-1] < seen[0][2]
    assert log_reader.CHECKING.path == ""

    lines = []

    class Stream:
        def write(self, text):
            lines.append(text)

        def flush(self):
            pass

    c = log_reader.CHECKING
    got = threading.Event()
    watch = progress.log_check_progress("rod-sim compare")
    watch.first_s = watch.every_s = 0.01
    watch.stream = Stream()
    write = watch.line

    def line(elapsed):
        text = write(elapsed)
        if text:
            got.set()
        return text

    watch.line = line
    try:
        c.path, c.done, c.size = "big.mcap", 340_000_000, 1_230_000_000
        c.since = progress.time.monotonic() - 12.0
        with watch:
            assert got.wait(30)
    finally:
        c.path = ""
    assert re.fullmatch(r"rod-sim compare: checking big\.mcap \(every record and its CRC\): "
                        r"340 of 1230 MB after \d+ s\n", lines[0]), lines
