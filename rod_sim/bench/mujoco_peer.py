"""The peer: the same chain as rigid links in MuJoCo, for ``rod-sim bench``.

Physical model (equal to rod_sim's rigid model, EI -> infinity):
- rod k is a body with a hinge joint about z at node k-1 (joint angle = the relative hinge
  rotation phi_k - phi_{k-1}, phi_0 = 0), stiffness kappa_k (springref 0), damping nu_k,
  armature 0, no friction loss; its inertia is a uniform thin rod: mass m_k l_k at l_k / 2,
  moment m_k l_k^3 / 12 about its centre;
- the point mass mu_k is a welded child body at node k (so a nodal force, applied through
  ``xfrc_applied`` at that body's centre of mass, acts exactly at the node);
- gravity off, no geoms, no contacts; integrator RK4 (explicit, like ours) or implicitfast.
The scripted nodal forces are held over each MuJoCo step at their value at the step's
midpoint (MuJoCo holds applied forces constant within a step; the midpoint keeps the forcing
second-order accurate). Held (commanded) forces are zero, as in the bench.

Runs use ``mujoco.rollout`` (the stepping loop in C) over each output interval, with the
forces as ``mjSTATE_XFRC_APPLIED`` controls. ``mujoco`` is imported only inside functions: the
bench works without it and says so.
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass

import numpy as np

from rod_sim.app.common import importable

NAME = "mujoco"
"""The peer's name: its bench rows are integrators ``mujoco-<integrator>``."""
MODEL = "rigid"
"""The rod_sim model it simulates (its rows' errors are against that model's reference)."""


class PeerError(RuntimeError):
    """The peer could not run this scene or this setting."""


def available() -> bool:
    """True when the ``mujoco`` package can be imported."""
    return importable("mujoco")


def bench_settings(quick: bool) -> list[tuple[str, float]]:
    """(MuJoCo integrator, time step [s]) pairs timed by the bench."""
    steps = (2e-3, 1e-3, 5e-4, 2.5e-4) if quick else (5e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1e-4)
    out = [("RK4", dt) for dt in steps]
    out += [("implicitfast", dt) for dt in ((1e-4,) if quick else (1e-3, 1e-4, 1e-5))]
    return out


def chain_xml(scene, dt: float, integrator: str = "RK4") -> str:
    """MJCF of the rigid chain of ``scene`` (see the module docstring)."""
    n = scene.n
    l, m, mu, kappa, nu = ([float(v) for v in getattr(scene, key)] for key in
                           ("length", "mass_per_length", "node_mass", "hinge_stiffness",
                            "hinge_damping"))
    if any(mk * lk <= 0 for mk, lk in zip(m, l)):
        raise PeerError("the MuJoCo peer needs every rod to have mass (a jointed body needs "
                        "inertia)")
    parts = [f'<mujoco model="{scene.name}">',
             '<compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
             f'<option timestep="{dt!r}" gravity="0 0 0" integrator="{integrator}">',
             '<flag contact="disable"/></option>', "<worldbody>"]
    closing = []
    for k in range(n):
        pos = 0.0          # rod k+1 starts at the frame of node k (or the origin)
        i_rod = m[k] * l[k] ** 3 / 12.0
        tiny = 1e-12 * i_rod
        parts.append(f'<body name="rod{k + 1}" pos="{pos!r} 0 0">')
        parts.append(f'<joint name="hinge{k}" type="hinge" axis="0 0 1" '
                     f'stiffness="{kappa[k]!r}" springref="0" damping="{nu[k]!r}" armature="0"/>')
        parts.append(f'<inertial pos="{l[k] / 2.0!r} 0 0" mass="{m[k] * l[k]!r}" '
                     f'diaginertia="{tiny!r} {i_rod!r} {i_rod!r}"/>')
        parts.append(f'<body name="node{k + 1}" pos="{l[k]!r} 0 0">')
        if mu[k] > 0:
            e = 1e-12 * i_rod
            parts.append(f'<inertial pos="0 0 0" mass="{mu[k]!r}" diaginertia="{e!r} {e!r} {e!r}"/>')
        closing.append("</body></body>")
    parts += closing[::-1]
    parts += ["</worldbody>", "</mujoco>"]
    return "\n".join(parts)


@dataclass
class PeerRun:
    """Samples of one MuJoCo run: t (N,), phi (N, n) [rad]; steps; median wall [s]."""

    t: np.ndarray
    phi: np.ndarray
    steps: int
    wall_s: float = math.nan
    cpu_s: float = math.nan
    repeats: int = 1


class ChainPeer:
    """A compiled MuJoCo model of ``scene``'s rigid chain at time step ``dt`` [s]."""

    def __init__(self, scene, dt: float, integrator: str = "RK4"):
        import mujoco

        from rod_sim.core.models import load_table

        self.mj = mujoco
        self.scene = scene
        self.dt = float(dt)
        self.model = mujoco.MjModel.from_xml_string(chain_xml(scene, dt, integrator))
        self.data = mujoco.MjData(self.model)
        self.n = scene.n
        self.node_body = np.array([mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY,
                                                     f"node{k + 1}") for k in range(self.n)])
        self.spec_state = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.spec_ctrl = mujoco.mjtState.mjSTATE_XFRC_APPLIED
        self.loads = load_table(scene)
        self.qpos_slice = slice(1, 1 + self.model.nq)           # FULLPHYSICS: time, qpos, ...

    def initial_state(self) -> np.ndarray:
        mj = self.mj
        mj.mj_resetData(self.model, self.data)
        phi0 = np.asarray(self.scene.phi0, dtype=float)
        rate0 = np.asarray(self.scene.phi_rate0, dtype=float)
        self.data.qpos[:] = np.diff(phi0, prepend=0.0)
        self.data.qvel[:] = np.diff(rate0, prepend=0.0)
        state = np.empty(mj.mj_stateSize(self.model, self.spec_state))
        mj.mj_getState(self.model, self.data, state, self.spec_state)
        return state

    def forces(self, t_mid: np.ndarray) -> np.ndarray:
        """xfrc_applied controls (len(t_mid), nbody * 6): scripted loads at t_mid [s]."""
        node, axis, shape, amp, start, dur = self.loads
        ctrl = np.zeros((t_mid.size, self.model.nbody, 6))
        for i in range(node.size):
            tau = t_mid - start[i]
            if shape[i] == 1:                                   # constant
                v = np.where(tau >= 0, amp[i], 0.0)
            elif shape[i] == 2:                                 # step
                v = np.where((tau >= 0) & (tau < dur[i]), amp[i], 0.0)
            else:                                               # raised cosine pulse
                v = np.where((tau >= 0) & (tau <= dur[i]),
                             amp[i] * (0.5 - 0.5 * np.cos(2 * np.pi * tau / dur[i])), 0.0)
            ctrl[:, self.node_body[node[i]], axis[i]] += v
        return ctrl.reshape(t_mid.size, -1)

    def run(self, t_end: float, rate_hz: float) -> PeerRun:
        """Samples every 1/rate_hz [s] on [0, t_end] (the output period must be a whole
        number of steps)."""
        from mujoco import rollout

        period = 1.0 / rate_hz
        per = period / self.dt
        if abs(per - round(per)) > 1e-6 or round(per) < 1:
            raise PeerError(f"step {self.dt:g} s does not divide the output period {period:g} s")
        per = int(round(per))
        n_out = int(round(t_end * rate_hz))
        state = self.initial_state()
        phi = np.empty((n_out + 1, self.n))
        phi[0] = np.cumsum(state[self.qpos_slice])
        offsets = (np.arange(per) + 0.5) * self.dt
        for i in range(n_out):
            t0 = i * per * self.dt
            ctrl = self.forces(t0 + offsets)
            states, _ = rollout.rollout(self.model, self.data, state, ctrl,
                                        control_spec=self.spec_ctrl, nstep=per)
            state = states[0, -1]
            q = state[self.qpos_slice]
            if not np.all(np.isfinite(q)):
                phi[i + 1:] = np.nan
                break
            phi[i + 1] = np.cumsum(q)
        return PeerRun(np.arange(n_out + 1) / rate_hz, phi, n_out * per)


def time_run(scene, t_end, rate_hz, dt, integrator="RK4", repeats=3, cap_s=60.0) -> PeerRun:
    """Median wall and CPU time [s] of ``ChainPeer.run`` (model compilation excluded, as our JIT
    warm-up is); a pilot over 5 % of the span predicts the wall time against ``cap_s``."""
    try:
        peer = ChainPeer(scene, dt, integrator)
    except ValueError as exc:                       # MuJoCo's compile errors
        raise PeerError(str(exc).splitlines()[0]) from None
    started = time.perf_counter()
    peer.run(max(1.0 / rate_hz, 0.05 * t_end), rate_hz)
    predicted = (time.perf_counter() - started) / 0.05
    if predicted > cap_s:
        raise PeerError(f"timed out: predicted {predicted:.3g} s > cap {cap_s:g} s")
    walls, cpus = [], []
    res = None
    while True:
        cpu0, started = time.process_time(), time.perf_counter()
        res = peer.run(t_end, rate_hz)
        walls.append(time.perf_counter() - started)
        cpus.append(time.process_time() - cpu0)
        if len(walls) >= repeats and (sum(walls) > 0.3 or len(walls) >= 15):
            break
        if sum(walls) > cap_s / 2:
            break
    res.wall_s = statistics.median(walls)
    res.cpu_s = statistics.median(cpus)
    res.repeats = len(walls)
    return res
