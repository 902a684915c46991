"""The long-chain peer: Pinocchio's articulated-body algorithm (``pin.aba``) on the same planar
chain as rod_sim's rigid model, for ``rod-sim bench`` (cost per call against n).

Model: rod k is a body on a revolute joint about z at node k-1 (joint angle = the relative
hinge rotation theta_k = phi_k - phi_{k-1}); its inertia is a uniform thin rod (mass m_k l_k
at l_k / 2, m_k l_k^3 / 12 about its centre) plus the node mass mu_k at l_k; joint torques
tau = -kappa theta - nu theta' (the hinge springs and dampers). Before timing, the accelerations
are checked against rod_sim's rigid model (phi''_k = sum_{j<=k} theta''_j).

``pinocchio`` is imported only inside functions: the bench works without it and says so.
Pinocchio's ``Data`` grows faster than linearly with the depth of the chain (measured here:
see :func:`data_rss_bytes`), so the bench stops the peer at :data:`MAX_JOINTS` or when one
``Data`` would not fit in :data:`MEMORY_LIMIT_BYTES`.
"""
from __future__ import annotations

import os
import time

import numpy as np

from rod_sim.app.common import importable

MAX_JOINTS = 4096
MEMORY_LIMIT_BYTES = 4 << 30


class PeerError(RuntimeError):
    """The peer could not be built or disagrees with rod_sim."""


def available() -> bool:
    """True when ``pinocchio`` (PyPI package ``pin``) can be imported."""
    return importable("pinocchio")


def build(scene):
    """(pinocchio Model, its Data) of the rigid chain of ``scene`` (see the module docstring)."""
    import pinocchio as pin

    model = pin.Model()
    parent = 0
    offset = 0.0
    for k in range(scene.n):
        l = float(scene.length[k])
        m = float(scene.mass_per_length[k]) * l
        mu = float(scene.node_mass[k])
        i_rod = m * l * l / 12.0
        tiny = 1e-12 * max(i_rod, 1e-30)
        placement = pin.SE3(np.eye(3), np.array([offset, 0.0, 0.0]))
        jid = model.addJoint(parent, pin.JointModelRZ(), placement, f"hinge_{k}")
        model.appendBodyToJoint(jid, pin.Inertia(m, np.array([l / 2.0, 0.0, 0.0]),
                                                 np.diag([tiny, i_rod, i_rod])),
                                pin.SE3.Identity())
        if mu > 0.0:
            model.appendBodyToJoint(jid, pin.Inertia(mu, np.array([l, 0.0, 0.0]),
                                                     np.diag([tiny, tiny, tiny])),
                                    pin.SE3.Identity())
        parent = jid
        offset = l
    return model, model.createData()


def joint_state(scene, phi, phi_rate):
    """Joint angles and rates (n,) each from rod angles and rates."""
    return np.diff(phi, prepend=0.0), np.diff(phi_rate, prepend=0.0)


def accelerations(model, data, scene, phi, phi_rate) -> np.ndarray:
    """phi'' (n,) [rad/s^2] from ``pin.aba`` with the hinge springs and dampers as torques."""
    import pinocchio as pin

    q, v = joint_state(scene, phi, phi_rate)
    tau = -np.asarray(scene.hinge_stiffness) * q - np.asarray(scene.hinge_damping) * v
    return np.cumsum(pin.aba(model, data, q, v, tau))


def check(scene, rigid_model, rng=None) -> float:
    """Largest relative difference between Pinocchio's and rod_sim's rigid accelerations at a
    random state (loads off); raises PeerError above 1e-9."""
    rng = np.random.default_rng(0) if rng is None else rng
    model, data = build(scene)
    n = scene.n
    phi = rng.uniform(-1.0, 1.0, n)
    rate = rng.uniform(-1.0, 1.0, n)
    ours = rigid_model.rhs(0.0, np.concatenate([phi, rate]))[n:]
    theirs = accelerations(model, data, scene, phi, rate)
    err = float(np.max(np.abs(ours - theirs)) / max(1e-300, np.max(np.abs(ours))))
    if not err < 1e-9:
        raise PeerError(f"pinocchio and rod_sim disagree by {err:.3g} (relative)")
    return err


def data_rss_bytes(scene) -> int:
    """Resident memory [bytes] that building one Model and Data for ``scene`` adds."""
    before = _rss()
    model, data = build(scene)
    after = _rss()
    del model, data
    return max(0, after - before)


def _rss() -> int:
    with open(f"/proc/{os.getpid()}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def aba_cost(scene, budget_s: float = 0.05) -> float:
    """Wall time [s] of one ``pin.aba`` call from Python (state fixed, torques included)."""
    import pinocchio as pin

    model, data = build(scene)
    rng = np.random.default_rng(1)
    q = rng.uniform(-0.5, 0.5, scene.n)
    v = rng.uniform(-0.5, 0.5, scene.n)
    tau = np.zeros(scene.n)
    calls = 1
    while True:
        started = time.perf_counter()
        for _ in range(calls):
            pin.aba(model, data, q, v, tau)
        wall = time.perf_counter() - started
        if wall > budget_s or calls >= 1 << 20:
            return wall / calls
        calls *= 4
