"""The work budget of one control period (pure Python, no ROS).

A compiled integrator cannot be interrupted by a wall clock, so the node bounds the *work* of
every ``Simulator.advance`` call instead: accepted steps for ``dop853-jit`` (its
``max_steps``), right-hand side evaluations for the scipy methods (``max_nfev``). The limit
is the wall budget [s] divided by the cost of one unit measured at start, so a period that
would take seconds (e.g. a 1e12 N command: 50 000 steps, ~1.3 s per 10 ms period) fails fast
with a named cause and the executor keeps serving services and diagnostics. The fixed-step
integrators do a fixed amount of work per period and need no limit.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

MIN_UNITS = 50
"""Lower bound of a limit, so that a noisy cost measurement never fails an ordinary period."""
CALIBRATION_SUBSTEPS = 64
"""Steps per period forced while measuring the cost of a step (dop853-jit's ``max_step``)."""
CALIBRATION_PERIODS = 5
"""Periods timed after the first (which loads the compiled kernels); the median cost counts
(a shared machine interrupts some of them)."""
REJECTION_ALLOWANCE = 2.0
"""Step attempts per accepted step the limit allows for: ``max_steps`` counts accepted steps
only, and a 1e12 N command rejects ~0.6 steps per accepted one (measured: 20 528 accepted
steps cost 0.49 s at a calibrated 14.6 us per step)."""

_UNITS = {"max_steps": ("steps", "steps"), "max_nfev": ("nfev", "derivative evaluations")}


def limit_attribute(integrator) -> str | None:
    """The integrator's work-limit attribute (``max_steps`` or ``max_nfev``), or None when
    its work per period is fixed (fixed-step methods)."""
    for name in _UNITS:
        if hasattr(integrator, name):
            return name
    return None


@dataclass
class WorkBudget:
    """``limit`` work units (``unit``) per advance call, from ``seconds`` of wall time at
    ``unit_cost_s`` [s] per unit. ``limit`` 0 = unbounded (fixed-step integrators)."""

    seconds: float
    unit: str = ""
    unit_cost_s: float = 0.0
    limit: int = 0

    def apply(self, sim) -> None:
        """Set the limit on the simulator ``sim``'s integrator (a no-op for fixed-step
        methods)."""
        name = limit_attribute(sim.integrator)
        if name is not None and self.limit > 0:
            sim.configure(**{name: self.limit})

    @staticmethod
    def work(sim) -> int:
        """The simulator ``sim``'s cumulative work counter in the budget's unit."""
        name = limit_attribute(sim.integrator)
        if name is None:
            return 0
        return getattr(sim.stats, _UNITS[name][0])

    def exceeded(self, sim, work_before: int) -> bool:
        """Whether the call that started at counter ``work_before`` used the whole limit."""
        return self.limit > 0 and self.work(sim) - work_before >= self.limit

    def describe(self) -> str:
        if self.limit <= 0:
            return "fixed work per period (fixed-step integrator)"
        return (f"{self.limit} {self.unit} per period (max_period_cost {self.seconds:g} s, "
                f"{self.unit_cost_s * 1e6:.3g} us each measured)")


PROBE_UNITS = 1
"""Work units of the first (kernel-loading) calibration call: one step of a 100 000-rod
chain takes ~0.5 s, so nothing more is done before the cost of a unit is known."""
CALL_WALL_S = 0.1
"""[s] of work each later calibration call is limited to, from the cost measured so far."""
CALIBRATION_WALL_S = 1.0
"""[s] after the first call, calibration stops (with at least one timed call)."""


def measure(sim, period_s: float, seconds: float) -> WorkBudget:
    """The budget for ``seconds`` of wall time per period, timing the scratch simulator
    ``sim`` (advanced and modified) over a few periods of ``period_s`` [s]; its first period
    loads the compiled kernels and is not timed. Every call is bounded (issue 27, item 1: an
    unbounded calibration period of a 10 000-rod chain took 22 s, of 100 000 rods minutes):
    the first to :data:`PROBE_UNITS` work units, the others to :data:`CALL_WALL_S` at the
    cost measured so far, all of it to ~:data:`CALIBRATION_WALL_S` after the first; a call
    that reaches its limit counts its work like one that ends the period (the scratch
    simulator then stays where it was). O(n) work, bounded wall time; a signal interrupts it
    between calls. Raises what ``Simulator.advance`` raises, except the work limit's own
    IntegrationError."""
    from rod_sim.core.integrators import IntegrationError

    name = limit_attribute(sim.integrator)
    if name is None:
        sim.advance(period_s)
        return WorkBudget(seconds)
    if hasattr(sim.integrator, "max_step"):   # many short steps: a per-step cost, not overhead
        sim.configure(max_step=period_s / CALIBRATION_SUBSTEPS)
    from rod_sim.ros.startup import phase

    units, costs = PROBE_UNITS, []
    started = None
    for call in range(1 + CALIBRATION_PERIODS):
        phase("loading the compiled kernels (compiling them if not cached)" if call == 0 else
              f"calibrating the work budget ({call} of {CALIBRATION_PERIODS} timed calls)")
        sim.configure(**{name: units})
        before = WorkBudget.work(sim)
        start = time.perf_counter()
        try:
            sim.advance(period_s)
        except IntegrationError:
            if WorkBudget.work(sim) - before < units:
                raise                               # failed before its limit: a real failure
        done = WorkBudget.work(sim) - before
        cost = (time.perf_counter() - start) / max(done, 1)
        if call == 0:
            started = time.perf_counter()
        else:
            costs.append(cost)
            if time.perf_counter() - started > CALIBRATION_WALL_S:
                break
        units = max(1, int(CALL_WALL_S / max(cost, 1e-9)))
    phase("preparing the run (validity checks, messages, topics)")
    # the first timed call was sized by the kernel-loading one (a unit or so: overhead)
    return _budget(name, seconds, statistics.median(costs[1:] if len(costs) >= 3 else costs))


def _budget(name: str, seconds: float, unit_cost_s: float) -> WorkBudget:
    allowance = REJECTION_ALLOWANCE if name == "max_steps" else 1.0
    limit = max(MIN_UNITS, int(seconds / (unit_cost_s * allowance)))
    return WorkBudget(seconds, _UNITS[name][1], unit_cost_s, limit)


FALLBACK_UNIT_COST_S = 1e-4
"""[s] cost of a work unit assumed when it cannot be measured (the scene fails at once);
about 4x a dop853-jit step of the reduced model at n = 8 (25 us measured)."""


def fallback(integrator, seconds: float) -> WorkBudget:
    """The budget for ``seconds`` per period at :data:`FALLBACK_UNIT_COST_S` per unit."""
    name = limit_attribute(integrator)
    if name is None:
        return WorkBudget(seconds)
    return _budget(name, seconds, FALLBACK_UNIT_COST_S)
