"""The Python API of rod_sim: ``import rod_sim`` gives these names (docs/python_api.md).

A study in five lines::

    import rod_sim

    sim = rod_sim.Simulator.from_scene("config/paper_example.yaml", model="reduced")
    traj = sim.run(2.0, rate_hz=100.0)          # samples t (N,), y (N, state_size)
    print(traj.phi[-1], sim.energies().total)   # rod angles [rad], energy [J]

The pieces, each by name as the command line takes them:

- scenes: :func:`load_scene` (a YAML file, a dict of the scene format, or a Scene) ->
  :class:`Scene` (docs/interface.md section 1); a bad entry is a :class:`SceneError` naming it;
- models: :func:`make_model` (``MODEL_NAMES``: full, reduced, rigid), integrators:
  :func:`make_integrator` (``INTEGRATOR_NAMES``);
- running: :class:`Simulator` (advance, sample, run, state, snapshot, energies, momentum, the
  base of a spacecraft scene), :class:`Trajectory` (what ``run`` returns) and
  :func:`energy_balance` (the energy residual of a run, as ``rod-sim simulate`` books it);
- logs: :func:`open_log` (any log ``rod-sim`` or the node writes: MCAP or rosbag2) and the
  readers of one topic as numpy arrays: :func:`read_rod_states`, :func:`read_joint_states`,
  :func:`read_base_odometry`, :func:`read_applied_forces`.

Units are SI throughout (s, m, kg, rad, N, N m, J). ``rod-sim simulate`` and the node build
their simulators through :func:`load_scene`, :func:`make_model`, :func:`make_integrator` and
:class:`Simulator`: the API is the command line's own path, not a second one.

Importing this module imports numpy and the model code (numba when installed); ``import
rod_sim`` alone does not (its names load on first use).
"""
from __future__ import annotations

import os
from collections.abc import Iterable, Mapping

import numpy as np

from rod_sim.core.integrators import IntegrationError, Integrator
from rod_sim.core.integrators import make_integrator as _make_integrator
from rod_sim.core.memory import check_model_memory
from rod_sim.core.models import BaseState, ChainModel, Energies, ModelError, Momentum
from rod_sim.core.models import make_model as _make_model
from rod_sim.core.names import INTEGRATOR_NAMES, MODEL_NAMES
from rod_sim.core.scene import Scene, SceneError
from rod_sim.core.simulator import Simulator as _CoreSimulator
from rod_sim.core.simulator import Trajectory
from rod_sim.core.snapshot import Snapshot
from rod_sim.core.validity import EnergyBalance, balance_run
from rod_sim.io.log_format import LogFormatError
from rod_sim.io.log_open import open_log
from rod_sim.io.scene_yaml import load_scene as _load_scene_file
from rod_sim.io.series import (read_applied_forces, read_base_odometry, read_joint_states,
                               read_rod_states)

__all__ = ["MODEL_NAMES", "INTEGRATOR_NAMES", "load_scene", "make_model", "make_integrator",
           "Simulator", "Trajectory", "Snapshot", "Energies", "Momentum", "BaseState",
           "energy_balance", "open_log", "read_rod_states", "read_joint_states",
           "read_base_odometry", "read_applied_forces", "Scene", "SceneError", "ModelError",
           "IntegrationError", "LogFormatError"]

DEFAULT_MODEL = "reduced"
DEFAULT_INTEGRATOR = "dop853-jit"


def load_scene(source: str | os.PathLike | Mapping | Scene) -> Scene:
    """The validated scene of ``source``: a scene YAML file's path, a dict in the scene format
    (docs/interface.md section 1) or a :class:`Scene` (returned as is). A file's scene
    without a ``name`` is named after the file. Raises :class:`SceneError` (``str(err)`` is
    one line naming the entry, e.g. ``rods.length: must be > 0``)."""
    if isinstance(source, Scene):
        return source
    if isinstance(source, Mapping):
        return Scene.from_dict(dict(source))
    if isinstance(source, (str, os.PathLike)):
        return _load_scene_file(source)
    raise TypeError(f"load_scene: expected a path, a dict or a Scene, got {type(source).__name__}")


def make_model(name: str, scene: str | os.PathLike | Mapping | Scene) -> ChainModel:
    """The model ``name`` (one of :data:`MODEL_NAMES`: ``full`` 3n ODEs with bending inertia,
    ``reduced`` n ODEs with quasi-static bending, ``rigid`` n ODEs of rigid rods) of ``scene``
    (anything :func:`load_scene` takes). The chain must fit in the memory this process may use
    (estimated before allocating: a :class:`SceneError` keyed ``rods.count`` otherwise);
    :class:`ModelError` when the scene cannot be run with that model."""
    scene = load_scene(scene)
    check_model_memory(scene.n)
    return _make_model(name, scene)


def make_integrator(name: str = DEFAULT_INTEGRATOR, *, rtol: float | None = None,
                    atol: float | None = None, step: float | None = None) -> Integrator:
    """The integrator ``name`` (one of :data:`INTEGRATOR_NAMES`): ``dop853-jit`` (default) and
    ``radau-jit`` compiled adaptive (``rtol``, ``atol``; default 1e-8 and atol = rtol), ``rk4``,
    ``rk2``, ``euler`` compiled fixed step (``step`` [s], default 1e-3), or scipy's ``RK45``,
    ``DOP853``, ``Radau``, ``BDF``, ``LSODA``. Immutable settings: one integrator may serve
    many simulators. ValueError on a bad name or setting."""
    return _make_integrator(name, rtol=rtol, atol=atol, step=step)


class Simulator(_CoreSimulator):
    """One model stepped by one integrator, owning simulated time (whole nanoseconds), the
    state and the held inputs.

    ``Simulator(model, integrator)``: ``model`` from :func:`make_model`, ``integrator`` an
    integrator or its name (default ``dop853-jit``; ``settings`` are its ``rtol``, ``atol``,
    ``step``). :meth:`from_scene` builds both by name.

    Stepping: :meth:`advance` (dt [s]), :meth:`sample` (integer-ns times),
    :meth:`run` (to t_end [s] sampled at rate_hz, returns a :class:`Trajectory`),
    :meth:`reset`. Inputs held from now on: :meth:`set_forces` (n, 2) [N],
    :meth:`set_hinge_torques` (n,) [N m], :meth:`set_held`. State: :attr:`t` [s],
    :attr:`state` (state_size,), :attr:`phi`, :attr:`phi_rate` (n,), :meth:`snapshot` (every
    published quantity), :meth:`energies`, :meth:`momentum`, :meth:`base_state`, :attr:`events`
    (hinge events so far), :attr:`stats` (work counters). A run that cannot go on raises
    :class:`IntegrationError` and leaves the simulator where it was.
    """

    def __init__(self, model: ChainModel, integrator: Integrator | str | None = None,
                 **settings):
        if integrator is None or isinstance(integrator, str):
            integrator = make_integrator(integrator or DEFAULT_INTEGRATOR, **settings)
        elif settings:
            raise TypeError("Simulator: settings go with an integrator name, not an integrator")
        super().__init__(model, integrator)

    @classmethod
    def from_scene(cls, scene: str | os.PathLike | Mapping | Scene, model: str = DEFAULT_MODEL,
                   integrator: str = DEFAULT_INTEGRATOR, *, rtol: float | None = None,
                   atol: float | None = None, step: float | None = None) -> "Simulator":
        """A simulator of ``scene`` (a path, a dict or a Scene) with the model and integrator
        named (defaults: reduced, dop853-jit at rtol 1e-8), at t = 0 in the scene's initial
        state."""
        return cls(make_model(model, scene), make_integrator(integrator, rtol=rtol, atol=atol,
                                                             step=step))

    @property
    def scene(self) -> Scene:
        """The scene simulated."""
        return self.model.scene

    @property
    def state(self) -> np.ndarray:
        """The state vector now (state_size,), read-only: the rod angles phi (n,) and their
        rates (n,), the full model's bending amplitudes between them (model.phi(y) and
        model.phi_rate(y) pick them), the base's coordinates on a free base at the end."""
        y = self.y.view()
        y.flags.writeable = False
        return y

    @property
    def phi(self) -> np.ndarray:
        """(n,) rod chord angles now [rad], from the x axis."""
        return self.model.phi(self.y)

    @property
    def phi_rate(self) -> np.ndarray:
        """(n,) rod angular rates now [rad/s]."""
        return self.model.phi_rate(self.y)

    def energies(self) -> Energies:
        """Mechanical energy now [J]: ``kinetic``, ``hinge`` (springs and stop contacts),
        ``bending``, ``gravity`` and ``total``."""
        return self.model.energies(self.t, self.y, self.held, mode=self.mode)

    def momentum(self) -> Momentum:
        """Linear momentum (2,) [kg m/s], angular momentum about the origin and about the
        centre of mass [kg m^2/s], the centre of mass (2,) [m] and the mass [kg] of the whole
        system now (a free base and its wheel included; with a fixed or prescribed base, of
        the chains only): the quantities a free-floating spacecraft conserves."""
        return self.model.momentum(self.t, self.y, self.held)

    def base_state(self) -> BaseState | None:
        """The base's pose (x, y [m], psi [rad]) and rates in Oxy and its wheel's rate now;
        None on a scene without a base (docs/spacecraft.md)."""
        if not self.model.is_spacecraft:
            return None
        return self.model.base_state(self.t, self.y)


def energy_balance(trajectory: Trajectory, events: Iterable = (),
                   held: np.ndarray | None = None) -> EnergyBalance:
    """The mechanical energy balance of a run, booked as ``rod-sim simulate`` books it:
    ``residual`` = E - E0 - W + D [J] (W the work of loads, motors and dampers, D the energy
    lost in latch impacts; ~0 for an accurate run) and ``scale`` [J] (what it is relative to),
    after the last sample of ``trajectory`` (from :meth:`Simulator.run`, starting at the state
    whose energy is E0). ``events``: the simulator's :attr:`~Simulator.events` of the run;
    ``held``: the inputs held during it ((n, 3), None: zeros). O(samples x n)."""
    balance = None
    for _, balance, _ in balance_run(trajectory.model, trajectory.t, trajectory.y, held,
                                     trajectory.modes, tuple(events)):
        pass
    return balance
