"""The Model/Data split: a model is constants (scene, compiled parameters, per-mode plans)
that any number of simulators share; every byte the kernels write is in a simulator's own
``ModelData`` (``model.new_data()``)."""
from __future__ import annotations

import hashlib
import threading
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import SCRATCH_FIELDS, ModelData, make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene

CONFIG = Path(__file__).resolve().parents[1] / "config"


def _arrays(obj, seen=None):
    """Every numpy array reachable from a model through tuples, lists, dicts and attributes
    (the model's bytes)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        yield obj
    elif isinstance(obj, (tuple, list)):
        for v in obj:
            yield from _arrays(v, seen)
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from _arrays(v, seen)
    elif hasattr(obj, "__dict__") and not isinstance(obj, type):
        for v in vars(obj).values():
            yield from _arrays(v, seen)


def _contents(model) -> list:
    """(array, sha256 of its bytes) for every array the model holds now."""
    return [(a, hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest())
            for a in _arrays(model)]


def _unchanged(contents) -> bool:
    return all(hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest() == h
               for a, h in contents)


def _inputs(sim, k: int, which: int):
    """Different held inputs per simulator and period."""
    n = sim.model.n
    sim.set_forces(np.full((n, 2), 0.3 * which * np.sin(k)))
    sim.set_hinge_torques(np.linspace(0.0, 0.2 * which, n) * np.cos(k))


def _alone(model, integ, which: int, periods: int):
    sim = Simulator(model, integ)
    for k in range(periods):
        _inputs(sim, k, which)
        sim.advance(0.01)
    return sim


@pytest.mark.parametrize("scene, model_name, integ_name", [
    ("deployment", "full", "radau-jit"), ("deployment", "reduced", "dop853-jit"),
    ("paper_example", "rigid", "rk4"), ("paper_example", "reduced", "RK45")])
def test_two_simulators_sharing_one_model_give_each_ones_results_bit_for_bit(
        scene, model_name, integ_name):
    model = make_model(model_name, load_scene(CONFIG / f"{scene}.yaml"))
    integ = make_integrator(integ_name, rtol=1e-7)
    before = _contents(model)
    periods = 15
    ref = [_alone(make_model(model_name, load_scene(CONFIG / f"{scene}.yaml")), integ, w,
                  periods) for w in (1, 2)]
    a, b = Simulator(model, integ), Simulator(model, integ)
    for k in range(periods):                  # interleaved, different inputs
        _inputs(a, k, 1)
        _inputs(b, k, 2)
        a.advance(0.01)
        b.advance(0.01)
        a.snapshot()                          # Python-side evaluations in between
        model.energies(b.t, b.y, b.held, mode=b.mode)
    for sim, alone in zip((a, b), ref):
        np.testing.assert_array_equal(sim.y, alone.y)
        assert sim.stats == alone.stats
        assert [(e.t, e.kind, e.hinge) for e in sim.events] == \
            [(e.t, e.kind, e.hinge) for e in alone.events]
        np.testing.assert_array_equal(sim.snapshot().alpha, alone.snapshot().alpha)
    assert not np.array_equal(a.y, b.y)
    assert _unchanged(before)                 # running wrote nothing into the model
    for plan in model._plans.values():        # new modes' plans (a cache) are constants too
        assert all(getattr(plan.extra, f) is None for f in SCRATCH_FIELDS)


def test_the_model_holds_no_scratch_and_each_simulator_its_own():
    model = make_model("full", load_scene(CONFIG / "deployment.yaml"))
    for fld in SCRATCH_FIELDS:
        assert getattr(model.plan().extra, fld) is None
    a, b = Simulator(model), Simulator(model)
    a.advance(0.01)
    assert isinstance(a.data, ModelData) and a.data is not b.data
    pa, pb = a.data.plan(a.mode, a.contact), b.data.plan(b.mode, b.contact)
    for fld in SCRATCH_FIELDS:
        x, y = getattr(pa.extra, fld), getattr(pb.extra, fld)
        assert isinstance(x, np.ndarray) and not np.shares_memory(x, y)
    # the constants are the model's, shared (not copied per simulator)
    assert pa.extra.rest_phi is model.plan(a.mode, a.contact).extra.rest_phi
    assert pa.events is pb.events


def test_simulators_on_threads_sharing_a_model_match_their_runs_alone():
    scene = load_scene(CONFIG / "paper_example.yaml")
    model = make_model("reduced", scene)
    integ = make_integrator("dop853-jit")
    ref = [_alone(make_model("reduced", scene), integ, w, 30).y for w in (1, 2, 3)]
    got = {}

    def work(w):
        got[w] = _alone(model, integ, w, 30).y

    threads = [threading.Thread(target=work, args=(w,)) for w in (1, 2, 3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for w, y in zip((1, 2, 3), ref):
        np.testing.assert_array_equal(got[w], y)
