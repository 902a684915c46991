"""Real-time pacing of a fixed-period simulation against a wall clock (pure logic, no ROS).

The node's timer ticks at roughly the control period; at each tick it asks a
:class:`RealTimePacer` how many whole control periods to advance. The pacer never assumes one
tick equals one period: it computes the target simulated time from the wall time elapsed since
an *anchor* times the real-time factor, and returns the number of whole periods between the
current simulated time and that target. So ticks that come late, early or irregularly do not
make the simulation drift from the wall clock.

A backlog comes from late ticks (the process was not scheduled: CPU contention) or from
stepping that costs more than the wall time it represents. Given the measured wall cost of one
period (``step_cost_ns``), the pacer catches up what stepping can afford and drops only the
rest: a tick may step up to :data:`TICK_STEP_FRACTION` of a tick's wall time (at least
``max_periods`` periods), and a backlog is kept as long as it can be caught up within
:data:`CATCH_UP_S` of wall time while the simulation also keeps pace (stepping must be faster
than real time x the factor); beyond that the excess is dropped and the clock re-anchored (the
node reports a measured real-time factor below the target and the dropped periods, instead of
stalling the executor). Without a cost (none measured yet), or when stepping is slower than
real time, at most ``max_periods_per_tick`` periods are advanced and the rest is dropped.

All times are integer nanoseconds: wall readings from a monotonic clock, simulated times as
kept by :class:`rod_sim.core.simulator.Simulator`.
"""
from __future__ import annotations

import math
import statistics
import time
from collections import deque
from dataclasses import dataclass

from rod_sim.core.units import NS_PER_S

MIN_TICK_S = 0.001
"""[s] shortest wall period of the node's pacing timer."""
TICK_STEP_FRACTION = 0.5
"""Share of a tick's wall period one tick may spend catching up (the rest serves commands and
services)."""
CATCH_UP_S = 1.0
"""[s] of wall time within which a backlog must be catchable to be kept (else dropped)."""


def period_ns(rate_hz: float) -> int:
    """The control period 1/rate_hz as whole nanoseconds (rate_hz [Hz] > 0)."""
    if not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise ValueError(f"rate_hz: must be a positive number (got {rate_hz!r})")
    period = int(round(NS_PER_S / rate_hz))
    if period <= 0:
        raise ValueError(f"rate_hz: {rate_hz} Hz gives a period shorter than 1 ns")
    return period


def tick_period_s(period: int, real_time_factor: float) -> float:
    """Wall period [s] of the pacing timer for a control period [ns] and a real-time factor
    (> 0): one control period of wall time, but not shorter than :data:`MIN_TICK_S`."""
    if not real_time_factor > 0.0:
        raise ValueError("tick_period_s: real_time_factor must be > 0 (0 = as fast as possible "
                         "has no pacing timer period)")
    return max(period / NS_PER_S / real_time_factor, MIN_TICK_S)


def max_periods_per_tick(period: int, real_time_factor: float, minimum: int = 4) -> int:
    """How many periods one tick may advance: twice the periods a tick normally covers (more
    than one when the timer cannot tick once per period), and at least ``minimum``."""
    per_tick = tick_period_s(period, real_time_factor) * real_time_factor * NS_PER_S / period
    return max(int(minimum), 2 * int(math.ceil(per_tick - 1e-9)))


@dataclass
class PacingDecision:
    """What one tick should do: ``periods`` to advance now; ``dropped`` periods of backlog
    given up (the clock was re-anchored)."""

    periods: int
    dropped: int = 0


class RealTimePacer:
    """Decides how many control periods to advance at each tick so that simulated time follows
    ``real_time_factor`` x wall time without drift.

    ``period``: control period [ns]; ``real_time_factor`` > 0 (1.0 = wall-clock pace);
    ``max_periods`` per tick (default :func:`max_periods_per_tick`).

    Call :meth:`anchor` whenever the simulation starts, resumes, is reset or stepped by hand;
    then :meth:`decide` at each tick. The pacer is unanchored until the first call of either
    (the first :meth:`decide` anchors and returns 0 periods).
    """

    def __init__(self, period: int, real_time_factor: float, max_periods: int | None = None):
        if period <= 0:
            raise ValueError(f"period: must be > 0 ns (got {period})")
        if not (math.isfinite(real_time_factor) and real_time_factor > 0.0):
            raise ValueError(f"real_time_factor: must be > 0 for pacing (got {real_time_factor!r})")
        self.period = int(period)
        self.real_time_factor = float(real_time_factor)
        self.max_periods = (max_periods_per_tick(self.period, self.real_time_factor)
                            if max_periods is None else int(max_periods))
        if self.max_periods < 1:
            raise ValueError(f"max_periods: must be >= 1 (got {max_periods})")
        self._wall0: int | None = None
        self._sim0 = 0
        self.dropped_total = 0
        """Periods of backlog dropped since construction."""

    @property
    def anchored(self) -> bool:
        return self._wall0 is not None

    def anchor(self, wall_ns: int, sim_ns: int) -> None:
        """Simulated time ``sim_ns`` corresponds to wall reading ``wall_ns`` from now on."""
        self._wall0 = int(wall_ns)
        self._sim0 = int(sim_ns)

    def unanchor(self) -> None:
        """Forget the anchor (e.g. while paused); the next :meth:`decide` re-anchors."""
        self._wall0 = None

    def target_ns(self, wall_ns: int) -> int:
        """Simulated time [ns] the simulation should have reached at wall reading ``wall_ns``."""
        if self._wall0 is None:
            raise RuntimeError("RealTimePacer.target_ns: not anchored")
        elapsed = max(int(wall_ns) - self._wall0, 0)
        return self._sim0 + int(elapsed * self.real_time_factor)

    def per_tick(self, step_cost_ns: float | None) -> int:
        """Periods one tick may advance: ``max_periods``, or more when stepping is cheap (as
        many as fit in :data:`TICK_STEP_FRACTION` of a tick at ``step_cost_ns`` [ns] each)."""
        if not step_cost_ns or step_cost_ns <= 0:
            return self.max_periods
        tick_ns = tick_period_s(self.period, self.real_time_factor) * NS_PER_S
        return max(self.max_periods, int(TICK_STEP_FRACTION * tick_ns // step_cost_ns))

    def affordable_backlog(self, step_cost_ns: float | None) -> int:
        """The largest backlog [periods] kept rather than dropped: what stepping at
        ``step_cost_ns`` [ns] per period catches up within :data:`CATCH_UP_S` while keeping
        pace (each wall ns gains 1/cost - rtf/period periods); ``max_periods`` when no cost is
        known or stepping is not faster than real time."""
        if not step_cost_ns or step_cost_ns <= 0:
            return self.max_periods
        gain_per_ns = 1.0 / step_cost_ns - self.real_time_factor / self.period
        return max(self.max_periods, int(CATCH_UP_S * NS_PER_S * gain_per_ns))

    def decide(self, wall_ns: int, sim_ns: int,
               step_cost_ns: float | None = None) -> PacingDecision:
        """Periods to advance at wall reading ``wall_ns`` when the simulation is at ``sim_ns``;
        ``step_cost_ns``: the measured wall cost of one period [ns] (None: unknown).

        Whole periods only: the remainder waits for a later tick. At most :meth:`per_tick` per
        tick; a backlog beyond :meth:`affordable_backlog` is dropped and the clock re-anchored
        so that the backlog left is the affordable one.
        """
        if self._wall0 is None:
            self.anchor(wall_ns, sim_ns)
            return PacingDecision(0)
        behind = (self.target_ns(wall_ns) - int(sim_ns)) // self.period
        if behind <= 0:
            return PacingDecision(0)
        step = self.per_tick(step_cost_ns)
        keep = self.affordable_backlog(step_cost_ns)
        if behind <= keep:
            return PacingDecision(int(min(behind, step)))
        dropped = int(behind) - keep
        self.dropped_total += dropped
        self.anchor(wall_ns, int(sim_ns) + keep * self.period)
        return PacingDecision(int(min(keep, step)), dropped)


class RateMeter:
    """Measured real-time factor over a window: simulated time advanced / wall time elapsed,
    plus the wall cost of each step (mean and max, [ms])."""

    def __init__(self, wall_ns: int):
        self.restart(wall_ns)

    def restart(self, wall_ns: int) -> None:
        """Start a new window at wall reading ``wall_ns``. The window sums the advances it is
        told of, so resets of the simulated time do not distort it."""
        self._wall0 = int(wall_ns)
        self._advanced_ns = 0
        self._costs_ns: list[int] = []

    def add_step(self, sim_dt_ns: int, cost_ns: int) -> None:
        """One step advanced ``sim_dt_ns`` of simulated time and cost ``cost_ns`` of wall time."""
        self._advanced_ns += int(sim_dt_ns)
        self._costs_ns.append(int(cost_ns))

    def window_s(self, wall_ns: int) -> float:
        """Wall time [s] since the window started."""
        return (int(wall_ns) - self._wall0) / NS_PER_S

    def real_time_factor(self, wall_ns: int) -> float:
        """Simulated seconds per wall second since the window started (0 if no wall time)."""
        elapsed = int(wall_ns) - self._wall0
        return self._advanced_ns / elapsed if elapsed > 0 else 0.0

    def step_cost_ms(self) -> tuple[float, float]:
        """(mean, max) wall cost of the window's steps [ms]; (0, 0) without steps."""
        if not self._costs_ns:
            return 0.0, 0.0
        return (sum(self._costs_ns) / len(self._costs_ns) / 1e6, max(self._costs_ns) / 1e6)

    @property
    def steps(self) -> int:
        return len(self._costs_ns)


class CostEstimate:
    """The wall cost of one period [ns] the pacer catches up with: the median of the last
    ``ticks`` ticks' cost per period (stepping, publishing, recording); a tick that was itself
    preempted by another process does not inflate it; when every tick is slow, the median is
    slow too. ``value`` is None until a tick was measured."""

    def __init__(self, ticks: int = 50):
        self._costs: deque[float] = deque(maxlen=ticks)
        self.value: float | None = None

    def add(self, cost_ns: float) -> None:
        self._costs.append(cost_ns)
        # statistics.median: the same middle value (or mean of the two middle ones) as
        # np.median, without converting the deque to an array at every tick (22 -> 2 us)
        self.value = float(statistics.median(self._costs))


FAST_TICK_BUDGET_NS = 20_000_000
"""[ns] wall time one tick may spend stepping when running as fast as possible."""


class Pacing:
    """The pace of a node outside lockstep, control period ``period`` [ns]: real time x
    ``rtf`` (a :class:`RealTimePacer` and the measured cost of a period) or, for ``rtf`` 0, as
    fast as possible (:data:`FAST_TICK_BUDGET_NS` of stepping per tick, so commands and
    services are served between ticks). ``dropped`` counts the periods of backlog given up."""

    def __init__(self, period: int, rtf: float):
        self.period = period
        self.cost = CostEstimate()
        self.dropped = 0
        self.set_rtf(rtf)

    def set_rtf(self, rtf: float) -> None:
        self.rtf = rtf
        self.pacer = RealTimePacer(self.period, rtf) if rtf > 0 else None

    def tick_period_s(self) -> float:
        """[s] period of the pacing timer (0: as fast as possible)."""
        return tick_period_s(self.period, self.rtf) if self.rtf > 0 else 0.0

    def unanchor(self) -> None:
        if self.pacer is not None:
            self.pacer.unanchor()

    def tick(self, sim_ns: int, step, running, budget_s: float, warn) -> None:
        """One timer tick: ``step(wall_age)`` -> success for each period that is due (the
        rest of a tick longer than ``budget_s`` waits for the next one); ``running()`` says
        whether to go on; ``warn(text)`` reports dropped backlog."""
        if self.pacer is None:
            deadline = time.monotonic_ns() + FAST_TICK_BUDGET_NS
            while running() and time.monotonic_ns() < deadline:
                step(False)
            return
        decision = self.pacer.decide(time.monotonic_ns(), sim_ns, self.cost.value)
        if decision.dropped:
            self.dropped += decision.dropped
            warn(f"cannot keep up with real time x{self.rtf:g}: dropped {decision.dropped} "
                 f"period(s) of backlog ({self.dropped} in all; a period costs "
                 f"{(self.cost.value or 0) / 1e6:.3g} ms of wall time)")
        start = time.monotonic_ns()
        deadline, stepped = start + budget_s * NS_PER_S, 0
        for _ in range(decision.periods):
            ok = step(True)
            stepped += ok
            if not ok or time.monotonic_ns() > deadline:
                break
        if stepped:
            self.cost.add((time.monotonic_ns() - start) / stepped)
