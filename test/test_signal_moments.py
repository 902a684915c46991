"""Issue 27, item 2: Ctrl-C and SIGTERM at any moment, for every command. Each command is sent
SIGINT or SIGTERM at seeded random moments from 0.05 s to 3 s after it starts (so during the
interpreter's and the command table's imports, argument parsing, kernel loading, the work and
the writing of its output), as the console script ``rod-sim`` runs it. It must end within
1 s of the signal with status 130 (SIGINT) or 143 (SIGTERM) and one line, ``rod-sim CMD:
interrupted`` (``(SIGTERM)``), or have finished before it; its output is absent or whole
(checked with readers that are not rod_sim's: the mcap library, the PNG trailer, the XML
parser). Before this, SIGTERM during the imports printed a traceback from signals.py and
Ctrl-C to ``compare --plot`` was ignored in 2 of 11 tries (PNG written, exit 0)."""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader

from procs import terminal_signals
from ros_domains import next_domain  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"
DEPLOYMENT = ROOT / "config" / "deployment.yaml"
LAUNCH = "import sys; from rod_sim.tools.launch import main; sys.exit(main())"   # as bin/rod-sim
SEED = int(os.environ.get("ROD_SIM_SIGNAL_SEED", "27"))
TRIALS = 3                              # per command; 10 commands
EARLY_S = 0.5
"""[s] a signal sent this soon may still meet the interpreter's own start-up (before
rod_sim.tools.launch's first line: 0.13-0.14 s was seen under load), where Python's defaults
apply; the later moments (most of the seeded 0.05-3 s) check rod_sim's handling."""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    for scene, log, t_end in ((PAPER, "paper.mcap", "20"), (DEPLOYMENT, "deploy.mcap", "2")):
        done = subprocess.run([sys.executable, "-c", LAUNCH, "simulate", str(scene), "--t-end",
                               t_end, "--rate", "1000", "--out", str(d / log)],
                              capture_output=True, text=True, cwd=ROOT, timeout=300)
        assert done.returncode == 0, done.stderr
    data = (d / "paper.mcap").read_bytes()
    (d / "cut.mcap").write_bytes(data[:len(data) * 2 // 3])       # a writer killed mid-run
    spec = {"name": "sig", "scene": str(PAPER), "models": ["reduced"], "t_end": 0.5,
            "rate": 50, "parameters": {"hinges.stiffness": {"linspace": [50.0, 150.0, 40]}}}
    (d / "sweep.yaml").write_text(yaml.safe_dump(spec))
    return d


def shown(what: str, proc, err: str) -> str:
    """A failed trial's message: the moment, the status and the whole stderr (pytest cuts a
    tuple's repr, which hid where a traceback came from)."""
    return f"{what}: status {proc.returncode}, stderr:\n{err}"


def commands(d: Path, out: Path) -> dict[str, tuple[list[str], Path | None]]:
    """name -> (arguments, the output file it writes or None)."""
    return {
        "simulate": (["simulate", str(PAPER), "--t-end", "30", "--rate", "1000", "--out",
                      str(out / "run.mcap")], out / "run.mcap"),
        "compare": (["compare", str(d / "paper.mcap"), "--plot", str(out / "c.png")],
                    out / "c.png"),
        "urdf": (["urdf", str(PAPER), "--out", str(out / "chain.urdf")], out / "chain.urdf"),
        "table1": (["table1"], None),
        "advise": (["advise", str(PAPER), "--tolerance", "1e-3", "--t-end", "0.5"], None),
        "sweep": (["sweep", str(d / "sweep.yaml"), "--out", str(out / "s.csv"), "--workers",
                   "1"], out / "s.csv"),
        "deployment-figure": (["deployment-figure", str(d / "deploy.mcap"),
                               str(out / "d.png")], out / "d.png"),
        "repair": (["repair", str(d / "cut.mcap"), "--out", str(out / "r.mcap")],
                   out / "r.mcap"),
        "bench": (["bench", "--help"], None),
        "ctl": (["ctl", "--timeout", "5", "pause"], None),
    }


def whole(path: Path) -> bool:
    """Whether the output ``path`` is complete, by a reader that is not rod_sim's."""
    data = path.read_bytes()
    if path.suffix == ".png":
        return data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(b"IEND\xaeB`\x82")
    if path.suffix == ".urdf":
        return ET.fromstring(data).tag == "robot"
    if path.suffix == ".csv":
        return data.endswith(b"\n") and data.count(b"\n") >= 1
    with open(path, "rb") as f:                            # .mcap: summary present and read
        return make_reader(f).get_summary() is not None


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("name", ["simulate", "compare", "urdf", "table1", "advise", "sweep",
                                  "deployment-figure", "repair", "bench", "ctl"])
def test_a_signal_at_a_random_moment_ends_the_command_cleanly(inputs, tmp_path, name):
    rng = random.Random(f"{SEED}-{name}")
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(next_domain()))
    for trial in range(TRIALS):
        out = tmp_path / str(trial)
        out.mkdir()
        args, output = commands(inputs, out)[name]
        sig = rng.choice([signal.SIGINT, signal.SIGTERM])
        delay = rng.uniform(0.05, 3.0)
        what = f"{name} {sig.name} at {delay:.2f} s (seed {SEED}, trial {trial})"
        proc = subprocess.Popen([sys.executable, "-c", LAUNCH, *args], cwd=out, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=terminal_signals)
        time.sleep(delay)
        if proc.poll() is not None:                     # finished before the signal
            _, err = proc.communicate()
            assert proc.returncode in (0, 1) and "Traceback" not in err, shown(what, proc, err)
            continue
        sent = time.monotonic()
        proc.send_signal(sig)
        try:
            printed, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            pytest.fail(f"{what}: still running 30 s after the signal")
        took = time.monotonic() - sent
        lines = err.strip().splitlines()
        if delay < EARLY_S and (output is None or not output.exists()):
            early = (proc.returncode == -sig and not err.strip() if sig == signal.SIGTERM
                     else proc.returncode in (1, -sig) and "KeyboardInterrupt" in err
                     and "rod_sim" not in err)
            if early:
                # the signal came during the interpreter's own start-up, before the first
                # line of rod_sim.tools.launch (which handles both from there on): Python's
                # defaults end it, nothing was written (seen at 0.13-0.14 s under load)
                continue
        if proc.returncode in (0, 1) and (not lines or "interrupted" not in lines[-1]):
            # it ended just as the signal came (its own last line, no traceback)
            assert "Traceback" not in err and took < 0.1, shown(what, proc, err)
        elif proc.returncode == -sig and "Traceback" not in err and took < 0.1 and (
                printed.strip() if output is None else output.exists()):
            # the command had returned: the signal came in the interpreter's last teardown,
            # after Python restored the default dispositions (seen once for table1 in a full
            # run: killed by SIGTERM 0 s after it, its table already printed)
            pass
        else:
            assert proc.returncode == 128 + sig, shown(what, proc, err)
            assert "Traceback" not in err, shown(what, proc, err)
            assert lines and lines[-1].startswith(f"rod-sim {name}: interrupted"), \
                shown(what, proc, err)
            assert lines[-1].endswith("(SIGTERM)") or "(SIGTERM)" not in lines[-1] and \
                sig == signal.SIGINT or "(SIGTERM)" in lines[-1] and sig == signal.SIGTERM
            assert took < 1.0, f"{what}: ended {took:.2f} s after the signal: {err}"
        if output is not None and output.exists():
            assert whole(output), f"{what}: {output.name} left incomplete"
        leftovers = [p.name for p in out.iterdir() if p != output]
        assert not leftovers, (what, leftovers)
