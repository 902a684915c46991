"""The simulator: owns simulated time, the state and the held inputs (nodal forces and hinge
motor moments).

Time is kept as integer nanoseconds so that repeated ``advance`` calls land exactly on the
stamps a ROS node or a log uses (no drift from summing float periods).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .integrators import (Carry, Integrator, IntegrationError, Stats, drive, explain_state,
                          make_integrator)
from .models import ChainModel
from .snapshot import Snapshot
from .units import NS_PER_S


def seconds_to_ns(t: float) -> int:
    """Round a time [s] to integer nanoseconds."""
    return int(round(float(t) * NS_PER_S))


@dataclass(frozen=True, eq=False)
class Trajectory:
    """States of a model sampled at times ``t`` (N,) [s]: ``y`` (N, state_size); ``modes``
    (N, n) bool: the latches fired at each sample (None: none)."""

    model: ChainModel
    t: np.ndarray
    y: np.ndarray
    modes: np.ndarray | None = None

    @property
    def phi(self) -> np.ndarray:
        """(N, n) rod angles [rad]."""
        return self.model.phi(self.y)

    @property
    def phi_rate(self) -> np.ndarray:
        """(N, n) rod rates [rad/s]."""
        return self.model.phi_rate(self.y)

    def snapshot(self, i: int, held=None) -> Snapshot:
        mode = None if self.modes is None else self.modes[i]
        return self.model.snapshot(float(self.t[i]), self.y[i], held, mode)

    def at(self, t: float) -> np.ndarray:
        """The state at a sample time t [s] (must be one of ``self.t`` to 1 ns)."""
        i = int(np.argmin(np.abs(self.t - t)))
        if abs(self.t[i] - t) > 1e-9:
            raise KeyError(f"t = {t} s is not a sample time of this trajectory")
        return self.y[i]


class Simulator:
    """Steps one model with one integrator; nodal forces are held between calls. The model
    and the integrator are constants (scene, compiled parameters; settings): the kernels'
    scratch is the simulator's :attr:`data` (``model.new_data()``) and what the integrator
    carries between calls (step size, workspace, work counters) its :attr:`carry`, so any
    number of simulators may share one model and one integrator."""

    def __init__(self, model: ChainModel, integrator: Integrator | None = None):
        self.model = model
        self.integrator = integrator if integrator is not None else make_integrator()
        self.data = model.new_data()
        self.carry: Carry = self.integrator.init(model)
        self.reset()

    @property
    def stats(self) -> Stats:
        """Work counters of this simulator's integration since it was made (kept by reset)."""
        return self.carry.stats

    def configure(self, **settings) -> None:
        """Change integrator settings (e.g. ``max_steps``, ``max_step``) from now on; the
        carried step size and workspace stay."""
        self.integrator = replace(self.integrator, **settings)

    def reset(self) -> None:
        """Back to the scene's initial state at t = 0 with zero held forces."""
        self.t_ns = 0
        self.events = []    # hinge events (latch, stop contact), see rod_sim.core.hinges
        self.mode = np.zeros(self.model.n, dtype=bool)    # which latches have fired
        self.y = self.model.initial_state()
        self.contact = self.model.contact_state(self.y, self.t)   # stop contacts (+1, -1, 0)
        self.held = np.zeros((self.model.n, 3))     # X, Y [N] at nodes 1..n; T [N m], hinges
        # (set_held: (n + 2, 3) with the base's and the wheel's rows)
        self.carry.restart()

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return self.t_ns / NS_PER_S

    def set_forces(self, forces) -> None:
        """Hold nodal forces (n, 2) or flat [X_1, Y_1, ..., X_n, Y_n] [N] from now on (the
        held hinge torques stay)."""
        f = np.asarray(forces, dtype=float).reshape(self.model.n, 2)
        if not np.all(np.isfinite(f)):
            raise ValueError("forces: non-finite value")
        held = self.held.copy()
        held[:self.model.n, :2] = f
        self.held = held

    def set_held(self, held) -> None:
        """Hold every input from now on: (n, 3) [X, Y [N], T [N m]] per node and hinge, or
        (n + 2, 3) with the kernels' base row n (Fx, Fy [N] in Oxy at the base's centre of
        mass, moment [N m]) and wheel row n + 1 (motor torque in column 2 [N m]); a free base
        is moved by them, other bases ignore those rows."""
        n = self.model.n
        h = np.array(held, dtype=float)
        if h.shape not in ((n, 3), (n + 2, 3)):
            raise ValueError(f"held inputs: expected shape ({n}, 3) or ({n + 2}, 3), got "
                             f"{h.shape}")
        if not np.isfinite(h).all():
            raise ValueError("held inputs: non-finite value")
        self.held = h

    def set_hinge_torques(self, torques) -> None:
        """Hold motor moments T_h (n,) [N m] at hinges 0..n-1 from now on (the held nodal
        forces stay): T_h acts +T on rod h+1 and -T on rod h (hinge 0: on rod 1 against the
        ground), added to the hinge's elastic and viscous moments, in every model."""
        t = np.asarray(torques, dtype=float).reshape(self.model.n)
        if not np.all(np.isfinite(t)):
            raise ValueError("torques: non-finite value")
        held = self.held.copy()
        held[:self.model.n, 2] = t
        self.held = held

    def advance(self, dt: float) -> None:
        """Advance by dt [s] (rounded to whole ns) holding the current forces."""
        dt_ns = seconds_to_ns(dt)
        if dt_ns <= 0:
            raise ValueError(f"dt: must be > 0 (got {dt!r})")
        t1_ns = self.t_ns + dt_ns
        self._integrate([t1_ns / NS_PER_S])
        self.t_ns = t1_ns

    def sample(self, t_out_ns) -> np.ndarray:
        """Advance to the last of the sorted integer-ns times ``t_out_ns`` (all >= now) holding
        the current forces; returns the states there (len(t_out_ns), state_size). Hinge
        events on the way are handled and recorded as by ``run``."""
        t_out_ns = np.asarray(t_out_ns, dtype=np.int64)
        if t_out_ns.size == 0 or t_out_ns[0] < self.t_ns or np.any(np.diff(t_out_ns) < 0):
            raise ValueError("t_out_ns: sorted times from the current time on are needed")
        t = t_out_ns / NS_PER_S
        Y, _ = self._integrate(t)
        self.t_ns = int(t_out_ns[-1])
        return Y

    def _integrate(self, t_out):
        """(states, modes) at t_out from now through the one driver; when it raises, the
        simulator is left as it was (mode, contacts and events included)."""
        n_events = len(self.events)
        try:
            out = drive(self.model, self.integrator, self.y, self.t, t_out, self.held,
                        self.mode, self.events, self.contact, self.carry, self.data)
            self._check_finite(np.asarray(t_out, dtype=float), out.Y)
        except BaseException:
            del self.events[n_events:]
            raise
        self.mode, self.y, self.contact = out.mode, out.y, out.contact
        return out.Y, out.modes

    def _check_finite(self, t: np.ndarray, Y: np.ndarray) -> None:
        """Never hand out a NaN: IntegrationError naming the first non-finite sample."""
        if np.isfinite(Y).all():        # one pass; the row is found only when one is bad
            return
        i = int(np.argmax(~np.all(np.isfinite(Y), axis=1)))
        raise IntegrationError("the state became non-finite (NaN/Inf); "
                               + explain_state(self.model, float(t[i]), Y[i], self.held),
                               float(t[i]))

    def snapshot(self) -> Snapshot:
        """The chain now."""
        return self.model.snapshot(self.t, self.y, self.held, self.mode)

    def run(self, t_end: float, rate_hz: float = 100.0) -> Trajectory:
        """Integrate from now to t_end [s], sampling every 1/rate_hz [s] of simulated time
        (sample times are whole ns: round(k * 1e9 / rate_hz)). Returns the samples,
        including the current state as the first one."""
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate: must be > 0 (got {rate_hz!r})")
        end_ns = seconds_to_ns(t_end)
        if end_ns <= self.t_ns:
            raise ValueError(f"t_end: must be after the current time {self.t} s (got {t_end!r})")
        period = NS_PER_S / rate_hz
        k0 = int(np.ceil(self.t_ns / period - 1e-9))
        ticks = np.round(np.arange(k0, int(np.floor(end_ns / period + 1e-9)) + 1) * period)
        ticks = ticks[(ticks >= self.t_ns) & (ticks <= end_ns)].astype(np.int64)
        if ticks.size == 0 or ticks[0] != self.t_ns:
            ticks = np.concatenate([[self.t_ns], ticks])
        if ticks[-1] != end_ns:
            ticks = np.concatenate([ticks, [end_ns]])
        t = ticks / NS_PER_S
        Y, modes = self._integrate(t)
        self.t_ns = end_ns
        return Trajectory(self.model, t, Y, modes if modes.any() else None)
