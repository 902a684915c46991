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


def measure(sim, period_s: float, seconds: float) -> WorkBudget:
    """The budget for ``seconds`` of wall time per period, timing the scratch simulator
    ``sim`` (advanced and modified) over a few periods of ``period_s`` [s]; its first period
    loads the compiled kernels and is not timed. Raises what ``Simulator.advance`` raises."""
    name = limit_attribute(sim.integrator)
    if name is None:
        sim.advance(period_s)
        return WorkBudget(seconds)
    if hasattr(sim.integrator, "max_step"):   # many short steps: a per-step cost, not overhead
        sim.configure(max_step=period_s / CALIBRATION_SUBSTEPS)
    sim.advance(period_s)
    costs = []
    for _ in range(CALIBRATION_PERIODS):
        before = WorkBudget.work(sim)
        start = time.perf_counter()
        sim.advance(period_s)
        costs.append((time.perf_counter() - start) / max(WorkBudget.work(sim) - before, 1))
    return _budget(name, seconds, statistics.median(costs))


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
