"""The spacecraft peer: Basilisk (PyPI ``bsk``) with a hub carrying N hinged rigid panels, for
the spacecraft bench (:mod:`.spacecraft`), beside rod_sim's rigid model with N one-rod chains
on a free base.

Model (the mapping of test/test_basilisk_peer.py on branch sc-verify, read from Basilisk's
hingedRigidBodyStateEffector.cpp): ``spacecraft.Spacecraft`` (no gravity, no orbit) and one
``HingedRigidBodyStateEffector`` per panel, all planar: every hinge axis along the body z
axis, the hub turning about z. Panel i sits at ``attach_i`` of the body frame and points, at
hinge angle theta = 0, along the body direction a_i (rod_sim: rest angle a_i, rod angle
phi_i = psi + a_i + theta_i). Its hinge frame has the rows h1 = -(cos a_i, sin a_i, 0),
h2 = (0, 0, 1), h3 = h1 x h2. A uniform rod of length l and mass m: d = l / 2, inertia about
the hinge axis through its centre of mass m l^2 / 12; Basilisk's spring and damper
-k theta - c theta' are rod_sim's hinge 0 (kappa = k, nu = c about the rest angle). The hub:
mass m_B, J_B = IHubPntBc_B[2][2] (the x and y inertias do not enter planar motion). The
hub attitude psi = 4 atan(sigma_3) (MRP about z, unwrapped).

Basilisk integrates with its default fixed-step RK4 at the task's step (``bench_settings``);
each setting is timed over the whole ``ExecuteSimulation`` (the C++ loop, one Python call),
with one recorder sample at the end. ``Basilisk`` is imported only inside functions: the
bench works without it and says so.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from rod_sim.app.common import importable

NAME = "basilisk"
"""The peer's name (rows ``basilisk-rk4``)."""
MODEL = "rigid"
"""The rod_sim model it simulates."""


class PeerError(RuntimeError):
    """Basilisk is missing, or could not run this spacecraft or this setting."""


def available() -> bool:
    """True when Basilisk (``pip install bsk``) can be imported."""
    return importable("Basilisk")


def bench_settings(quick: bool = False) -> list[tuple[str, float]]:
    """(Basilisk integrator, time step [s]) pairs timed by the bench."""
    steps = (1e-2, 5e-3, 2e-3) if quick else (2e-2, 1e-2, 5e-3, 2e-3, 1e-3)
    return [("rk4", dt) for dt in steps]


@dataclass(frozen=True)
class Panel:
    """One hinged rigid panel: body-frame hinge point ``attach`` [m], direction ``angle`` a
    [rad] at theta = 0, initial hinge angle ``theta`` [rad] and rate ``theta_rate`` [rad/s]."""

    attach: tuple[float, float]
    angle: float
    theta: float
    theta_rate: float


@dataclass(frozen=True)
class Spacecraft:
    """A hub (mass [kg], z inertia about its centre of mass [kg m^2], initial rate
    ``omega`` [rad/s], centre of mass at the body origin) with identical panels (``mass``
    [kg], ``length`` [m], hinge spring ``k`` [N m/rad] and damper ``c`` [N m s/rad])."""

    hub_mass: float
    hub_inertia: float
    omega: float
    panels: tuple[Panel, ...]
    mass: float
    length: float
    k: float
    c: float


@dataclass(frozen=True)
class PeerRun:
    """One timed Basilisk run: ``wall_s`` (minimum over repeats) [s], the hub attitude
    ``psi`` [rad] and rate [rad/s] at t_end, the hinge angles ``theta`` (N,) [rad] at t_end."""

    dt: float
    wall_s: float
    psi: float
    psi_rate: float
    theta: np.ndarray


def _simulate(craft: Spacecraft, t_end: float, dt: float):
    """Build and run Basilisk once; (wall time of ExecuteSimulation [s], psi, psi_rate,
    theta (N,)) at ``t_end``."""
    from Basilisk.simulation import hingedRigidBodyStateEffector, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros

    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("proc")
    proc.addTask(sim.CreateNewTask("task", macros.sec2nano(dt)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "hub"
    sc.hub.mHub = craft.hub_mass
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    J = craft.hub_inertia
    sc.hub.IHubPntBc_B = [[J + 300.0, 0, 0], [0, J + 200.0, 0], [0, 0, J]]
    sc.hub.r_CN_NInit = [[0.0], [0.0], [0.0]]
    sc.hub.v_CN_NInit = [[0.0], [0.0], [0.0]]
    sc.hub.sigma_BNInit = [[0.0], [0.0], [0.0]]
    sc.hub.omega_BN_BInit = [[0.0], [0.0], [craft.omega]]
    m, l = craft.mass, craft.length
    effectors = []
    for i, p in enumerate(craft.panels):
        e = hingedRigidBodyStateEffector.HingedRigidBodyStateEffector()
        e.ModelTag = f"panel{i}"
        e.mass = m
        e.IPntS_S = [[m * l * l / 12, 0, 0], [0, m * l * l / 12, 0], [0, 0, m * l * l / 12]]
        e.d, e.k, e.c = l / 2, craft.k, craft.c
        e.r_HB_B = [[p.attach[0]], [p.attach[1]], [0.0]]
        ca, sa = math.cos(p.angle), math.sin(p.angle)
        e.dcm_HB = [[-ca, -sa, 0.0], [0.0, 0.0, 1.0], [-sa, ca, 0.0]]
        e.thetaInit, e.thetaDotInit = p.theta, p.theta_rate
        e.nameOfThetaState, e.nameOfThetaDotState = f"theta{i}", f"thetaDot{i}"
        sc.addStateEffector(e)
        sim.AddModelToTask("task", e)
        effectors.append(e)
    sim.AddModelToTask("task", sc)
    every = macros.sec2nano(t_end)           # one sample at 0 and one at t_end
    rec = sc.scStateOutMsg.recorder(every)
    sim.AddModelToTask("task", rec)
    precs = [e.hingedRigidBodyOutMsg.recorder(every) for e in effectors]
    for r in precs:
        sim.AddModelToTask("task", r)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(t_end))
    started = time.perf_counter()
    sim.ExecuteSimulation()
    wall = time.perf_counter() - started
    sigma, omega = np.asarray(rec.sigma_BN), np.asarray(rec.omega_BN_B)
    if not (np.all(np.isfinite(sigma)) and np.max(np.abs(sigma[:, :2])) < 1e-12):
        raise PeerError(f"Basilisk left the plane or diverged at step {dt:g} s")
    times = np.asarray(rec.times()) * 1e-9
    if abs(times[-1] - t_end) > 1e-9:
        raise PeerError(f"Basilisk's last sample is at {times[-1]} s, not {t_end} s")
    # psi = 4 atan(sigma_3) in (-2 pi, 2 pi), defined modulo 2 pi (Basilisk switches to the
    # shadow MRP set at |sigma| > 1): compare it modulo 2 pi
    psi = 4.0 * math.atan(float(sigma[-1, 2]))
    theta = np.array([float(np.asarray(r.theta)[-1]) for r in precs])
    return wall, psi, float(omega[-1, 2]), theta


def time_run(craft: Spacecraft, t_end: float, dt: float, repeats: int = 3,
             cap_s: float = 60.0) -> PeerRun:
    """Time Basilisk over [0, t_end] at RK4 step ``dt`` [s]: the minimum wall time of
    ``repeats`` runs (more up to 0.3 s or 15 runs for fast ones, fewer when one run takes more
    than ``cap_s`` / repeats)."""
    if not available():
        raise PeerError("Basilisk is not installed (pip install bsk)")
    best, out, total, runs = math.inf, None, 0.0, 0
    while runs < max(1, repeats) or (total < 0.3 and runs < 15):    # fast runs: more repeats
        wall, psi, rate, theta = _simulate(craft, t_end, dt)
        best, total, runs = min(best, wall), total + wall, runs + 1
        out = (psi, rate, theta)
        if wall * repeats > cap_s:
            break
    return PeerRun(dt, best, out[0], out[1], out[2])
