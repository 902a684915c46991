"""One control period of the node, without ROS: inputs held, bounded integration, bookkeeping.

:class:`PeriodRunner` owns what a period changes besides the simulator's state: the energy
ledger (:class:`~rod_sim.ros.monitor.EnergyLedger`, fed with the balance samples of each
period's start and end), the validity monitor, the step-cost meter, the largest end slopes
since the last diagnostics, and the cause of a failed period. :meth:`PeriodRunner.run` holds
the inputs, lets the caller publish what is applied at the period's start, advances the
simulator by one period within the work budget (:mod:`rod_sim.ros.budget`) and returns the
snapshot at the period's end (None when the integration failed: :attr:`error` says why and
the simulator stays at the period's start).

Per period, beyond the integration: one snapshot, one or two balance samples (two when the
held inputs changed at the period's start, since the net power jumps there) and the monitor's
O(n) checks: vectorised, no loop over rods. A change of the held inputs is judged as a force
jump at the period's start from the slopes of the last period's end and of the new start
(no extra solve). Outside lockstep, while the held inputs stay the
same and no hinge event or breakpoint of a scripted load happens, the ledgers book one span per
:data:`LEDGER_SPAN_S` instead of one per period (the span's end sample is taken when it closes: its state, inputs and
right-hand side are kept), and one drive may cover several periods
(:class:`~rod_sim.core.ahead.Ahead`).
"""
from __future__ import annotations

import bisect
import time
from typing import Callable

import numpy as np

from rod_sim.core.ahead import Ahead
from rod_sim.core.integrators import IntegrationError
from rod_sim.core.ledger import SpacecraftLedger, diagnostic_strings, diagnostic_values
from rod_sim.core.snapshot import Snapshot
from rod_sim.core.units import NS_PER_S
from rod_sim.core.validity import ValidityMonitor, balance_sample
from rod_sim.ros.errors import one_line
from rod_sim.ros.monitor import EnergyLedger
from rod_sim.ros.pacing import RateMeter

LEDGER_SPAN_S = 0.01
"""[s] of simulated time the energy and momentum ledgers may go without a sample while the
held inputs stay the same and no hinge event happens (outside lockstep; at rates of 100 Hz
and below every period is booked): at 1 kHz one balance sample per 10 periods, as a 100 Hz
node or ``simulate``'s default log books them."""
AHEAD_MAX_S = 0.1
"""[s] of simulated time one drive may cover ahead (:class:`~rod_sim.core.ahead.Ahead`)."""


AHEAD_SHORT_STEPS = 4
"""Periods one drive may cover when the integrator's step is shorter than a period: its
steps then do not end at every period's end (each such end costs a shortened step)."""


def ahead_periods(limit: int, held_for: int, step_s: float, period_ns: int) -> int:
    """Periods to integrate ahead at once: 1 (an ordinary period) unless the inputs have
    been held unchanged for ``held_for`` >= 2 periods, then as many as they have been held
    (they are expected to stay as long again; a command that comes earlier wastes at most
    that much work), as the integrator's carried step ``step_s`` [s] covers (its natural
    step: one drive ~ one step), or :data:`AHEAD_SHORT_STEPS` when that step is shorter
    than a period, and as ``limit`` allows (0 s: no step carried yet, 1)."""
    if step_s <= 0:
        return 1
    natural = max(int(step_s * NS_PER_S // period_ns), AHEAD_SHORT_STEPS)
    return max(1, min(int(limit), int(held_for), natural))


def full_inputs(held, n: int) -> np.ndarray:
    """(n, 3) [X, Y, T] from (n, 3), or from (n, 2) / 2n forces (zero torques); (n + 2, 3)
    (with the base's and the wheel's rows) as it is."""
    held = np.asarray(held, dtype=float)
    if held.shape in ((n, 3), (n + 2, 3)):
        return held
    full = np.zeros((n, 3))
    full[:, :2] = held.reshape(n, 2)
    return full


class PeriodRunner:
    """Advances ``sim`` (a :class:`~rod_sim.core.simulator.Simulator`) one period of
    ``period_ns`` [ns] at a time within ``budget`` (a :class:`~rod_sim.ros.budget.WorkBudget`).
    ``ahead``: integrate several periods at once while the inputs stay held
    (:func:`ahead_periods`, :class:`~rod_sim.core.ahead.Ahead`: the integrator's natural
    steps, period ends from its dense output; not in lockstep, whose log stays bit for bit
    that of one drive per period)."""

    def __init__(self, sim, budget, period_ns: int, ahead: bool = False):
        self.sim = sim
        self.ahead = Ahead(sim)
        self.ahead_limit = max(1, int(AHEAD_MAX_S * NS_PER_S // period_ns)) if ahead else 1
        """Most periods one drive covers (1: one drive per period)."""
        self.held_for = 0
        """Periods the current held inputs have been held unchanged."""
        self.model = sim.model
        self.budget = budget
        self.period_ns = int(period_ns)
        self.ledger = EnergyLedger.for_model(self.model, self.energy(sim.held))
        self.spacecraft = SpacecraftLedger(self.model) if self.model.is_spacecraft else None
        """The momentum balance and injected work (spacecraft scenes; None otherwise)."""
        self.last_state: Snapshot | None = None
        """The snapshot at the end of the last good period (spacecraft diagnostics)."""
        self._book_spacecraft(sim.held)
        self.validity = ValidityMonitor(self.model)
        self.meter = RateMeter(time.monotonic_ns())
        self.max_alpha = 0.0
        self.max_beta = 0.0
        self.error: str | None = None
        """The cause of the last failed period (None after a good one or a reset)."""
        self.events_seen = 0
        """Hinge events of ``sim.events`` already booked and published."""
        self._balance_end = None
        """(t_ns, held, y, mode, State) at the end of the last period: its inputs and
        what its balance sample needs (the next period goes on with the same span when the
        held inputs did not change)."""
        self._span_start = None
        """The BalanceSample where the span not yet booked in the ledgers starts."""
        self._span_ns = 0
        """Its time [ns]."""
        scene = self.model.scene
        self._breaks_ns = sorted({int(round(b * NS_PER_S)) for b in scene.breakpoints()})
        """Breakpoints of the scripted loads and base motion [ns], sorted: the periods
        holding one are booked on their own (as in lockstep)."""

    def energy(self, held: np.ndarray) -> float:
        sim = self.sim
        return self.model.energies(sim.t, sim.y, held, mode=sim.mode).total

    def reset(self) -> None:
        """The simulator back at t = 0 and the bookkeeping started afresh."""
        self.sim.reset()
        self.held_for = 0
        self.events_seen = 0
        self.error = None
        self.ledger.start(self.energy(self.sim.held))
        if self.spacecraft is not None:
            self.spacecraft.start()
        self.last_state = None
        self._book_spacecraft(self.sim.held)
        self._balance_end = self._span_start = None
        self.validity = ValidityMonitor(self.model)
        self.meter.restart(time.monotonic_ns())

    def _book_spacecraft(self, held, state=None) -> None:
        """The simulator's state in the momentum ledger (a spacecraft scene); ``state``: its
        :class:`~rod_sim.core.state.State`, shared with the balance sample and snapshot."""
        if self.spacecraft is not None:
            sim = self.sim
            self.spacecraft.add(sim.t, sim.y, held, sim.mode, state=state)

    def spacecraft_values(self) -> dict[str, str]:
        """The spacecraft keys of ``/diagnostics`` (:func:`rod_sim.core.ledger.diagnostic_values`)
        at the last period's end; {} for a plain chain."""
        if self.spacecraft is None:
            return {}
        snap = self.last_state if self.last_state is not None else self.sim.snapshot()
        return diagnostic_strings(diagnostic_values(snap, self.spacecraft))

    def take_events(self) -> list:
        """The simulator's hinge events since the last call (or the start, or a reset), each
        given once."""
        events = self.sim.events[self.events_seen:]
        self.events_seen = len(self.sim.events)
        return events

    def take_extremes(self) -> tuple[float, float]:
        """max |alpha|, max |beta| [rad] since the last call (then start again)."""
        out = (self.max_alpha, self.max_beta)
        self.max_alpha = self.max_beta = 0.0
        return out

    def note_state(self, snap: Snapshot) -> None:
        """Count a published state's end slopes in the extremes."""
        if snap.alpha.size:     # the arrays' own max: np.max's wrapper costs as much again
            self.max_alpha = max(self.max_alpha, float(np.abs(snap.alpha).max()))
            self.max_beta = max(self.max_beta, float(np.abs(snap.beta).max()))

    def run(self, held, at_start: Callable[[int], None] | None = None) -> Snapshot | None:
        """One period holding ``held`` ((n, 3) [X, Y, T], (n + 2, 3) with the base's and the
        wheel's rows, or (n, 2) forces) plus the scene's
        scripted loads; ``at_start(t_ns)`` is called once the inputs are set. Returns the
        snapshot at the period's end, or None (``error`` set, state unchanged) on failure."""
        sim = self.sim
        held = full_inputs(held, sim.model.n)
        sim.set_held(held)
        if at_start is not None:
            at_start(sim.t_ns)
        held = sim.held         # its own copy: a State may be evaluated later (its span's end)
        last = self._balance_end
        jump = None
        here = last is not None and last[0] == sim.t_ns and last[2] is sim.y
        if here and last[1].shape == held.shape and (last[1] == held).all():
            self.held_for += 1
        else:       # one right-hand side gives the slopes and the rate's direction
            self.book()                      # the pending span ends here, with its inputs
            # the last period's end with the new inputs: what they do not change is shared
            state = (last[4].with_held(held) if here else
                     self.model.state(sim.t, sim.y, held, sim.mode, data=sim.data))
            self._span_start = balance_sample(self.model, sim.t, sim.y, held, sim.mode,
                                              state=state, energy=False)
            self._span_ns = sim.t_ns
            self._book_spacecraft(held, state)  # the inputs changed: their rates from now on
            self.held_for = 0
            jump = self._jump(last, state) if here else None
        kink = self._kink_in(sim.t_ns)
        if kink:
            self.book()              # a span never holds a scripted load's breakpoint inside
        work = self.budget.work(sim)
        start = time.perf_counter_ns()
        try:
            # advance() never hands out a non-finite state and, when it raises, leaves the
            # simulator at the period's start (hinge latches and events included)
            self.ahead.advance(self.period_ns, ahead_periods(
                self.ahead_limit, self.held_for, sim.carry.h, self.period_ns))
        except (IntegrationError, ArithmeticError) as exc:
            self.error = self._failure(exc, work, start)
            return None
        self.meter.add_step(self.period_ns, time.perf_counter_ns() - start)
        # one State for the snapshot, the balance sample and the momentum ledger: each
        # quantity (the right-hand side with the slopes, the momentum, the powers) once
        state = self.model.state(sim.t, sim.y, held, sim.mode, data=sim.data)
        snap = self.model.snapshot(sim.t, sim.y, held, sim.mode, state=state)
        self._balance_end = (sim.t_ns, held, sim.y, sim.mode, state)
        self.last_state = snap
        self.validity.update(sim.t, sim.y, held[:sim.model.n], snap.alpha, snap.beta, jump)
        if len(sim.events) > self.events_seen or self.ahead_limit <= 1 or kink or \
                sim.t_ns - self._span_ns >= LEDGER_SPAN_S * NS_PER_S:
            self.book(events=sim.events[self.events_seen:])
        return snap

    def _jump(self, last, state):
        """The jump of the quasi-static end slopes at the period's start, where the held
        inputs changed: (t [s], |slopes after - slopes before| (2n,) [rad], alpha then beta)
        from the last period's end State ``last[4]`` (the old inputs) and the start's
        ``state`` (the new ones), at the same time, state and latches: what the validity
        monitor judges (:meth:`~rod_sim.core.validity.ValidityMonitor.update`), both slopes
        already solved for the snapshot and the balance sample. None when the monitor judges
        no jumps. (Without such an end, the first period or after a reset, the caller gives
        None: the monitor then checks the held inputs itself.)"""
        sim = self.sim
        if not self.validity.judges_jumps:
            return None
        a0, b0 = last[4].bending
        a1, b1 = state.bending
        n = a0.size
        jump = np.empty(2 * n)
        np.subtract(a1, a0, out=jump[:n])
        np.subtract(b1, b0, out=jump[n:])
        return sim.t, np.abs(jump, out=jump)

    def _kink_in(self, t_ns: int) -> bool:
        """Whether a scripted load or a prescribed base motion has a breakpoint in the period
        (t_ns, t_ns + period] (its power, or the power's rate, may jump there)."""
        breaks = self._breaks_ns
        k = bisect.bisect_right(breaks, t_ns)
        return k < len(breaks) and breaks[k] <= t_ns + self.period_ns

    def book(self, events=()) -> None:
        """Book the span from the last booked sample to the end of the last period (its
        energy balance sample, the momentum ledger), if not booked yet; ``events``: the
        hinge events inside it."""
        end = self._balance_end
        if end is None or self._span_start is None or end[0] == self._span_ns:
            return
        t_ns, held, y, mode, state = end
        t = t_ns / NS_PER_S
        sample = balance_sample(self.model, t, y, held, mode, state=state)
        self.ledger.add(self._span_start, sample, events)
        self._span_start, self._span_ns = sample, t_ns
        if self.spacecraft is not None:
            self.spacecraft.add(t, y, held, mode, state=state)
        self.validity.update_energy(t, self.ledger.residual, self.ledger.scale,
                                    self.ledger.unresolved)

    def _failure(self, exc: Exception, work, start_ns: int) -> str:
        """The one-line cause of a failed period, naming the work budget when it ran out."""
        sim, b = self.sim, self.budget
        if b.exceeded(sim, work):
            exc = IntegrationError(
                f"work budget exceeded: the period needs more than {b.limit} {b.unit} "
                f"(~{b.seconds:g} s of wall time, max_period_cost; took "
                f"{(time.perf_counter_ns() - start_ns) / 1e9:.3g} s); "
                + (exc.reason if isinstance(exc, IntegrationError) else one_line(exc)),
                exc.t if isinstance(exc, IntegrationError) else sim.t)
        if isinstance(exc, IntegrationError):
            reason, t = exc.reason, exc.t
        else:  # an arithmetic failure inside the stepper, e.g. a division by zero
            reason, t = f"{type(exc).__name__}: {one_line(exc)}", sim.t
        return f"{reason} at t = {t:.6g} s ({self.model.name} model, {sim.integrator.describe()})"
