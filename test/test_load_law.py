"""One scripted-load law: the scene's Python side (Load.value, Scene.scripted_load_table) and
the compiled side (kernels.scripted_value, the model's load table through kernels.load_forces)
give the same bits, and both follow the formulas of docs/interface.md section 1 (the oracle
below is written from the document, not imported), on every load shape, at random times and
exactly at and next to the breakpoints."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rod_sim.core import kernels, loadlaw
from rod_sim.core.models import make_model
from rod_sim.core.scene import LOAD_SHAPES, Load, Scene


def oracle(shape: str, amp: float, start: float, dur: float, t: float) -> float:
    """docs/interface.md: raised_cosine_pulse F(t) = A (1/2 - 1/2 cos(2 pi (t - start)/duration))
    on [start, start + duration], else 0; constant A from start on; step A on
    [start, start + duration)."""
    if shape == "raised_cosine_pulse":
        if start <= t <= start + dur:
            return amp * (0.5 - 0.5 * math.cos(2.0 * math.pi * (t - start) / dur))
        return 0.0
    if shape == "constant":
        return amp if t >= start else 0.0
    if shape == "step":
        return amp if start <= t < start + dur else 0.0
    raise AssertionError(f"no oracle for load shape {shape!r}")


LOADS = [("raised_cosine_pulse", -150.0, 0.0, 0.5), ("raised_cosine_pulse", 1200.0, 0.3, 1.7),
         ("constant", 7.5, 0.25, math.inf), ("constant", -2.0, 0.0, math.inf),
         ("step", 40.0, 0.1, 0.2), ("step", -3.0, 1.1, 0.45)]


def test_every_shape_has_an_oracle_here():
    assert set(LOAD_SHAPES) == {shape for shape, *_ in LOADS} == set(loadlaw.SHAPE_CODES)


def _times(start: float, dur: float, rng) -> np.ndarray:
    """Random times around the load and its breakpoints, and the breakpoints themselves with
    their neighbouring floats."""
    end = start + dur if math.isfinite(dur) else start + 1.0
    marks = [start, end] if math.isfinite(dur) else [start]
    near = [np.nextafter(b, d) for b in marks for d in (-np.inf, np.inf)]
    return np.concatenate([rng.uniform(start - 0.5, end + 0.5, 200), marks, near])


@pytest.mark.parametrize("shape, amp, start, dur", LOADS)
def test_python_and_compiled_entry_points_follow_the_documented_law(shape, amp, start, dur):
    rng = np.random.default_rng(1000 + int(abs(amp)))
    load = Load(node=1, axis="x", shape=shape, amplitude=amp, start=start, duration=dur)
    code = loadlaw.SHAPE_CODES[shape]
    for t in _times(start, dur, rng):
        t = float(t)
        py = load.value(t)
        compiled = kernels.scripted_value(t, code, amp, start, dur, t)
        assert py == compiled, (t, py, compiled)                     # one law: the same bits
        assert py == pytest.approx(oracle(shape, amp, start, dur, t), rel=0, abs=1e-12 * abs(amp))
        if shape != "raised_cosine_pulse":
            assert py == oracle(shape, amp, start, dur, t)          # discrete: exactly


@pytest.mark.parametrize("shape, amp, start, dur", LOADS)
def test_an_integrator_segment_picks_the_side_of_a_jump(shape, amp, start, dur):
    """At a breakpoint the compiled law gives the limit from the side of ``t_side`` (a time
    inside the integrator's current segment): the oracle just before or just after it."""
    code = loadlaw.SHAPE_CODES[shape]
    for b in ([start, start + dur] if math.isfinite(dur) else [start]):
        before = kernels.scripted_value(b, code, amp, start, dur, b - 1e-3)
        after = kernels.scripted_value(b, code, amp, start, dur, b + 1e-3)
        left = oracle(shape, amp, start, dur, float(np.nextafter(b, -np.inf)))
        right = oracle(shape, amp, start, dur, float(np.nextafter(b, np.inf)))
        if shape == "raised_cosine_pulse":
            # continuous: both sides give the formula's value at b (0 at the pulse's ends)
            assert abs(before) <= 1e-12 * abs(amp) and abs(after) <= 1e-12 * abs(amp)
        else:
            assert (before, after) == (left, right), (b, before, after, left, right)


def test_the_scene_and_the_models_load_table_agree_bit_for_bit():
    """Every load of a scene at once: Scene.scripted_load_table (Python) and the model's
    applied loads (the kernels' load_forces with no held input) are the same array, and the
    oracle's sum per row and column."""
    data = {"name": "loads", "rods": {"count": 4, "length": 1.0, "mass_per_length": 1.0,
                                       "bending_stiffness": 1e3},
            "nodes": {"mass": 0.1}, "hinges": {"stiffness": 1.0, "damping": 0.1},
            "initial": {"phi": 0.0, "phi_rate": 0.0},
            "loads": [{"node": 1 + i % 4, "axis": "xy"[i % 2], "shape": s, "amplitude": a,
                       "start": t0, **({"duration": d} if math.isfinite(d) else {})}
                      for i, (s, a, t0, d) in enumerate(LOADS)]}
    scene = Scene.from_dict(data)
    model = make_model("rigid", scene)
    rng = np.random.default_rng(7)
    marks = [b for ld in scene.loads for b in ld.breakpoints()]
    for t in np.concatenate([rng.uniform(-0.5, 2.5, 100), marks]):
        t = float(t)
        table = scene.scripted_load_table(t)
        np.testing.assert_array_equal(model.loads_at(t), table)
        np.testing.assert_array_equal(scene.scripted_forces(t), table[:scene.n, :2])
        want = np.zeros((scene.n + 2, 3))
        for i, (s, a, t0, d) in enumerate(LOADS):
            want[i % 4, i % 2] += oracle(s, a, t0, d, t)
        np.testing.assert_allclose(table, want, rtol=0, atol=1e-9)
