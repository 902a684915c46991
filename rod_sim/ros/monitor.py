"""Health bookkeeping for the node's ``diagnostics`` topic (pure Python, no ROS).

- :class:`EnergyLedger`: the energy balance E - E0 - integral(net power) dt + (latch impact
  losses), the integral taken per control period (split at the hinge events).
- :class:`DiagnosticReport`: the values of one ``diagnostics`` message and its level/message,
  from plain numbers the node collects.
- :class:`NodeMonitor`: the report and the ``diagnostics`` message of the node's parts over a
  window of wall time, and the start of the next window.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from rod_sim.core.validity import SMALL_BENDING_RAD, EnergyBalance
from rod_sim.io import topics
from rod_sim.io.topics import DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN

BENDING_WARN_RAD = SMALL_BENDING_RAD
"""[rad] end slope above which the small-bending assumption is reported as questionable
(justified in :mod:`rod_sim.core.validity`)."""
RTF_WARN_FRACTION = 0.9
"""A measured real-time factor below this fraction of the target is reported (WARN)."""
MIN_RTF_WINDOW_S = 0.5
"""[s] of wall time a window needs before its measured real-time factor is judged."""
DIAGNOSTICS_PERIOD_S = 1.0
"""[s] wall period of the node's ``diagnostics`` (a window of :class:`NodeMonitor`)."""


class EnergyLedger(EnergyBalance):
    """Mechanical energy balance of the chain over simulated time: the core's
    :class:`~rod_sim.core.validity.EnergyBalance` (the same balance ``simulate`` judges), fed
    per control period: ``add(start, end, events)`` with the
    :class:`~rod_sim.core.validity.BalanceSample` s of the period's start and end (energy, net
    power and its rate, the full model's unpaired term) and the hinge events of the period
    (latch impacts' kinetic energy losses booked, the work integral split where the power
    jumps); ``residual`` = E - E0 - W + D [J]."""


@dataclass
class DiagnosticReport:
    """Everything one ``diagnostics`` status says; :meth:`status` gives level, message, values.

    Times in [s], costs in [ms], energies in [J], slopes in [rad]. ``rtf_target`` 0 means as
    fast as possible, None lockstep (no target). ``wall_window`` [s] is the wall time the
    measured factor and costs cover. ``error`` is the cause of an integration failure.
    """

    mode: str
    state: str
    sim_time: float
    rtf_target: float | None
    rtf_measured: float
    wall_window: float
    step_cost_mean: float
    step_cost_max: float
    step_budget: float | None
    steps: int
    dropped_periods: int
    energy: float
    energy_residual: float
    commands_received: int
    commands_rejected: int
    last_rejection: str
    command_active: bool
    max_abs_alpha: float
    max_abs_beta: float
    model: str
    integrator: str
    error: str | None = None
    recording_error: str | None = None
    """Why the recording stopped (the log could not be written or opened), None if fine."""
    name_conflict: str | None = None
    """The warning when other nodes on the graph have this node's full name, None if none."""
    unknown_parameters: tuple[str, ...] = ()
    """Overrides given at start-up that name no parameter of the node (ignored)."""
    extra: dict[str, str] = field(default_factory=dict)
    validity: list[str] = field(default_factory=list)
    """Messages of the validity monitor (:mod:`rod_sim.core.validity`) since the last reset."""

    def _warnings(self) -> list[str]:
        out = []
        running = self.state == "running"
        if (running and self.rtf_target and self.wall_window >= MIN_RTF_WINDOW_S
                and self.rtf_measured < RTF_WARN_FRACTION * self.rtf_target):
            out.append(f"slower than real time: measured RTF {self.rtf_measured:.3g} < target "
                       f"{self.rtf_target:g}")
        bend = max(self.max_abs_alpha, self.max_abs_beta)
        if bend > BENDING_WARN_RAD:
            out.append(f"large bending slope {bend:.3g} rad (small-bending assumption "
                       f"questionable above {BENDING_WARN_RAD} rad)")
        if self.name_conflict:
            out.append(self.name_conflict)
        out.extend(self.validity)
        return out

    def status(self) -> tuple[int, str, dict[str, str]]:
        """(level 0 OK / 1 WARN / 2 ERROR, one-line message, key -> value strings)."""
        if self.error:
            level, message = DIAGNOSTIC_ERROR, f"paused after an integration error: {self.error}"
        elif self.recording_error:
            level, message = DIAGNOSTIC_ERROR, f"recording stopped: {self.recording_error}"
        else:
            warnings = self._warnings()
            level = DIAGNOSTIC_WARN if warnings else DIAGNOSTIC_OK
            message = "; ".join(warnings) if warnings else f"{self.state} ({self.mode})"
        return level, message, self.values()

    def values(self) -> dict[str, str]:
        """The key/value pairs of the status (units in the key names)."""
        def num(x: float | None) -> str:
            return "n/a" if x is None or not math.isfinite(x) else f"{x:.6g}"

        values = {
            "mode": self.mode,
            "state": self.state,
            "sim_time_s": f"{self.sim_time:.9f}",
            "real_time_factor_target": ("lockstep" if self.rtf_target is None else
                                        "as fast as possible" if self.rtf_target == 0 else
                                        num(self.rtf_target)),
            "real_time_factor_measured": num(self.rtf_measured),
            "window_wall_s": num(self.wall_window),
            "step_cost_mean_ms": num(self.step_cost_mean),
            "step_cost_max_ms": num(self.step_cost_max),
            "step_budget_ms": num(self.step_budget),
            "steps_in_window": str(self.steps),
            "dropped_periods": str(self.dropped_periods),
            "energy_J": num(self.energy),
            "energy_balance_residual_J": num(self.energy_residual),
            "commands_received": str(self.commands_received),
            "commands_rejected": str(self.commands_rejected),
            "last_rejection": self.last_rejection or "none",
            "command_active": "true" if self.command_active else "false",
            "max_abs_alpha_rad": num(self.max_abs_alpha),
            "max_abs_beta_rad": num(self.max_abs_beta),
            "model": self.model,
            "integrator": self.integrator,
            "error": self.error or "none",
            "recording_error": self.recording_error or "none",
            "validity": "; ".join(self.validity) or "ok",
            "name_conflict": "true" if self.name_conflict else "false",
            "unknown_parameters": ", ".join(self.unknown_parameters) or "none",
        }
        values.update(self.extra)
        return values


class NodeMonitor:
    """The node's ``diagnostics`` from its parts, without ROS: ``control``
    (:class:`~rod_sim.ros.control.RunControl`), ``period``
    (:class:`~rod_sim.ros.period.PeriodRunner`: its simulator, work budget, meter, ledgers and
    extremes), ``inputs`` (:class:`~rod_sim.ros.inputs.Inputs`), ``pacing``
    (:class:`~rod_sim.ros.pacing.Pacing`: its ``dropped`` periods), ``recording``
    (:class:`~rod_sim.ros.recording.NodeRecording`: the log and why it stopped), ``rate_hz``
    [Hz] (the control rate) and ``node`` (the node's full name). The node sets the start-up
    findings: ``unknown_parameters`` (overrides naming no parameter) and ``name_conflict`` (the
    warning when another node has this name, from :func:`~rod_sim.ros.process.same_name_warning`).
    """

    def __init__(self, control, period, inputs, pacing, recording, rate_hz: float, node: str):
        self.control, self.period, self.inputs = control, period, inputs
        self.pacing, self.recording = pacing, recording
        self.rate_hz, self.node = rate_hz, node
        self.unknown_parameters: tuple[str, ...] = ()
        self.name_conflict: str | None = None

    def report(self) -> DiagnosticReport:
        """The health of the simulation over the window since the last :meth:`new_window`."""
        control, period, inputs, sim = self.control, self.period, self.inputs, self.period.sim
        wall = time.monotonic_ns()
        meter, ledger, log = period.meter, period.ledger, self.recording.path
        mean_ms, max_ms = meter.step_cost_ms()
        rtf_target = None if control.sync_mode else control.rtf
        intakes = inputs.intakes.values()
        extra = {"scene": period.model.scene.name, "rate_hz": f"{self.rate_hz:g}",
                 "recording": str(log) if log else "off",
                 "work_budget": period.budget.describe(), "node": self.node}
        return DiagnosticReport(
            mode=control.mode(), state=control.state(inputs.any_command()), sim_time=sim.t,
            rtf_target=rtf_target, rtf_measured=meter.real_time_factor(wall),
            wall_window=meter.window_s(wall), step_cost_mean=mean_ms, step_cost_max=max_ms,
            step_budget=(period.period_ns / 1e6 / control.rtf) if rtf_target else None,
            steps=meter.steps, dropped_periods=self.pacing.dropped, energy=ledger.energy,
            energy_residual=ledger.residual,
            commands_received=inputs.total("received"),
            commands_rejected=inputs.total("rejected"),
            last_rejection=inputs.rejection, command_active=any(i.active for i in intakes),
            max_abs_alpha=period.max_alpha, max_abs_beta=period.max_beta,
            model=period.model.name, integrator=sim.integrator.describe(),
            error=control.error, recording_error=self.recording.error,
            name_conflict=self.name_conflict, unknown_parameters=self.unknown_parameters,
            validity=[f.message for f in period.validity.findings() if f.kind != "bending"],
            extra={**extra, **inputs.counts(), **period.spacecraft_values()})

    def message(self) -> dict:
        """One ``diagnostics`` message (:func:`rod_sim.io.topics.diagnostics`) of
        :meth:`report`, stamped at the simulated time, its status named
        :data:`~rod_sim.io.topics.DIAGNOSTICS_STATUS_NAME`."""
        level, message, values = self.report().status()
        sim = self.period.sim
        return topics.diagnostics(sim.t, values, self.period.model.scene.name, level=level,
                                  message=message, frame_id="",
                                  name=topics.DIAGNOSTICS_STATUS_NAME)

    def new_window(self) -> None:
        """Start a new window: the step-cost meter and the extreme slopes from now on."""
        self.period.meter.restart(time.monotonic_ns())
        self.period.take_extremes()
