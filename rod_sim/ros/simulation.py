"""Building the rod_sim node's simulation from its settings, without ROS: scene, model,
integrator, simulator, the control period and the measured work budget.

Every failure is a :class:`~rod_sim.ros.errors.NodeConfigError` naming its cause in one line
(a scene that cannot be found, loaded, fitted in memory, or even started from its initial state).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rod_sim.api import (IntegrationError, ModelError, Scene, SceneError, Simulator, load_scene,
                         make_integrator, make_model)
from rod_sim.core.units import NS_PER_S
from rod_sim.core.validity import balance_sample
from rod_sim.ros import budget
from rod_sim.ros.errors import NodeConfigError, one_line
from rod_sim.ros.outputs import BY_NAME, STATE_TOPICS
from rod_sim.ros.pacing import period_ns as control_period_ns
from rod_sim.ros.period import PeriodRunner
from rod_sim.ros.scene_path import ScenePathError, resolve_scene_file


@dataclass
class Simulation:
    """What a node simulates: the scene file found for ``scene_file`` (``scene_path``), the
    scene, model and simulator, the control period [ns] and the work budget (None until
    :func:`start`); ``note``: a warning about how the scene file was found ('' if none)."""

    scene_path: Path
    scene: Scene
    model: object
    sim: Simulator
    period_ns: int
    note: str = ""
    budget: object = None


def build(settings, full_name: str, params_files: tuple[str, ...]) -> Simulation:
    """The simulation of ``settings`` (:class:`~rod_sim.ros.parameters.NodeSettings`) for the
    node ``full_name``. Raises NodeConfigError."""
    s = settings
    try:
        path, note = resolve_scene_file(s.scene_file, full_name, params_files)
    except ScenePathError as exc:
        raise NodeConfigError(f"scene_file {exc}") from None
    try:
        scene = load_scene(path)
        model = make_model(s.model, scene)      # simulate's memory estimate first
        integrator = make_integrator(s.integrator, rtol=s.rtol)
        period = control_period_ns(s.rate_hz)
    except SceneError as exc:
        raise NodeConfigError(f"scene_file {s.scene_file}: {one_line(exc)}") from None
    except (ModelError, ValueError) as exc:
        raise NodeConfigError(one_line(exc)) from None
    except MemoryError:          # beyond the estimate: still one line, not a traceback
        raise NodeConfigError(f"scene_file {s.scene_file}: out of memory building the "
                              f"{s.model} model of {scene.n} rods") from None
    return Simulation(path, scene, model, Simulator(model, integrator), period, note or "")


def start(simulation: Simulation, settings) -> PeriodRunner:
    """Load the compiled kernels and the encoders' layouts once, before the clock starts, so
    that the first real period does not pay for them, measure the work budget (applied to the
    simulator) and return the period runner. A scene that cannot even start (e.g. phi =
    1e308: non-finite linearization) is a NodeConfigError naming the cause."""
    try:
        _warm_up(simulation, settings)
        return PeriodRunner(simulation.sim, simulation.budget, simulation.period_ns,
                            ahead=not settings.sync_mode)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        raise NodeConfigError(
            f"scene_file {settings.scene_file}: the scene cannot be simulated from its "
            f"initial state ({type(exc).__name__}: {one_line(exc)[:200]})") from None


def _warm_up(simulation: Simulation, settings) -> None:
    sim, model = simulation.sim, simulation.model
    scratch = Simulator(model, sim.integrator)   # same settings, its own Carry
    period_s = simulation.period_ns / NS_PER_S
    try:
        simulation.budget = budget.measure(scratch, period_s, settings.max_period_cost)
    except (IntegrationError, ArithmeticError):
        simulation.budget = budget.fallback(sim.integrator, settings.max_period_cost)
    simulation.budget.apply(sim)
    if scratch.t_ns == 0:
        return  # the first period failed: the real run reports it
    snap = scratch.snapshot()
    # one energy balance sample: the energies, the powers and the balance's central
    # difference, as every period books them
    balance_sample(model, snap.t, scratch.y, scratch.held, scratch.mode)
    for name in STATE_TOPICS:
        if BY_NAME[name].exists_for(simulation.scene):
            BY_NAME[name].encode(snap, simulation.scene, settings.frame_id)


def start_line(node: str, simulation: Simulation, mode: str, command_topics, log_path,
               settings) -> str:
    """The node's start-up log line: what it simulates, how, and where its commands go."""
    sim = simulation.sim
    return (f"{node}: scene {simulation.scene.name!r} (n = {simulation.scene.n}), model "
            f"{simulation.model.name}, {sim.integrator.describe()}, {settings.rate_hz:g} Hz, "
            f"{mode}, work budget {simulation.budget.describe()}; commands on "
            f"{', '.join(command_topics[:-1])} and {command_topics[-1]}"
            + (f", recording to {log_path}" if log_path else "")
            + (", paused until ~/pause false or the first command"
               if settings.start_paused else ""))
