"""One control period of the node with its outputs, without ROS: :class:`Stepper` runs a
:class:`~rod_sim.ros.period.PeriodRunner` period and sends what it gives through
:class:`~rod_sim.ros.outputs.Outputs`: the inputs applied from the period's start
(``applied_forces``, ``applied_torques``, ``applied_base``), then at its end ``/clock``
(:class:`~rod_sim.ros.outputs.SimClock`), the state topics and the period's hinge events.
"""
from __future__ import annotations

from rod_sim.core.snapshot import Snapshot
from rod_sim.core.units import NS_PER_S
from rod_sim.ros.applied_base import base_values


class Stepper:
    """Periods of ``period`` (a :class:`~rod_sim.ros.period.PeriodRunner`) sent to
    ``outputs`` (:class:`~rod_sim.ros.outputs.Outputs`) and ``clock``
    (:class:`~rod_sim.ros.outputs.SimClock`)."""

    def __init__(self, period, outputs, clock):
        self.period, self.outputs, self.clock = period, outputs, clock
        self.sim, self.model = period.sim, period.model
        self.free_base = outputs.scene.base.mode == "free"

    def run(self, held) -> bool:
        """One period holding ``held`` ((n, 3) [X, Y, T], (n + 2, 3) with a free base's rows,
        or (n, 2) forces) and its outputs; False when the integration failed (then
        ``period.error`` says why and nothing of the period's end is sent)."""
        snap = self.period.run(held, self.applied)
        if snap is None:
            return False
        self.state(snap)
        self.outputs.events(self.period.take_events())
        return True

    def applied(self, t_ns: int) -> None:
        """The inputs applied from ``t_ns`` [ns] on, from the kernels' load table at ``t_ns``
        (the held inputs plus the scene's scripted loads; n rows, n + 2 with a free base) and
        the held inputs: the nodal forces [N] of the table, the commanded hinge torques [N m]
        and, on a free base, the base's [Fx, Fy, M, T_w]
        (:func:`~rod_sim.ros.applied_base.base_values`)."""
        n, held = self.outputs.scene.n, self.sim.held
        loads = self.model.loads_at(t_ns / NS_PER_S, held)
        self.outputs.applied(t_ns, loads[:n, :2].copy(), held[:n, 2].copy(),
                             base_values(loads) if self.free_base else None)

    def state(self, snap: Snapshot) -> None:
        """The state ``snap`` at the simulator's time: counted in the period's extremes, then
        ``/clock`` (first: no output is stamped later than the clock), then the state topics."""
        self.period.note_state(snap)
        self.clock.publish(self.sim.t_ns)
        self.outputs.state(snap, self.sim.t_ns)

    def start(self) -> None:
        """At the start or after a reset: the applied inputs published again whatever they
        are, the descriptions (``robot_description``, ``scene``) and the state now."""
        self.outputs.forget_applied()
        self.outputs.descriptions(self.sim.t_ns)
        self.state(self.sim.snapshot())
