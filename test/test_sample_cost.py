"""One evaluation of each quantity per sample (issues 25/26: the per-sample cost of ``rod-sim
simulate`` on spacecraft scenes): the snapshot, the energy balance sample, the momentum ledger
and the diagnostics of a sample share one :class:`~rod_sim.core.state.State`, so the momentum
is evaluated once per sample, the powers once per state (the sample's own and the two states
of the balance's central difference, those two in one call without slope rates in the state), the
node velocities once per state and the right-hand side once per sample (beyond the
integrator's own). Counted by wrapping the laws themselves, wherever they are called from; the
counts of 1cf5e2f were 3 momenta, 6 node velocity evaluations and 3 powers per sample on the
two-wing scene."""
from __future__ import annotations

import collections
import functools
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core import models, state as state_mod
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
from rod_sim.tools.simulate import _LoggedRun

CONFIG = Path(__file__).resolve().parents[1] / "config"


@pytest.fixture
def counts(monkeypatch):
    """Counts of the laws' evaluations: ``counts[name]`` lists the (t, y bytes) of each."""
    seen = collections.defaultdict(list)

    def counted(name):
        law = state_mod.State.__dict__[name].compute

        @functools.wraps(law)
        def wrapper(s):
            seen[name].append((float(s.t), s.y.tobytes()))
            return law(s)
        monkeypatch.setattr(state_mod.State, name, state_mod.cached(wrapper))

    for name in ("momentum", "powers", "velocities", "nodes", "energies"):
        counted(name)
    pair = state_mod.State.moved_net_powers

    def moved_pair(s, *args):
        out = pair(s, *args)
        if out is not None:
            seen["moved_pair"].append((float(s.t), s.y.tobytes()))
        return out
    monkeypatch.setattr(state_mod.State, "moved_net_powers", moved_pair)
    evaluate = models.ChainModel._evaluate

    def rhs(self, *args, **kwargs):
        seen["rhs"].append(None)
        return evaluate(self, *args, **kwargs)
    monkeypatch.setattr(models.ChainModel, "_evaluate", rhs)
    return seen


def _per_sample(seen, samples):
    return {k: len(v) / samples for k, v in seen.items()}


@pytest.mark.parametrize("scene_name, model_name", [
    ("two_wing_deployment.yaml", "reduced"), ("spin_up_beam.yaml", "full"),
    ("deployment.yaml", "rigid"), ("paper_example.yaml", "reduced")])
def test_simulate_evaluates_each_quantity_once_per_sample(scene_name, model_name, counts,
                                                          tmp_path):
    scene = load_scene(CONFIG / scene_name)
    sim = Simulator(make_model(model_name, scene), make_integrator("dop853-jit"))
    log = LogWriter(tmp_path / "run.mcap", metadata={
        "scene": scene_to_yaml(scene), "model": model_name, "integrator": "dop853-jit"})
    logged = _LoggedRun(sim, scene, log, "world")
    write = logged._write

    def sample(t, y, mode=None, logged=True):   # count the sample's own evaluations only
        for v in counts.values():
            v.clear()
        write(t, y, mode, logged)
        per = _per_sample(counts, 1)
        here = (float(t), np.asarray(y, float).tobytes())
        for name, states in counts.items():     # never twice at one state
            if name != "rhs":
                assert len(set(states)) == len(states), (name, per)
        assert counts["momentum"] == ([here] if scene.is_spacecraft else []), per
        assert counts["energies"] == [here] and here in counts["nodes"], per
        # the powers once per state: the sample's own and y +- h f of the balance's rate
        # (no slope rates in the state: both of those in one call, at the sample's state)
        if sim.model.paired_balance:
            assert counts["moved_pair"] == [here], per
            assert per["powers"] == 1 and counts["powers"][0] == here, per
        else:
            assert "moved_pair" not in per, per
            assert per["powers"] == 3 and counts["powers"][0] == here, per
        # one right-hand side for the slopes and the balance's rate (the full model's
        # defect and a prescribed base's reaction share it); a prescribed base's reaction
        # also needs the accelerations at y +- h f
        assert per["rhs"] == (3 if sim.model.prescribed_base else 1), per
        summary[0] += 1

    summary = [0]
    logged._write = sample
    try:
        assert logged.integrate(0.05, 100.0, Exception) == 0
    finally:
        log.close()
    assert summary[0] == logged.samples == 6


def test_node_period_evaluates_each_quantity_once(counts):
    """The node's PeriodRunner (rod_sim/ros/period.py, no ROS graph): a period with unchanged
    inputs books its end state once — one momentum (snapshot and momentum ledger), the
    powers at its own state and the balance's two moved states in one call (stops and a free
    base), one right-hand side."""
    from rod_sim.ros import budget
    from rod_sim.ros.period import PeriodRunner

    scene = load_scene(CONFIG / "two_wing_deployment.yaml")
    sim = Simulator(make_model("reduced", scene), make_integrator("dop853-jit"))
    runner = PeriodRunner(sim, budget.fallback(sim.integrator, 0.5), 10_000_000)
    held = np.zeros((scene.n, 3))
    assert runner.run(held) is not None
    for _ in range(4):
        for v in counts.values():
            v.clear()
        assert runner.run(held) is not None
        here = (float(sim.t), sim.y.tobytes())
        assert counts["momentum"] == [here] and counts["energies"] == [here]
        assert counts["powers"] == [here] and counts["moved_pair"] == [here]
        assert len(counts["rhs"]) == 1
