"""The node judges a jump of its held inputs (the validity monitor's ``force_jump`` check) at
the period's start, where the jump happens, from the slopes it already solved on both sides of
it (the last period's end with the old inputs, the new period's start with the new ones):
the finding's time is the start, its value the largest |slope after - slope before| there.

Oracle: a fresh reduced model of the same scene (not the runner's, not the monitor's) solves
the quasi-static end slopes at the simulator's state at the period's start (its time, state
and latches, copied before the period runs) under the old and the new held inputs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene
from rod_sim.ros import budget
from rod_sim.ros.period import PeriodRunner
from rod_sim.tools.hard_cases import chain

CONFIG = Path(__file__).resolve().parents[1] / "config"
PERIOD_NS = 5_000_000          # 200 Hz


def _runner(scene, model_name="reduced", ahead=False):
    model = make_model(model_name, scene)
    integ = make_integrator("dop853-jit", rtol=1e-8)
    sim = Simulator(model, integ)
    budget.fallback(integ, 1000.0).apply(sim)
    return PeriodRunner(sim, budget.fallback(integ, 1000.0), PERIOD_NS, ahead=ahead)


def _jumps(runner):
    return [f for f in runner.validity.findings() if f.kind == "force_jump"]


def _oracle(scene, t, y, mode, before, after):
    """|slopes(after) - slopes(before)| (2n,) [rad] (alpha then beta) at (t, y, mode)."""
    fresh = make_model("reduced", scene)
    a0, b0 = fresh.bending(t, y, before, mode)
    a1, b1 = fresh.bending(t, y, after, mode)
    return np.abs(np.concatenate([a1 - a0, b1 - b0]))


@pytest.mark.parametrize("ahead", [False, True])
def test_a_jump_is_judged_at_the_period_start_with_the_slopes_on_both_sides(ahead):
    scene = chain(EI=1e3)         # soft rods, the paper's tip pulses: scripted loads too
    runner = _runner(scene, ahead=ahead)
    n = scene.n
    small = np.zeros((n, 3))
    small[:, 1] = 0.5
    for _ in range(4):
        assert runner.run(small) is not None
    assert _jumps(runner) == []                           # a held command is no jump
    sim = runner.sim
    t0, y0, mode0 = sim.t, sim.y.copy(), sim.mode.copy()
    big = small.copy()
    big[5, 1] = 500.0                                    # [N] at node 6, across
    assert runner.run(big) is not None
    assert sim.t > t0
    want = _oracle(scene, t0, y0, mode0, small, big)
    k = int(np.argmax(want))
    assert want[k] > 1e-3                                 # above JUMP_SLOPE_WARN_RAD
    found = _jumps(runner)
    assert len(found) == 1
    assert found[0].t == t0                               # the start, not the end
    assert found[0].rod == k % n + 1
    assert found[0].value == pytest.approx(want[k], rel=1e-9)
    assert f"t = {t0:.4g} s" in found[0].message
    assert runner.run(big) is not None                    # held: no new jump
    assert len(_jumps(runner)) == 1


def test_a_small_jump_and_the_first_command_are_not_reported():
    scene = chain(EI=1e3)
    runner = _runner(scene)
    n = scene.n
    first = np.zeros((n, 3))
    first[5, 1] = 500.0          # the first command after the start: no state before it
    assert runner.run(first) is not None
    assert runner.run(first) is not None
    nudged = first.copy()
    nudged[2, 1] += 1e-3          # a change far too small to bend the rods by 1e-3 rad
    sim = runner.sim
    t0, y0, mode0 = sim.t, sim.y.copy(), sim.mode.copy()
    assert runner.run(nudged) is not None
    assert _oracle(scene, t0, y0, mode0, first, nudged).max() < 1e-6
    assert _jumps(runner) == []


def test_a_jump_of_the_base_force_alone_is_judged_on_a_free_base():
    """A free base's held rows (its force and moment, the wheel's torque) accelerate the
    base: the rods' inertial loads and so their quasi-static slopes jump with them. The
    monitor's own check compares the rods' rows only; the node's, from its States, sees the
    whole jump."""
    scene = load_scene(CONFIG / "two_wing_deployment.yaml")
    runner = _runner(scene)
    n = scene.n
    assert runner.model.nb
    held = np.zeros((n + 2, 3))
    for _ in range(3):
        assert runner.run(held) is not None
    sim = runner.sim
    t0, y0, mode0 = sim.t, sim.y.copy(), sim.mode.copy()
    pushed = held.copy()
    pushed[n] = [0.0, 5.0e4, 2.0e4]      # base force [N] and moment [N m]
    assert runner.run(pushed) is not None
    want = _oracle(scene, t0, y0, mode0, held, pushed)
    k = int(np.argmax(want))
    assert want[k] > 1e-3
    found = _jumps(runner)
    assert [(f.t, f.rod) for f in found] == [(t0, k % n + 1)]
    assert found[0].value == pytest.approx(want[k], rel=1e-9)


@pytest.mark.parametrize("model_name", ["rigid", "full"])
def test_other_models_judge_no_jump(model_name):
    scene = load_scene(CONFIG / "paper_example.yaml")
    runner = _runner(scene, model_name)
    held = np.zeros((scene.n, 3))
    assert runner.run(held) is not None
    held[5, 1] = 500.0
    assert runner.run(held) is not None
    assert _jumps(runner) == []
