"""Bounded, interruptible integration (issue 19, item 1): every compiled driver returns to
Python after a bounded amount of work (``drive`` calls it again), so Ctrl-C closes the log of
a stiff run within a second or two; a collapsed step size and a Newton iteration that keeps
failing stop with one clear line instead of spinning."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core import erk, integrators, jit, kernels, radau
from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.series import read_rod_states

from procs import terminal_signals  # noqa: E402
from rod_sim.io.scene_yaml import load_scene

ROOT = Path(__file__).resolve().parents[1]
DEPLOYMENT = ROOT / "config" / "deployment.yaml"


def stiff_deployment(tmp_path: Path) -> Path:
    """The shipped deployment scene with the largest bending stiffness the validator accepts."""
    text = DEPLOYMENT.read_text().replace("bending_stiffness: 2.0e3", "bending_stiffness: 1.0e12")
    assert "1.0e12" in text
    path = tmp_path / "stiff_deployment.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("integrator", ["radau-jit", "dop853-jit", "rk4"])
def test_sigint_closes_the_log_of_a_stiff_run_within_two_seconds(tmp_path, integrator):
    out = tmp_path / "run.mcap"
    args = [sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(stiff_deployment(tmp_path)),
            "--model", "full", "--integrator", integrator, "--t-end", "0.2", "--out", str(out)]
    args += ["--step", "1e-8"] if integrator == "rk4" else ["--rtol", "1e-14"]
    proc = subprocess.Popen(args, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, preexec_fn=terminal_signals)
    try:
        deadline = time.monotonic() + 120.0            # a cold numba cache compiles first
        while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(3.0)                                # deep inside the integration
        assert proc.poll() is None, proc.stderr.read()
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{integrator}: still running 10 s after SIGINT")
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    err = proc.stderr.read()
    assert took < 2.0, f"{integrator}: exited {took:.2f} s after SIGINT"
    assert proc.returncode == 130 and "interrupted" in err, (proc.returncode, err)
    t, phi, _ = read_rod_states(out)                    # a readable log, from t = 0 on
    assert t.size >= 1 and t[0] == 0.0 and np.all(np.isfinite(phi))


def test_budget_returns_continue_the_same_integration():
    """Resuming after each budget return gives the same samples as one long call."""
    model = make_model("full", load_scene(DEPLOYMENT))
    results = {}
    for name in ("dop853-jit", "radau-jit", "rk4"):
        for work in (integrators.CALL_WORK, 10**12):
            old = integrators.CALL_WORK
            integrators.CALL_WORK = work
            try:
                integ = make_integrator(name, rtol=1e-8, step=1e-4)
                traj = Simulator(model, integ).run(0.2, 100.0)
            finally:
                integrators.CALL_WORK = old
            results[name, work] = traj.y
        small, big = results[name, integrators.CALL_WORK], results[name, 10**12]
        np.testing.assert_allclose(small, big, rtol=0, atol=1e-9, err_msg=name)


def test_collapsed_step_size_stops_with_one_line(tmp_path, monkeypatch, capsys):
    """A run whose mean step is below COLLAPSE_STEP over a whole budget call stops (exit 1,
    one line, the log kept up to there). The stiff deployment scene's dop853 steps (~2e-8 s
    at rtol 1e-12) stand in for a collapse by raising the threshold."""
    from rod_sim.tools import cli

    monkeypatch.setattr(integrators, "COLLAPSE_STEP", 1e-6)
    out = tmp_path / "run.mcap"
    started = time.monotonic()
    code = cli.main(["simulate", str(stiff_deployment(tmp_path)), "--model", "full",
                     "--integrator", "dop853-jit", "--rtol", "1e-12", "--t-end", "0.2",
                     "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 1, err
    assert time.monotonic() - started < 30.0
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "step size collapsed" in lines[0], err
    t, _, _ = read_rod_states(out)
    assert t.size >= 1 and t[0] == 0.0


@jit.njit
def nan_after_start(t, y, chain, extra, loads, held, t_side, out):
    """Kernel calling convention: finite at t = 0, non-finite at every later time, so that no
    Newton iteration of a step from t = 0 can converge."""
    for i in range(y.shape[0]):
        out[i] = np.nan if t > 0.0 else 0.0


def test_radau_gives_up_after_repeated_newton_failures():
    y0 = np.array([0.0, 1.0])
    t_out = np.array([0.0, 1.0])
    Y = np.empty((2, 2))
    stats = np.zeros(6, dtype=np.int64)
    ev = kernels.Events(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64),
                        np.zeros(0, dtype=np.int64),
                        np.empty(4), np.empty(4, dtype=np.int64), np.empty((4, 2)),
                        np.zeros(1, dtype=np.int64))
    y, t, h, status, written = radau.radau_run(
        nan_after_start,
        kernels.Problem((np.zeros(1),), (np.zeros(1),), (np.zeros(1),), np.zeros((1, 3))),
        kernels.Span(y0, 0.0, t_out, np.zeros(0)),
        kernels.Control(1e-8, 1e-8, 1e-3, np.inf, 100_000, 1 << 62),
        kernels.Output(Y, stats, ev))
    assert status == erk.STATUS_NEWTON_FAILED, status
    assert t == 0.0 and stats[2] == radau.NEWTON_FAILURES       # 30 halvings, then it stops
    assert 0.0 < h < 1e-3 / 2**29
    assert "Newton" in erk.STATUS_TEXT[status]
