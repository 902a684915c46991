"""Periods integrated ahead (rod_sim.core.ahead, the node's real-time mode): the period ends
taken from DOP853's dense output agree with a fresh integration to the tolerance; a change of
the held inputs ends the buffered stretch exactly at the period boundary where it came; one
period at a time is Simulator.advance bit for bit (lockstep); hinge events are never served
from the buffer. The reference is an ordinary Simulator at a 1e4 x tighter tolerance (one
drive per period: the code path the buffer replaces)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.ahead import Ahead
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene
from rod_sim.ros import budget
from rod_sim.ros.period import PeriodRunner, ahead_periods

CONFIG = Path(__file__).resolve().parents[1] / "config"
PERIOD_NS = 1_000_000          # 1 kHz
RTOL = 1e-8


def _model(name="paper_example.yaml"):
    return make_model("reduced", load_scene(CONFIG / name))


def _reference(model, periods, changes=()):
    """States at each period end from an ordinary simulator at rtol 1e-12; ``changes``:
    (period index, held (n, 3)) set at that period's start."""
    sim = Simulator(model, make_integrator("dop853-jit", rtol=1e-12))
    changes = dict(changes)
    out = []
    for k in range(periods):
        if k in changes:
            sim.set_held(changes[k])
        sim.advance(PERIOD_NS / 1e9)
        out.append(sim.y.copy())
    return np.array(out)


def _scale(model, ref):
    return np.max(np.abs(ref), axis=0) + 1.0


def test_period_ends_from_the_buffer_agree_with_a_fresh_integration():
    model = _model()
    periods = 300
    ref = _reference(model, periods)
    sim = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    ahead = Ahead(sim)
    got = []
    for k in range(periods):
        ahead.advance(PERIOD_NS, 50)
        assert sim.t_ns == (k + 1) * PERIOD_NS
        got.append(sim.y.copy())
    assert ahead.served > periods // 2          # it did serve from the buffer
    err = np.max(np.abs(np.array(got) - ref) / _scale(model, ref))
    plain = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    base = []
    for k in range(periods):
        plain.advance(PERIOD_NS / 1e9)
        base.append(plain.y.copy())
    err_plain = np.max(np.abs(np.array(base) - ref) / _scale(model, ref))
    assert err < max(100 * RTOL, 10 * err_plain), (err, err_plain)
    # the work: far fewer right-hand sides than one drive per period
    assert sim.stats.nfev < plain.stats.nfev / 3, (sim.stats.nfev, plain.stats.nfev)


def test_a_change_of_the_held_inputs_ends_the_stretch_at_the_period_boundary():
    model = _model()
    n = model.n
    push = np.zeros((n, 3))
    push[-1, 0] = 5.0                  # 5 N on the last node from period 40 on
    ref = _reference(model, 80, [(40, push)])
    sim = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    ahead = Ahead(sim)
    got = []
    for k in range(80):
        if k == 40:
            assert ahead.pending() > 0        # the buffer reaches past the change
            sim.set_held(push)
        served = ahead.advance(PERIOD_NS, 30)
        if k == 40:
            assert not served                # integrated afresh from the boundary
        got.append(sim.y.copy())
    got = np.array(got)
    scale = _scale(model, ref)
    assert np.max(np.abs(got - ref) / scale) < 100 * RTOL
    # the force acts from the boundary on, not earlier and not later: the same runs with the
    # change one period early or late differ from the reference far more than the tolerance
    for other in (39, 41):
        off = _reference(model, 80, [(other, push)])
        assert np.max(np.abs(off - ref) / scale) > 1e3 * np.max(np.abs(got - ref) / scale)


def test_one_period_at_a_time_is_simulator_advance_bit_for_bit():
    model = _model()
    a = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    b = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    ahead = Ahead(b)
    rng = np.random.default_rng(3)
    for k in range(60):
        held = np.zeros((model.n, 3))
        held[:, :2] = rng.normal(scale=0.5, size=(model.n, 2)) * (k % 7 == 0)
        a.set_held(held)
        b.set_held(held)
        a.advance(PERIOD_NS / 1e9)
        assert not ahead.advance(PERIOD_NS, 1)
        assert a.t_ns == b.t_ns and np.array_equal(a.y, b.y)
    assert a.stats == b.stats


def test_hinge_events_are_never_served_from_the_buffer():
    model = _model("deployment.yaml")
    period = 10_000_000
    a = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    b = Simulator(model, make_integrator("dop853-jit", rtol=RTOL))
    ahead = Ahead(b)
    for _ in range(300):                   # 3 s: the panels unfold and latch
        a.advance(period / 1e9)
        ahead.advance(period, 20)
        assert a.t_ns == b.t_ns
        np.testing.assert_array_equal(a.mode, b.mode)
    assert a.events and [(e.kind, e.hinge) for e in a.events] == \
        [(e.kind, e.hinge) for e in b.events]
    ta, tb = np.array([e.t for e in a.events]), np.array([e.t for e in b.events])
    assert np.max(np.abs(ta - tb)) < 1e-5
    assert np.max(np.abs(a.y - b.y)) < 1e-4 * (1.0 + np.max(np.abs(a.y)))


@pytest.mark.parametrize("limit, held_for, step_s, k", [
    (100, 0, 0.05, 1), (100, 1, 0.05, 1), (100, 7, 0.05, 7), (100, 500, 0.05, 50),
    (10, 500, 0.05, 10), (100, 500, 0.0, 1), (100, 500, 0.0004, 4), (100, 3, 0.0004, 3),
    (1, 500, 0.05, 1)])
def test_ahead_periods(limit, held_for, step_s, k):
    assert ahead_periods(limit, held_for, step_s, PERIOD_NS) == k


def test_period_runner_looks_ahead_only_outside_lockstep():
    model = _model()
    plain, ahead = (PeriodRunner(Simulator(model, make_integrator("dop853-jit")),
                                 budget.fallback(make_integrator("dop853-jit"), 0.5),
                                 PERIOD_NS, ahead=flag) for flag in (False, True))
    for _ in range(200):
        assert plain.run(np.zeros((model.n, 2))) is not None
        assert ahead.run(np.zeros((model.n, 2))) is not None
    assert plain.ahead.served == 0 and ahead.ahead.served > 100
    assert ahead.sim.stats.nfev < plain.sim.stats.nfev / 3
    # the energy ledger books the buffered periods as it books ordinary ones
    assert abs(ahead.ledger.residual - plain.ledger.residual) < 1e-6 * plain.ledger.scale


@pytest.mark.parametrize("scene, period_ns", [("paper_example.yaml", PERIOD_NS),
                                              ("deployment.yaml", 5_000_000)])
def test_the_ledgers_book_fewer_spans_to_the_same_balance(scene, period_ns):
    """Outside lockstep the energy ledger books one span per LEDGER_SPAN_S while the inputs
    stay held (closing it where they change or a hinge event happens): its residual and
    energy follow the period-by-period ledger's to the integration tolerance."""
    model = _model(scene)
    n = model.n
    runners = [PeriodRunner(Simulator(model, make_integrator("dop853-jit")),
                            budget.fallback(make_integrator("dop853-jit"), 0.5),
                            period_ns, ahead=flag) for flag in (False, True)]
    push = np.zeros((n, 3))
    push[-1, 1] = 0.3
    booked, spans = [], []
    add = runners[1].ledger.add

    def spy(start, end, events):
        spans.append((start.t, end.t))
        add(start, end, events)

    runners[1].ledger.add = spy
    for k in range(600 if period_ns == PERIOD_NS else 800):
        held = push if 57 <= k < 133 or k == 250 else np.zeros((n, 3))
        for r in runners:
            assert r.run(held) is not None
            r.events_seen = len(r.sim.events)
        booked.append(runners[1]._span_ns)
    plain, fewer = runners
    spans = [(round(a, 9), round(b, 9)) for a, b in spans]
    assert len(set(booked)) < 0.6 * len(booked)       # spans were merged
    for k in (57, 133, 250, 251):                     # ... and closed where the inputs change
        assert k * period_ns in booked, k
    if scene == "paper_example.yaml":        # ... and a load's breakpoint (0.5 s) has
        assert (0.499, 0.5) in spans             # a span of one period of its own
    fewer.book()
    # (the deployment's stop contacts and latches leave the ledger a residual of ~5e-5 of
    # its scale either way; the two differ by a fraction of it)
    assert abs(fewer.ledger.residual - plain.ledger.residual) < max(
        1e-6 * plain.ledger.scale, 0.2 * abs(plain.ledger.residual))
    if scene == "deployment.yaml":      # three latches: their impacts booked in both
        assert plain.sim.events and len(fewer.sim.events) == len(plain.sim.events)
        assert abs(plain.ledger.residual) < 1e-4 * plain.ledger.scale
