"""Real-time pacing and the diagnostics bookkeeping of the node, without ROS."""
from __future__ import annotations

import numpy as np
import pytest

from rod_sim.io.topics import DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN
from rod_sim.ros.monitor import DiagnosticReport, EnergyLedger
from rod_sim.ros.pacing import (MIN_TICK_S, RateMeter, RealTimePacer, max_periods_per_tick,
                                period_ns, tick_period_s)

MS = 1_000_000
PERIOD = 10 * MS  # 100 Hz


def run_ticks(pacer: RealTimePacer, tick_walls, sim0: int = 0):
    """Feed wall readings to the pacer like the node does; returns (sim_ns, periods per tick,
    dropped per tick)."""
    sim = sim0
    periods, dropped = [], []
    for wall in tick_walls:
        d = pacer.decide(int(wall), sim)
        sim += d.periods * pacer.period
        periods.append(d.periods)
        dropped.append(d.dropped)
    return sim, periods, dropped


def test_period_ns_rounds_to_whole_nanoseconds():
    assert period_ns(100.0) == 10 * MS
    assert period_ns(3.0) == 333_333_333
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="rate_hz"):
            period_ns(bad)


def test_tick_period_and_catch_up_bound():
    assert tick_period_s(PERIOD, 1.0) == pytest.approx(0.010)
    assert tick_period_s(PERIOD, 2.0) == pytest.approx(0.005)
    assert tick_period_s(PERIOD, 100.0) == MIN_TICK_S          # 10 periods per 1 ms tick
    assert max_periods_per_tick(PERIOD, 1.0) == 4
    assert max_periods_per_tick(PERIOD, 100.0) == 20
    with pytest.raises(ValueError):
        tick_period_s(PERIOD, 0.0)


def test_first_decision_anchors_and_advances_nothing():
    pacer = RealTimePacer(PERIOD, 1.0)
    assert not pacer.anchored
    assert pacer.decide(5 * 10**9, 0).periods == 0
    assert pacer.anchored
    assert pacer.decide(5 * 10**9 + 10 * MS, 0).periods == 1


def test_regular_ticks_give_one_period_each_without_drift():
    pacer = RealTimePacer(PERIOD, 1.0)
    walls = [1_000 * MS + k * PERIOD + 37_000 for k in range(1001)]  # offset inside a period
    sim, periods, dropped = run_ticks(pacer, walls)
    assert periods[0] == 0 and set(periods[1:]) == {1}
    assert sim == 1000 * PERIOD and sum(dropped) == 0


def test_irregular_ticks_follow_the_wall_clock_exactly():
    rng = np.random.default_rng(7)
    pacer = RealTimePacer(PERIOD, 1.0)
    gaps = rng.uniform(0.2, 2.5, size=3000) * PERIOD       # early, late and doubled ticks
    walls = 10**9 + np.concatenate([[0.0], np.cumsum(gaps)]).astype(np.int64)
    sim, periods, dropped = run_ticks(pacer, walls)
    assert sum(dropped) == 0 and max(periods) <= pacer.max_periods
    # never assumes one tick = one period: the simulated time is the whole periods of wall time
    assert sim == (int(walls[-1]) - int(walls[0])) // PERIOD * PERIOD


def test_late_tick_catches_up_within_the_bound():
    pacer = RealTimePacer(PERIOD, 1.0)
    sim, periods, _ = run_ticks(pacer, [0, 10 * MS, 45 * MS, 50 * MS])
    assert periods == [0, 1, 3, 1] and sim == 5 * PERIOD


@pytest.mark.parametrize("rtf", [0.5, 2.0, 10.0])
def test_real_time_factor_scales_simulated_time(rtf):
    pacer = RealTimePacer(PERIOD, rtf)
    tick = int(tick_period_s(PERIOD, rtf) * 1e9)
    walls = [k * tick for k in range(2001)]
    sim, _, dropped = run_ticks(pacer, walls)
    assert sum(dropped) == 0
    assert abs(sim - rtf * walls[-1]) <= PERIOD


def test_stall_drops_the_backlog_and_reanchors():
    pacer = RealTimePacer(PERIOD, 1.0)
    sim, periods, dropped = run_ticks(pacer, [0, 10 * MS, 1010 * MS, 1020 * MS, 1030 * MS])
    # 100 periods due after the 1 s stall: 4 advanced, 96 dropped, then on time again
    assert periods == [0, 1, 4, 1, 1]
    assert dropped == [0, 0, 96, 0, 0] and pacer.dropped_total == 96
    assert sim == 7 * PERIOD


def test_unanchor_resumes_without_catching_up_the_pause():
    pacer = RealTimePacer(PERIOD, 1.0)
    sim, _, _ = run_ticks(pacer, [0, 10 * MS, 20 * MS])
    pacer.unanchor()                                   # paused for 5 s
    sim, periods, dropped = run_ticks(pacer, [5020 * MS, 5030 * MS], sim0=sim)
    assert periods == [0, 1] and dropped == [0, 0] and sim == 3 * PERIOD


def test_slow_stepping_is_bounded_and_measured():
    """Each period costs 15 ms of wall time for 10 ms of simulated time: the executor is never
    stalled (bounded periods per tick) and the measured real-time factor is about 2/3."""
    pacer = RealTimePacer(PERIOD, 1.0)
    wall, sim = 0, 0
    meter = RateMeter(wall)
    for _ in range(300):
        d = pacer.decide(wall, sim)
        assert d.periods <= pacer.max_periods
        for _ in range(d.periods):
            wall += 15 * MS
            sim += PERIOD
            meter.add_step(PERIOD, 15 * MS)
        wall += 1 * MS                                 # executor overhead between ticks
    rtf = meter.real_time_factor(wall)
    assert 0.5 < rtf < 0.7
    assert pacer.dropped_total > 0
    assert meter.step_cost_ms() == (15.0, 15.0)


def test_rate_meter_window():
    meter = RateMeter(0)
    assert meter.real_time_factor(0) == 0.0 and meter.step_cost_ms() == (0.0, 0.0)
    meter.add_step(PERIOD, 2 * MS)
    meter.add_step(PERIOD, 4 * MS)
    assert meter.real_time_factor(40 * MS) == pytest.approx(0.5)
    assert meter.step_cost_ms() == (3.0, 4.0) and meter.steps == 2
    assert meter.window_s(40 * MS) == pytest.approx(0.04)
    meter.restart(40 * MS)
    assert meter.steps == 0


def test_energy_ledger_trapezoid_rule():
    ledger = EnergyLedger(10.0)
    # power rising linearly 0 -> 2 W over 1 s in 10 periods: work 1 J exactly (trapezoid)
    for k in range(10):
        ledger.add_period(0.1, 0.2 * k, 0.2 * (k + 1), 10.0 + 0.01 * (k + 1) ** 2)
    assert ledger.work == pytest.approx(1.0)
    assert ledger.residual == pytest.approx(11.0 - 10.0 - 1.0, abs=1e-12)
    ledger.start(3.0)
    assert ledger.residual == 0.0 and ledger.work == 0.0


def report(**changes) -> DiagnosticReport:
    base = dict(mode="real time x1", state="running", sim_time=1.0, rtf_target=1.0,
                rtf_measured=1.0, wall_window=1.0, step_cost_mean=0.1, step_cost_max=0.2,
                step_budget=10.0, steps=100, dropped_periods=0, energy=5.0,
                energy_residual=1e-6, commands_received=3, commands_rejected=1,
                last_rejection="expected 16 values", command_active=True,
                max_abs_alpha=0.01, max_abs_beta=0.02, model="reduced",
                integrator="dop853-jit")
    base.update(changes)
    return DiagnosticReport(**base)


def test_diagnostic_levels_and_values():
    level, message, values = report().status()
    assert level == DIAGNOSTIC_OK and "running" in message
    for key in ("real_time_factor_measured", "step_cost_mean_ms", "step_cost_max_ms",
                "sim_time_s", "energy_J", "energy_balance_residual_J", "commands_rejected",
                "max_abs_alpha_rad", "max_abs_beta_rad"):
        assert key in values
    assert values["commands_rejected"] == "1"
    assert all(isinstance(v, str) for v in values.values())

    level, message, _ = report(rtf_measured=0.5).status()
    assert level == DIAGNOSTIC_WARN and "slower than real time" in message
    assert report(rtf_measured=0.5, wall_window=0.1).status()[0] == DIAGNOSTIC_OK
    assert report(rtf_measured=0.5, rtf_target=None).status()[0] == DIAGNOSTIC_OK
    level, message, _ = report(max_abs_beta=0.5).status()
    assert level == DIAGNOSTIC_WARN and "bending" in message
    level, message, values = report(error="step size too small at t = 1 s").status()
    assert level == DIAGNOSTIC_ERROR and "step size too small" in message
    assert values["error"].startswith("step size")


def test_start_up_findings_are_diagnostics_values_and_a_name_conflict_warns():
    values = report().values()
    assert values["name_conflict"] == "false" and values["unknown_parameters"] == "none"
    level, message, values = report(name_conflict="2 nodes named /rod_sim are on the graph",
                                    unknown_parameters=("bogus", "rate")).status()
    assert level == DIAGNOSTIC_WARN and message == "2 nodes named /rod_sim are on the graph"
    assert values["name_conflict"] == "true" and values["unknown_parameters"] == "bogus, rate"
    assert report(unknown_parameters=("bogus",)).status()[0] == DIAGNOSTIC_OK


# ----- issue 20 item 5: catch up what stepping can afford -----

def test_cheap_stepping_catches_up_a_scheduling_delay_without_dropping():
    """A 200 ms delay (the process not scheduled) with 0.15 ms per period: the 20 periods due
    are caught up in one tick (0.5 x 10 ms / 0.15 ms = 33 per tick), none dropped. Without a
    cost (the previous pacer) 16 of them were dropped."""
    cost = 150_000
    pacer = RealTimePacer(PERIOD, 1.0)
    assert pacer.per_tick(cost) == 33
    sim, periods, dropped = run_ticks_costed(pacer, [0, 10 * MS, 210 * MS, 220 * MS], cost)
    assert periods == [0, 1, 20, 1] and dropped == [0, 0, 0, 0]
    assert sim == 22 * PERIOD
    old = RealTimePacer(PERIOD, 1.0)
    _, _, old_dropped = run_ticks(old, [0, 10 * MS, 210 * MS, 220 * MS])
    assert sum(old_dropped) == 16


def run_ticks_costed(pacer: RealTimePacer, tick_walls, cost_ns: float, sim0: int = 0):
    sim = sim0
    periods, dropped = [], []
    for wall in tick_walls:
        d = pacer.decide(int(wall), sim, cost_ns)
        sim += d.periods * pacer.period
        periods.append(d.periods)
        dropped.append(d.dropped)
    return sim, periods, dropped


def test_a_backlog_larger_than_one_tick_is_caught_up_over_several():
    cost = 1 * MS                                    # 5 periods per tick of 10 ms
    pacer = RealTimePacer(PERIOD, 1.0)
    walls = [0, 10 * MS, 310 * MS] + [310 * MS + k * 10 * MS for k in range(1, 12)]
    sim, periods, dropped = run_ticks_costed(pacer, walls, cost)
    assert sum(dropped) == 0
    assert periods[2] == 5 and max(periods) == 5
    assert sim == (walls[-1] // PERIOD) * PERIOD, "on time again after catching up"


def test_only_what_stepping_cannot_afford_is_dropped():
    """Catch-up gains 1/cost - 1/period periods per wall ns: 2 ms per 10 ms period gains 400
    periods per second (CATCH_UP_S = 1 s), so of a 10 s stall (1000 periods) 600 are dropped."""
    cost = 2 * MS
    pacer = RealTimePacer(PERIOD, 1.0)
    assert pacer.affordable_backlog(cost) == 400
    sim, periods, dropped = run_ticks_costed(pacer, [0, 10 * MS, 10_010 * MS], cost)
    assert dropped == [0, 0, 600] and periods[2] == pacer.per_tick(cost) == 4
    assert pacer.target_ns(10_010 * MS) - sim == (400 - 4) * PERIOD


def test_stepping_slower_than_real_time_keeps_the_old_bound():
    pacer = RealTimePacer(PERIOD, 1.0)
    assert pacer.affordable_backlog(15 * MS) == pacer.max_periods
    assert pacer.per_tick(15 * MS) == pacer.max_periods
    assert pacer.affordable_backlog(None) == pacer.per_tick(None) == pacer.max_periods


def test_cost_estimate_is_the_median_of_the_last_ticks():
    """The pacer's cost per period: the median of the last ``ticks`` ticks' costs (numpy's
    median of the same window is the oracle), odd and even windows, bit for bit."""
    from rod_sim.ros.pacing import CostEstimate

    rng = np.random.default_rng(7)
    costs = rng.uniform(1e4, 1e6, 130)
    est = CostEstimate(ticks=50)
    assert est.value is None
    for k, c in enumerate(costs):
        est.add(c)
        window = costs[max(0, k + 1 - 50):k + 1]
        assert est.value == float(np.median(window)), k
