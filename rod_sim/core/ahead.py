"""Periods integrated ahead: the integrator's natural steps across control periods while the
held inputs stay the same.

A node advances its :class:`~rod_sim.core.simulator.Simulator` one control period at a time;
``Simulator.advance`` ends an integrator step at every period's end, so a period never costs
less than one step (DOP853: 12 right-hand sides), however short it is. :class:`Ahead` lets
one drive cover ``k`` periods at once (outputs at each period's end, taken from the
integrator's dense output inside its steps: DOP853's is of order 7, accurate to the
tolerance) and serves the later periods' states from that buffer, one per call, as long as
the held inputs, the latched hinges and the simulator's state are those the buffer was
computed for. A change of any of them (a command, a timeout, a reset) drops the rest of the
buffer: the next period starts from the state at the period boundary where the change came,
exactly there. ``k`` = 1 is ``Simulator.advance`` itself, call for call (lockstep keeps its
bit-for-bit log that way).

The buffer keeps only the periods before the first hinge event the drive met (a latch or a
stop contact changes what the following states mean); when the first period itself has
one, or the drive fails (work budget, divergence), the period is advanced the ordinary way,
which then meets the event or reports the failure as it always did.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .integrators import IntegrationError, drive
from .units import NS_PER_S


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.array_equal(a, b)`` for arrays without NaN (held inputs are finite, latches
    bool), through their bytes first: equal bytes are the common case and cost ~0.4 us
    against ~2.5 us (n = 8)."""
    return (a.shape == b.shape and a.tobytes() == b.tobytes()) or np.array_equal(a, b)


class Ahead:
    """The buffer of periods integrated ahead for one simulator ``sim``. Costs one drive per
    ``k`` periods; O(k x state size) memory."""

    def __init__(self, sim):
        self.sim = sim
        self.served = 0
        """Periods served from the buffer (no integration) since this object was made."""
        self._forget()

    def _forget(self) -> None:
        self._t_ns = np.zeros(0, dtype=np.int64)    # (k,) period ends [ns]
        self._Y = None                              # (k, size) states there
        self._next = 0                              # index of the next period to serve
        self._held = None
        self._mode = None
        self._y = None                              # the state object last handed out

    def pending(self) -> int:
        """Periods left in the buffer (valid or not)."""
        return int(self._t_ns.size - self._next)

    def _valid(self, period_ns: int) -> bool:
        sim = self.sim
        i = self._next
        return (i < self._t_ns.size and sim.y is self._y
                and self._t_ns[i] - sim.t_ns == period_ns
                and _same(sim.held, self._held) and _same(sim.mode, self._mode))

    def advance(self, period_ns: int, k: int) -> bool:
        """Advance ``sim`` by one period of ``period_ns`` [ns] holding its current inputs:
        from the buffer when it holds this period, else through a drive over ``k`` >= 1
        periods (``k`` = 1: ``Simulator.advance``). Returns True when the period came from
        the buffer. Raises what ``Simulator.advance`` raises (the simulator then stays at
        the period's start)."""
        sim = self.sim
        if self._valid(period_ns):
            self._take()
            self.served += 1
            return True
        self._forget()
        if k > 1 and self._fill(period_ns, k):
            self._take()
            return False
        sim.advance(period_ns / NS_PER_S)
        return False

    def _take(self) -> None:
        sim, i = self.sim, self._next
        y = self._Y[i].copy()
        sim.y, sim.t_ns = y, int(self._t_ns[i])
        self._y = y
        self._next = i + 1

    def _fill(self, period_ns: int, k: int) -> bool:
        """One drive over k periods from the simulator's state into the buffer (the
        simulator itself untouched, its carried step size and counters updated); False when
        not even the first period could be kept (an event in it, or a failure)."""
        sim = self.sim
        t_ns = sim.t_ns + period_ns * np.arange(1, k + 1, dtype=np.int64)
        events: list = []
        carry = sim.carry
        stats, h = dataclasses.replace(carry.stats), carry.h
        try:
            out = drive(sim.model, sim.integrator, sim.y, sim.t, t_ns / NS_PER_S, sim.held,
                        sim.mode, events, sim.contact.copy(), carry, sim.data)
        except (IntegrationError, ArithmeticError):
            # not counted: the ordinary period that follows meets (and reports) its own
            # failure or work budget, as without the buffer
            carry.stats, carry.h = stats, h
            return False
        keep = k if not events else int(np.searchsorted(t_ns / NS_PER_S, events[0].t))
        finite = np.all(np.isfinite(out.Y[:keep]), axis=1)
        if not finite.all():
            keep = int(np.argmin(finite))
        if keep < 1:
            return False
        self._t_ns, self._Y = t_ns[:keep], out.Y[:keep]
        self._held, self._mode = sim.held.copy(), sim.mode.copy()
        self._next = 0
        return True
