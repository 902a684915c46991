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
O(n) checks: vectorised, no loop over rods.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from rod_sim.core.integrators import IntegrationError
from rod_sim.core.ledger import SpacecraftLedger, diagnostic_strings, diagnostic_values
from rod_sim.core.snapshot import Snapshot
from rod_sim.core.units import NS_PER_S
from rod_sim.core.validity import ValidityMonitor, balance_sample
from rod_sim.ros.errors import one_line
from rod_sim.ros.monitor import EnergyLedger
from rod_sim.ros.pacing import RateMeter


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
    ``period_ns`` [ns] at a time within ``budget`` (a :class:`~rod_sim.ros.budget.WorkBudget`)."""

    def __init__(self, sim, budget, period_ns: int):
        self.sim = sim
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
        """(t_ns, held, BalanceSample) at the end of the last period (the next start when
        the held inputs did not change)."""

    def energy(self, held: np.ndarray) -> float:
        sim = self.sim
        return self.model.energies(sim.t, sim.y, held, mode=sim.mode).total

    def reset(self) -> None:
        """The simulator back at t = 0 and the bookkeeping started afresh."""
        self.sim.reset()
        self.events_seen = 0
        self.error = None
        self.ledger.start(self.energy(self.sim.held))
        if self.spacecraft is not None:
            self.spacecraft.start()
        self.last_state = None
        self._book_spacecraft(self.sim.held)
        self._balance_end = None
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

    def take_extremes(self) -> tuple[float, float]:
        """max |alpha|, max |beta| [rad] since the last call (then start again)."""
        out = (self.max_alpha, self.max_beta)
        self.max_alpha = self.max_beta = 0.0
        return out

    def note_state(self, snap: Snapshot) -> None:
        """Count a published state's end slopes in the extremes."""
        self.max_alpha = max(self.max_alpha, float(np.max(np.abs(snap.alpha), initial=0.0)))
        self.max_beta = max(self.max_beta, float(np.max(np.abs(snap.beta), initial=0.0)))

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
        last = self._balance_end
        if last is not None and last[0] == sim.t_ns and np.array_equal(last[1], held):
            start_sample = last[2]
        else:       # one right-hand side gives the slopes and the rate's direction
            state = self.model.state(sim.t, sim.y, held, sim.mode, data=sim.data)
            start_sample = balance_sample(self.model, sim.t, sim.y, held, sim.mode, state=state)
            self._book_spacecraft(held, state)  # the inputs changed: their rates from now on
        work = self.budget.work(sim)
        start = time.perf_counter_ns()
        try:
            # advance() never hands out a non-finite state and, when it raises, leaves the
            # simulator at the period's start (hinge latches and events included)
            sim.advance(self.period_ns / NS_PER_S)
        except (IntegrationError, ArithmeticError) as exc:
            self.error = self._failure(exc, work, start)
            return None
        self.meter.add_step(self.period_ns, time.perf_counter_ns() - start)
        # one State for the snapshot, the balance sample and the momentum ledger: each
        # quantity (the right-hand side with the slopes, the momentum, the powers) once
        state = self.model.state(sim.t, sim.y, held, sim.mode, data=sim.data)
        snap = self.model.snapshot(sim.t, sim.y, held, sim.mode, state=state)
        end_sample = balance_sample(self.model, sim.t, sim.y, held, sim.mode, state=state)
        self.ledger.add(start_sample, end_sample, sim.events[self.events_seen:])
        self._balance_end = (sim.t_ns, held.copy(), end_sample)
        self._book_spacecraft(held, state)
        self.last_state = snap
        self.validity.update(sim.t, sim.y, held[:sim.model.n], snap.alpha, snap.beta)
        self.validity.update_energy(sim.t, self.ledger.residual, self.ledger.scale,
                                    self.ledger.unresolved)
        return snap

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
