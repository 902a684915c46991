"""SIGTERM on the command line tools is handled like Ctrl-C (issue 19, item 2): ``simulate``
closes its log with the summary, ``compare`` and ``sweep`` stop cleanly (sweep writes the rows
finished so far), exit status 143 (130 for SIGINT), one line on stderr, no traceback.
(``replay`` and the node: test_replay.py, test_node_process.py.)"""
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from procs import terminal_signals  # noqa: E402
import yaml
from mcap.reader import make_reader

from rod_sim.io.log_reader import LogReader

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"


def rod_sim_proc(*args, cwd=None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "rod_sim.tools.cli", *map(str, args)],
                            cwd=cwd or ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=terminal_signals)


def wait_for_size(proc, path: Path, size: int, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not (path.exists() and path.stat().st_size > size):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the log did not grow"
        time.sleep(0.05)


def terminate(proc, timeout: float = 30.0) -> tuple[int, str]:
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=timeout)
    return proc.returncode, err


@pytest.mark.slow
@pytest.mark.timing
def test_sigterm_closes_the_simulate_log_with_its_summary(tmp_path):
    log = tmp_path / "long.mcap"
    proc = rod_sim_proc("simulate", PAPER, "--t-end", 600, "--rate", 1000, "--out", log)
    wait_for_size(proc, log, 1_000_000)            # several complete chunks written
    status, err = terminate(proc)
    assert status == 143, err
    assert err.strip().splitlines()[-1] == "rod-sim simulate: interrupted (SIGTERM)"
    assert "Traceback" not in err
    with LogReader(log) as reader:
        assert reader.complete and not reader.truncated
    with open(log, "rb") as f:                     # the mcap library accepts it as it is
        summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        count = sum(1 for _ in make_reader(f).iter_messages())
    assert count == summary.statistics.message_count


@pytest.mark.slow
@pytest.mark.timing
def test_sigterm_stops_compare_cleanly(tmp_path):
    """SIGTERM once compare says it is re-running the log (its first progress line, 2 s into
    the comparison of a 60 s log, which takes ~10 s more on an idle machine; a 10 s log's
    comparison came to take under 2 s, so CI saw no progress line): one line, 143."""
    log = tmp_path / "c.mcap"
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(PAPER),
                           "--t-end", "60", "--out", str(log)],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    proc = rod_sim_proc("compare", log)
    seen = []
    for line in proc.stderr:                       # (a compile notice may come first)
        seen.append(line)
        if line.startswith("rod-sim compare: full-model re-runs at t = "):
            break                                  # inside the comparison
    else:
        raise AssertionError("".join(seen))
    assert proc.poll() is None, proc.communicate()
    status, err = terminate(proc)
    assert status == 143, err
    assert err.strip().splitlines()[-1] == "rod-sim compare: interrupted (SIGTERM)"


@pytest.mark.slow
@pytest.mark.timing
def test_sigterm_stops_a_sweep_and_writes_the_finished_rows(tmp_path):
    spec = {"name": "term", "scene": str(PAPER), "models": ["full"], "t_end": 2.0,
            "rtol": 1e-10, "rate": 50,
            "parameters": {"hinges.stiffness": {"linspace": [50.0, 150.0, 400]}}}
    path = tmp_path / "term.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = tmp_path / "partial.csv"
    proc = rod_sim_proc("sweep", path, "--out", out, "--workers", 1, cwd=tmp_path)
    assert "400 runs" in proc.stderr.readline()
    time.sleep(5.0)
    started = time.monotonic()
    status, err = terminate(proc)
    assert time.monotonic() - started < 30
    assert status == 143, err
    assert "interrupted" in err and "Traceback" not in err
    assert out.exists()


def test_an_interrupt_raised_inside_a_compiled_call_is_still_an_interrupt(monkeypatch, capsys):
    """A signal handler's exception that fires inside a numba call (e.g. while it loads a
    cached kernel) comes back as SystemError caused by it: still exit 130, one line (seen
    under load: SIGTERM during compare gave a SystemError traceback and exit 1)."""
    from rod_sim.tools import cli

    def compare_run(args):
        try:
            raise cli.Terminated
        except KeyboardInterrupt as stop:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") \
                from stop

    monkeypatch.setattr(cli.plugin_modules()["compare"], "run", compare_run)
    assert cli.main(["compare", "x.mcap"]) == 143
    assert capsys.readouterr().err.strip() == "rod-sim compare: interrupted (SIGTERM)"


@pytest.mark.parametrize("where", ["before", "inside"])
def test_an_interrupt_raised_inside_a_class_creation_is_still_an_interrupt(monkeypatch, capsys,
                                                                          where):
    """A signal handler's exception that fires inside a descriptor's ``__set_name__`` while
    a class is made (numba's import, ``BaseContext``'s cached properties) comes back as
    "RuntimeError: Error calling __set_name__ ..." caused by it: still exit 143, one line.
    CI: SIGTERM 0.56 s into ``simulate`` printed that traceback and exited 1 (it came in the
    compile watch's import of numba, before the command ran: ``before``); inside the command
    (``inside``) the RuntimeError was reported as the command's error."""
    from rod_sim.app import common
    from rod_sim.tools import cli

    class Interrupting:
        def __set_name__(self, owner, name):
            raise cli.Terminated

    def make_class(*args):
        type("Context", (), {"cached": Interrupting()})

    if where == "before":
        monkeypatch.setattr(common, "watch_compiles", make_class)
    else:
        monkeypatch.setattr(cli.plugin_modules()["compare"], "run", make_class)
    assert cli.main(["compare", "x.mcap"]) == 143
    assert capsys.readouterr().err.strip() == "rod-sim compare: interrupted (SIGTERM)"


@pytest.mark.timing
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_in_the_middle_of_a_log_write_waits_for_its_end(tmp_path, monkeypatch, capsys,
                                                                 sig):
    """The signal arrives inside a write of the log: between a chunk's frame and its bytes
    in the pipe to the writer process (no shared ring here, as under ``ulimit -f``; the 40th
    pipe write). It is raised once the sample is written, so the log closes with its summary
    and holds whole samples only; raised there, the child would take the next frame for the
    chunk's bytes. (The first full `make test` hit this by chance: SIGTERM inside a chunk
    write left a log that ended in a broken record, no DataEnd.)"""
    import os

    from rod_sim.io import log_process
    from rod_sim.io.log_process import ProcessSink
    from rod_sim.tools import cli

    for s in (signal.SIGTERM, signal.SIGINT):
        monkeypatch.setattr(cli, "_restore_" + s.name, signal.getsignal(s), raising=False)
    signal.signal(signal.SIGINT, signal.default_int_handler)    # as Python starts a command
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    real = ProcessSink._write_all
    calls = []

    def write_all(self, data):
        calls.append(len(data))
        if len(calls) == 40:        # frames: start, metadata, then each chunk's frame + bytes
            os.kill(os.getpid(), sig)         # the handler runs here, before the bytes go out
        return real(self, data)

    monkeypatch.setattr(log_process, "_shared_ring", lambda size: (-1, None))
    monkeypatch.setattr(ProcessSink, "_write_all", write_all)
    log = tmp_path / "sig.mcap"
    try:
        code = cli.main(["simulate", str(PAPER), "--t-end", "20", "--rate", "1000",
                         "--markers-rate", "0", "--out", str(log)])    # every topic each sample
    finally:
        for s in (signal.SIGTERM, signal.SIGINT):
            signal.signal(s, getattr(cli, "_restore_" + s.name))
    assert len(calls) > 40 and code == 128 + sig
    assert capsys.readouterr().err.strip().splitlines()[-1].startswith(
        "rod-sim simulate: interrupted")
    with LogReader(log) as reader:
        assert reader.complete and not reader.damaged
        counts, times = {}, {}
        for topic, t_ns, _ in reader.raw_messages():
            counts[topic] = counts.get(topic, 0) + 1
            times.setdefault(topic, []).append(t_ns)
    assert counts.pop("/scene") == 1                     # latched, written once at the start
    assert len(set(counts.values())) == 1, counts        # whole samples: every topic alike
    for topic, t_ns in times.items():                    # and none lost: no chunk dropped
        if topic != "/scene":
            assert t_ns == [k * 1_000_000 for k in range(len(t_ns))], topic


def test_an_interruption_python_cannot_raise_is_not_reported_as_ignored():
    """A signal's KeyboardInterrupt raised inside a weakref callback of the import system
    (seen: "Exception ignored in: <function _get_module_lock.<locals>.cb ...>" with a
    traceback before `rod-sim advise: interrupted`) is not reported, nor is the fallout of the
    interruption in a finaliser (CI: llvmlite's ObjectRef.__del__, AttributeError, after a
    SIGTERM in simulate): the command's one line says it. With no signal received, every
    unraisable exception goes to the hook that was there before."""
    import sys
    import types

    from rod_sim.app import signals

    before = sys.unraisablehook
    seen = []
    sys.unraisablehook = lambda u: seen.append(type(u.exc_value).__name__)
    signals.reset("rod-sim test")
    try:
        signals.handle_sigterm()
        signals.handle_sigterm()            # twice: still one hook, not a chain to itself

        def unraisable(exc):
            return types.SimpleNamespace(exc_type=type(exc), exc_value=exc,
                                         exc_traceback=None, err_msg="Exception ignored in",
                                         object=None)

        sys.unraisablehook(unraisable(KeyboardInterrupt()))   # no signal yet: reported
        sys.unraisablehook(unraisable(AttributeError("before")))
        signals._received.append(signal.SIGINT)
        sys.unraisablehook(unraisable(KeyboardInterrupt()))
        sys.unraisablehook(unraisable(signals.Terminated()))
        sys.unraisablehook(unraisable(AttributeError("fallout")))
        assert seen == ["KeyboardInterrupt", "AttributeError"]
    finally:
        signals.reset()
        sys.unraisablehook = before
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)



def test_a_node_stop_quiets_the_fallout_of_its_interruption():
    """The node's stop request (rod_sim.ros.process.StopRequest) quiets unraisable exceptions
    once a stop was requested, as a command does: its interruption and the fallout in a
    finaliser of an object it cut in half; before the stop, they are reported."""
    import sys
    import types

    from rod_sim.ros.process import StopRequest

    before = sys.unraisablehook
    seen = []
    sys.unraisablehook = lambda u: seen.append(str(u.exc_value))

    def unraisable(exc):
        return types.SimpleNamespace(exc_type=type(exc), exc_value=exc, exc_traceback=None,
                                     err_msg="Exception ignored in", object=None)
    try:
        with StopRequest() as stop:
            sys.unraisablehook(unraisable(AttributeError("before")))
            stop.event.set()
            sys.unraisablehook(unraisable(AttributeError("fallout")))
            sys.unraisablehook(unraisable(KeyboardInterrupt("stop")))
        sys.unraisablehook(unraisable(AttributeError("after")))
        assert seen == ["before", "after"]
    finally:
        sys.unraisablehook = before

PRINTED_BY_C = """
import ctypes, os, signal, sys, time
from rod_sim.tools import urdf

def run(args):
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(5)
    except KeyboardInterrupt:
        # numpy's import_array() when the signal lands in its import of numpy, in a C
        # extension's initialization: PyErr_Print (sys.excepthook), then an ImportError
        ctypes.pythonapi.PyRun_SimpleString(b"raise KeyboardInterrupt")
        raise ImportError("numpy._core.multiarray failed to import") from None
    return 0

urdf.run = run
sys.argv = ["rod-sim", "urdf", sys.argv[1]]
from rod_sim.tools.launch import main
sys.exit(main())
"""


def test_an_interruption_that_c_code_prints_itself_is_one_line():
    """CI's signal-moments trial of `sweep` at 0.27 s printed a traceback from importlib's
    _find_and_load through the signal handler: numpy's import_array() macro (in C extensions'
    initialization) prints a failed import of numpy with PyErr_Print, i.e. sys.excepthook,
    then raises ImportError. A command's excepthook drops its own signal's interruption:
    the command's one line and status only (fails on the old code: a traceback first)."""
    done = subprocess.run([sys.executable, "-c", PRINTED_BY_C, str(PAPER)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stderr) == (130, "rod-sim urdf: interrupted\n")


INTERRUPTED_OPENING = """
import os, signal, sys
from rod_sim.io.log_writer import LogWriter

def signalled(self, *args, **kwargs):
    os.kill(os.getpid(), signal.SIGTERM)      # lands as the open log's first record is written
    raise AssertionError("the signal's handler did not raise")

LogWriter.write = signalled
from rod_sim.tools.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_signal_before_the_log_is_in_its_closing_block_leaves_no_log(tmp_path):
    """CI (test_signal_moments): SIGTERM landed after `simulate` had created its log file and
    before the log was in the block that closes it whole: the command ended with its status
    and line and left an incomplete file. An interrupted command now removes the outputs it
    had not finished, as its watchdog does, and says so: a log is whole or absent."""
    out = tmp_path / "run.mcap"
    done = subprocess.run([sys.executable, "-c", INTERRUPTED_OPENING, "simulate", str(PAPER),
                           "--t-end", "1", "--out", str(out)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120,
                          preexec_fn=terminal_signals)
    assert done.returncode == 143, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        f"rod-sim simulate: interrupted (SIGTERM); removed the unfinished {out}")
    assert "Traceback" not in done.stderr
    assert not out.exists()
