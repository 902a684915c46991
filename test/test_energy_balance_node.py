"""The node and ``simulate`` judge the same energy balance: on the shipped deployment scene
(three latches) their residuals agree to integration error. The node runs in this process
with real rclpy, stepped period by period without spinning (issue 19, item 6). ROS domain ids
from ros_domains (LOCALHOST)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

import test_node_ros as base  # noqa: E402

from rod_sim.core.integrators import make_integrator  # noqa: E402
from rod_sim.core.models import make_model  # noqa: E402
from rod_sim.core.simulator import Simulator  # noqa: E402
from rod_sim.io.log_writer import LogWriter  # noqa: E402
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml  # noqa: E402
from rod_sim.tools.simulate import _LoggedRun  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

DEPLOYMENT = Path(__file__).resolve().parents[1] / "config" / "deployment.yaml"
harness = base.harness_fixture()


def simulate_balance(model: str, t_end: float, rate_hz: float, tmp_path):
    """The EnergyBalance ``rod-sim simulate`` keeps (its _LoggedRun, default integrator)."""
    scene = load_scene(DEPLOYMENT)
    sim = Simulator(make_model(model, scene), make_integrator("dop853-jit", rtol=1e-8))
    log = LogWriter(tmp_path / f"{model}.mcap", metadata={
        "scene": scene_to_yaml(scene), "model": model, "integrator": "dop853-jit"})
    run = _LoggedRun(sim, scene, log, "world")
    try:
        assert run.integrate(t_end, rate_hz, Exception) == 0
    finally:
        log.close()
    return run.balance, run.validity


@pytest.mark.parametrize("model", ["full", "rigid"])
def test_node_and_simulate_report_the_same_energy_residual(harness, tmp_path, model):
    node = harness(scene_file=str(DEPLOYMENT), model=model, rtol=1e-8, rate_hz=100.0,
                   real_time_factor=0.0, start_paused=True).node
    for _ in range(300):                                # 3 s in periods of 10 ms
        assert node._step_period(np.zeros((5, 3)))
    assert node.sim.t == pytest.approx(3.0)
    assert sum(e.kind == "latch" for e in node.sim.events) == 3
    balance, validity = simulate_balance(model, 3.0, 100.0, tmp_path)
    ledger = node.period.ledger
    assert ledger.impacts == pytest.approx(balance.impacts, rel=1e-6)
    assert ledger.scale == pytest.approx(balance.scale, rel=1e-6)
    # at 100 Hz: full 0.16 J (its bending vibration, 55 Hz, is beyond the samples' Nyquist
    # frequency), rigid 1e-4 J, of 35.8 J
    bound = 0.2 if model == "full" else 1e-3
    assert abs(ledger.residual) < bound and abs(balance.residual) < bound
    assert ledger.residual == pytest.approx(balance.residual, abs=1e-2 * bound)
    assert not [f for f in node.period.validity.findings() if f.kind == "energy"]
    assert not [f for f in validity.findings() if f.kind == "energy"]
