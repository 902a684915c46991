"""Compiled calls through a looked-up overload (rod_sim.core.typed_call): the same results as
numba's dispatcher, bit for bit, and the dispatcher whenever the vouched types do not name a
compiled overload. The oracle is the dispatcher itself (``model.kernel(...)``) and
``numba.typeof``."""
from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import pytest

from rod_sim.core import typed_call
from rod_sim.core.models import make_model
from rod_sim.io.scene_yaml import load_scene

CONFIG = Path(__file__).resolve().parents[1] / "config"


def _direct(model, t, y, held, data):
    """dy/dt by the dispatcher with the same scratch plan as ``_evaluate`` uses."""
    out = np.empty(model.state_size)
    extra = data.plan(None, model.contact_state(y, t)).extra
    model.kernel(float(t), y, model.chain, extra, model.loads, model._held(held), float(t), out)
    return out, extra.work.copy()


@pytest.mark.parametrize("scene,name", [("paper_example.yaml", "reduced"),
                                        ("paper_example.yaml", "full"),
                                        ("paper_example.yaml", "rigid"),
                                        ("two_wing_deployment.yaml", "reduced"), ("hub_arm_latch.yaml", "full")])
def test_evaluate_matches_the_dispatcher_bit_for_bit(scene, name):
    model = make_model(name, load_scene(CONFIG / scene))
    rng = np.random.default_rng(7)
    data = model.new_data()
    for k in range(4):
        y = 0.1 * rng.standard_normal(model.state_size)
        held = rng.standard_normal((model.n, 3))
        t = 0.05 * k            # the first call types the arguments, the later ones look up
        got, extra = model._evaluate(t, y, held, data=data)
        work = extra.work.copy()
        want, want_work = _direct(model, t, y, held, model.new_data())
        assert got.tobytes() == want.tobytes()
        assert work.tobytes() == want_work.tobytes()      # the slopes the reduced model keeps
    assert any(key[0] is model.kernel for key in typed_call._ENTRIES), \
        "the looked-up overload was never used"


def test_array_types_are_numbas():
    a = np.zeros((5, 3))
    ro = np.zeros(4)
    ro.flags.writeable = False
    f_order = np.asfortranarray(np.zeros((3, 4)))
    strided = np.zeros(10)[::2]
    raw = np.zeros(8 * 4 + 1, dtype=np.uint8)[1:].view(np.float64)     # misaligned
    for arr in (a, ro, f_order, strided, raw, np.zeros(3, dtype=np.int64),
                np.zeros(3, dtype=np.int8), np.zeros(0)):
        assert typed_call.array_type(arr) == numba.typeof(arr), arr.flags


def test_a_signature_without_an_overload_goes_through_the_dispatcher():
    @numba.njit
    def add(a, b):
        return a + b

    assert add(1.0, 2.0) == 3.0     # compiled for (float64, float64)
    # vouched int64 types: no such overload, so the dispatcher types and compiles them
    assert typed_call.call(add, (typed_call.INT64, typed_call.INT64), 2, 5) == 7
    assert isinstance(typed_call.call(add, (typed_call.INT64, typed_call.INT64), 2, 5), int)
    assert typed_call.call(add, (typed_call.FLOAT64, typed_call.FLOAT64), 0.5, 0.25) == 0.75
    assert typed_call.call(add, (typed_call.FLOAT64, typed_call.FLOAT64), 1.5, 0.25) == 1.75


def test_a_plain_python_function_is_called_as_it_is():
    calls = []

    def plain(a, b):
        calls.append((a, b))
        return a * b

    sig = (typed_call.FLOAT64, typed_call.FLOAT64)
    assert typed_call.call(plain, sig, 2.0, 3.0) == 6.0
    assert typed_call.call(plain, sig, 4.0, 3.0) == 12.0
    assert calls == [(2.0, 3.0), (4.0, 3.0)]
