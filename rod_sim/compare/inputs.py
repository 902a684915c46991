"""The logged inputs of ``rod-sim compare``: the held commands rebuilt from ``/applied_forces``
and ``/applied_torques`` (:class:`HeldInputs`: integration bounds and held (n, 3) = [X, Y, T]
inputs [N, N, N m] per segment) and the time line of the ``/rod_states`` samples
(:class:`SampleTimeline`: sampling period and gaps). Both refuse a history with a hole
(:class:`CompareInputError`). Times are integer ns.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rod_sim.core.units import NS_PER_S

GAP_FACTOR = 1.5
"""A time step larger than GAP_FACTOR sampling periods between consecutive messages is a gap."""
MAX_LISTED_GAPS = 100
"""State gaps listed in the report (all are counted)."""


class CompareInputError(ValueError):
    """The log cannot be compared (wrong scene size, incomplete force history, ...): one line."""


@dataclass(frozen=True)
class _History:
    """How the messages of one held input are named in the refusals."""

    topic: str          # "/applied_forces"
    history: str        # "applied-force": "the applied-force history cannot be rebuilt"
    gap_history: str    # "force": "so the force history cannot be rebuilt" (after a gap)
    values: str         # "forces": "the forces before it are unknown"


FORCES = _History("/applied_forces", "applied-force", "force", "forces")
TORQUES = _History("/applied_torques", "hinge-torque", "hinge-torque", "torques")


def _split(items: list, t_cut: int) -> tuple[list, list]:
    """(the (t_ns, ...) items at or before ``t_cut`` [ns], the rest), in order."""
    return [x for x in items if x[0] <= t_cut], [x for x in items if x[0] > t_cut]


def _require_start(h: _History, taken: list, t_cut: int) -> None:
    """Refuse a history that has no message up to ``t_cut`` [ns] or does not start at 0."""
    if not taken:
        raise CompareInputError(f"no {h.topic} messages up to t = {t_cut / NS_PER_S:.9g} s, so "
                                f"the {h.history} history cannot be rebuilt")
    if taken[0][0] != 0:
        raise CompareInputError(f"{h.topic} starts at t = {taken[0][0] / NS_PER_S:.9g} s, not 0: "
                                f"the {h.values} before it are unknown")


def _require_no_gap(h: _History, last: int | None, t: int, period: float,
                    end: bool = False) -> None:
    """Refuse a step from the last message at ``last`` [ns] to ``t`` [ns] (the next message,
    or with ``end`` the last state) longer than GAP_FACTOR sampling periods [ns]."""
    if last is None or not t - last > GAP_FACTOR * period:
        return
    if end:
        raise CompareInputError(f"{h.topic} ends at t = {last / NS_PER_S:.9g} s but the states "
                                f"go on to {t / NS_PER_S:.9g} s: messages are missing")
    raise CompareInputError(f"{h.topic} has a gap longer than {GAP_FACTOR:g} sampling periods "
                            f"({last / NS_PER_S:.9g} s to {t / NS_PER_S:.9g} s): messages are "
                            f"missing, so the {h.gap_history} history cannot be rebuilt")


class HeldInputs:
    """The applied-force and hinge-torque messages of a log (``log``: a LogStream, for its
    message decoding and whether it has torques), buffered until a window takes them: the held
    part of the forces is ``applied(t_i) - scripted(t_i)`` (``scripted_forces(t [s])``: the
    scene's loads (n, 2) [N]); torques are held as logged. Counts messages and segments and
    the largest |held| force [N] and torque [N m]."""

    def __init__(self, log, n: int, scripted_forces, scripted_base=None):
        self.log = log
        self.scripted_forces = scripted_forces
        self.scripted_base = scripted_base
        """``scripted_base(t [s]) -> (2, 3)``: the scene's base and wheel rows of the load
        table (a free base; None otherwise): ``applied_base`` less them is held."""
        self.base_msgs: list[tuple[int, np.ndarray]] = []
        self.held_base: np.ndarray | None = None
        self.applied: list[tuple[int, np.ndarray]] = []
        self.torque_msgs: list[tuple[int, np.ndarray]] = []
        self.held: np.ndarray | None = None
        self.held_force = np.zeros((n, 2))
        self.held_torque = np.zeros(n)
        self.last_applied: int | None = None
        self.last_torque: int | None = None
        self.applied_messages = 0
        self.torque_messages = 0
        self.segments = 0
        self.max_held = 0.0
        self.max_torque = 0.0

    def take(self, t_cut: int, period: float) -> tuple[list[int], list[np.ndarray]]:
        """Integration bounds and held commands up to ``t_cut`` from the buffered applied
        forces (held = applied - scripted loads; consecutive equal commands merged); refuses
        a force history with a hole."""
        use, self.applied = _split(self.applied, t_cut)
        if self.last_applied is None:
            _require_start(FORCES, use, t_cut)
        torques, self.torque_msgs = _split(self.torque_msgs, t_cut)
        if self.log.has_torques and self.last_torque is None:
            _require_start(TORQUES, torques, t_cut)
        changes: dict[int, dict[str, np.ndarray]] = {}
        for t, applied in use:
            changes.setdefault(t, {})["forces"] = applied
        for t, value in torques:
            changes.setdefault(t, {})["torques"] = value
        bases, self.base_msgs = _split(self.base_msgs, t_cut)
        for t, value in bases:
            changes.setdefault(t, {})["base"] = value
        bounds, helds = [], []
        for t in sorted(changes):
            change = changes[t]
            if "forces" in change:
                applied = change["forces"]
                if applied.ndim == 1:
                    applied = self.log.applied_array(t, applied)
                _require_no_gap(FORCES, self.last_applied, t, period)
                self.last_applied = t
                self.applied_messages += 1
                self.held_force = applied - self.scripted_forces(t / NS_PER_S)
                self.max_held = max(self.max_held, float(np.max(np.abs(self.held_force))))
            if "torques" in change:
                value = self.log.torque_array(t, change["torques"])
                _require_no_gap(TORQUES, self.last_torque, t, period)
                self.last_torque = t
                self.torque_messages += 1
                self.held_torque = value
                self.max_torque = max(self.max_torque, float(np.max(np.abs(value))))
            if "base" in change and self.scripted_base is not None:
                fx, fy, m, tw = change["base"]
                self.held_base = np.array([[fx, fy, m], [0.0, 0.0, tw]]) \
                    - self.scripted_base(t / NS_PER_S)
            held = np.column_stack([self.held_force, self.held_torque])
            if self.held_base is not None:
                held = np.vstack([held, self.held_base])
            if self.held is None or not np.array_equal(held, self.held):
                bounds.append(t)
                helds.append(self.held)
                self.held = held
                self.segments += 1
        bounds.append(t_cut)
        helds.append(self.held)
        return bounds, helds

    def check_end(self, last_state: int, period: float) -> None:
        """Refuse a log whose force (or torque) messages end before its states do."""
        _require_no_gap(FORCES, self.last_applied, last_state, period, end=True)
        if self.log.has_torques and self.last_torque is not None:
            _require_no_gap(TORQUES, self.last_torque, last_state, period, end=True)

    def summary(self) -> dict:
        """The ``forces`` part of the report."""
        return {"messages": self.applied_messages, "segments": self.segments,
                "max_abs_held": self.max_held, "torque_messages": self.torque_messages,
                "max_abs_torque": self.max_torque}


class SampleTimeline:
    """The times [ns] of the ``/rod_states`` samples seen so far: the sampling period (from
    ``rate_hz`` [Hz], else the median step), the first and last time, the count and the gaps
    (steps longer than GAP_FACTOR periods; the first MAX_LISTED_GAPS listed in s)."""

    def __init__(self, rate_hz: float | None):
        self.rate_hz = rate_hz
        self.period: float | None = None
        self.first: int | None = None
        self.last: int | None = None
        self.count = 0
        self.gaps: list[tuple[float, float]] = []
        self.gap_count = 0

    def add(self, t_st: np.ndarray) -> None:
        """The sample times ``t_st`` (N,) [ns] of one window, in order."""
        if self.period is None:
            self.period = self._period(t_st)
            if t_st[0] > GAP_FACTOR * self.period:
                self._gap(0, int(t_st[0]))
        prev = self.last
        steps = np.diff(np.concatenate([[prev], t_st])) if prev is not None else np.diff(t_st)
        base = [prev] + list(t_st) if prev is not None else list(t_st)
        for i in np.flatnonzero(steps > GAP_FACTOR * self.period):
            self._gap(int(base[i]), int(base[i + 1]))
        if self.first is None:
            self.first = int(t_st[0])
        self.last = int(t_st[-1])
        self.count += t_st.size

    def _period(self, t: np.ndarray) -> float:
        rate = self.rate_hz
        if rate is not None and math.isfinite(rate) and rate > 0:
            return NS_PER_S / rate
        d = np.diff(t)
        d = d[d > 0]
        if d.size == 0:
            raise CompareInputError("only one /rod_states sample: nothing to compare over time")
        return float(np.median(d))

    def _gap(self, a: int, b: int) -> None:
        self.gap_count += 1
        if len(self.gaps) < MAX_LISTED_GAPS:
            self.gaps.append((a / NS_PER_S, b / NS_PER_S))
