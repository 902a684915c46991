"""Shared helpers of the spacecraft tests (issue 25, SPEC section 8): random scenes as dicts in
the SPEC structure, the matching oracle (``lagrangian_base``), and the mapping between a model's
state y = [q, q'] and the oracle's coordinates [phi, alpha, beta, x_B, y_B, psi, theta_w].

Nothing here imports rod_sim's internals: the tests get the model's answers only through
``make_model(name, Scene.from_dict(d))`` and its public methods.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lagrangian_base import BaseData, BaseLagrangian, ChainData  # noqa: E402


def spacecraft_available() -> str | None:
    """None when rod_sim accepts a free-base scene with chains, else the reason it does not."""
    try:
        from rod_sim.core.models import make_model
        from rod_sim.core.scene import Scene
        d = scene_dict([chain_dict("a", 1, np.random.default_rng(0))], free_base(), None)
        make_model("rigid", Scene.from_dict(d))
    except Exception as e:     # noqa: BLE001 (any failure: the feature is not there)
        return f"the spacecraft scenes are not implemented here ({type(e).__name__}: {e})"
    return None


def needs_spacecraft():
    reason = spacecraft_available()
    return pytest.mark.skipif(reason is not None, reason=reason or "")


def chain_dict(name, n, rng, attach=None, **override):
    """A heterogeneous random chain (every rod, node and hinge different) as a SPEC dict."""
    p = dict(l=rng.uniform(0.5, 2.0, n), m=rng.uniform(0.5, 3.0, n), mu=rng.uniform(0.2, 2.0, n),
             EI=rng.uniform(1e3, 1e5, n), kappa=rng.uniform(10.0, 200.0, n),
             nu=rng.uniform(0.05, 2.0, n))
    for k, v in override.items():
        p[k] = np.broadcast_to(np.asarray(v, float), (n,)).copy()
    a = rng.uniform(-1.0, 1.0, 2) if attach is None else np.asarray(attach, float)
    return {"name": name, "attach": [float(v) for v in a],
            "rods": {"count": n, "length": [float(v) for v in p["l"]],
                     "mass_per_length": [float(v) for v in p["m"]],
                     "bending_stiffness": [float(v) for v in p["EI"]]},
            "nodes": {"mass": [float(v) for v in p["mu"]]},
            "hinges": {"stiffness": [float(v) for v in p["kappa"]],
                       "damping": [float(v) for v in p["nu"]]}}


def free_base(mass=40.0, inertia=12.0, com=(0.1, -0.05), wheel=0.3, **kw):
    d = {"mode": "free", "mass": float(mass), "inertia": float(inertia),
         "centre_of_mass": [float(v) for v in com]}
    if wheel:
        d["wheel"] = {"inertia": float(wheel), "rate": 0.0}
    d.update(kw)
    return d


def scene_dict(chains, base, gravity, loads=(), name="sc_test"):
    d = {"name": name, "chains": list(chains), "loads": list(loads)}
    if base is not None:
        d["base"] = base
    if gravity is not None:
        d["gravity"] = [float(v) for v in gravity]
    return d


def _arr(v, n):
    return np.broadcast_to(np.asarray(v, float), (n,)).copy()


def oracle_from_dict(d) -> BaseLagrangian:
    """The oracle of a scene dict (only the keys the helpers above write)."""
    chains = []
    for c in d["chains"]:
        n = c["rods"]["count"]
        chains.append(ChainData(
            l=_arr(c["rods"]["length"], n), m=_arr(c["rods"]["mass_per_length"], n),
            mu=_arr(c["nodes"]["mass"], n), EI=_arr(c["rods"]["bending_stiffness"], n),
            kappa=_arr(c["hinges"]["stiffness"], n), nu=_arr(c["hinges"].get("damping", 0.0), n),
            attach=c.get("attach", [0.0, 0.0]),
            rest=_arr(c["hinges"].get("rest_angle", 0.0), n)))
    b = d.get("base") or {"mode": "fixed"}
    base = BaseData(mass=b.get("mass", 0.0), inertia=b.get("inertia", 0.0),
                    com=b.get("centre_of_mass", [0.0, 0.0]),
                    wheel=(b.get("wheel") or {}).get("inertia", 0.0))
    return BaseLagrangian(chains, base, gravity=d.get("gravity") or (0.0, 0.0))


class Layout:
    """Where the oracle's coordinates sit in a model's state (SPEC section 8 / the brief):
    q = [phi (N), alpha (N), beta (N) full only, x_B, y_B, psi (free only), theta_w (wheel)]."""

    def __init__(self, model_name: str, N: int, free: bool, wheel: bool):
        self.N, self.full = N, model_name == "full"
        nb = (3 if free else 0) + (1 if (free and wheel) else 0)
        self.dof = (3 * N if self.full else N) + nb
        self.free, self.wheel = free, wheel
        # oracle index of every model coordinate
        idx = list(range(N)) + (list(range(N, 3 * N)) if self.full else [])
        if free:
            idx += [3 * N, 3 * N + 1, 3 * N + 2]
        if free and wheel:
            idx += [3 * N + 3]
        self.idx = np.array(idx)

    def to_oracle(self, y, base_q=None, base_qd=None):
        """(q, qd) (3N + 4,) from a model state y (2 dof,); for a fixed or prescribed base the
        base coordinates come from ``base_q``, ``base_qd`` (x_B, y_B, psi) (default 0)."""
        y = np.asarray(y, float)
        assert y.shape == (2 * self.dof,), (y.shape, self.dof)
        q, qd = np.zeros(3 * self.N + 4), np.zeros(3 * self.N + 4)
        if base_q is not None:
            q[3 * self.N:3 * self.N + 3] = base_q
        if base_qd is not None:
            qd[3 * self.N:3 * self.N + 3] = base_qd
        q[self.idx] = y[:self.dof]
        qd[self.idx] = y[self.dof:]
        return q, qd

    def qdd_to_oracle(self, dy, base_qdd=None):
        qdd = np.zeros(3 * self.N + 4)
        if base_qdd is not None:
            qdd[3 * self.N:3 * self.N + 3] = base_qdd
        qdd[self.idx] = np.asarray(dy, float)[self.dof:]
        return qdd

    def from_oracle(self, q, qd):
        return np.concatenate([np.asarray(q)[self.idx], np.asarray(qd)[self.idx]])


def spin_up(t, rate, T):
    """psi, psi', psi'' of SPEC's spin_up profile (psi(0) = 0): psi' = (rate/T)(t - (T/2pi)
    sin(2 pi t/T)) for t < T, then rate."""
    w = 2 * np.pi / T
    if t < T:
        psi = (rate / T) * (t * t / 2 + (np.cos(w * t) - 1) / w ** 2)
        return psi, (rate / T) * (t - np.sin(w * t) / w), (rate / T) * (1 - np.cos(w * t))
    psiT = (rate / T) * (T * T / 2)
    return psiT + rate * (t - T), rate, 0.0


def cycloidal(t, D, T):
    """p, p', p'' of a cycloidal rest-to-rest move by D in T (start 0)."""
    w = 2 * np.pi / T
    if t < T:
        return D * (t / T - np.sin(w * t) / (2 * np.pi)), (D / T) * (1 - np.cos(w * t)), \
            (D / T) * w * np.sin(w * t)
    return D, 0.0, 0.0


def harmonic(t, A, f):
    """p, p', p'' of A (1 - cos(2 pi f t)) (start 0)."""
    w = 2 * np.pi * f
    return A * (1 - np.cos(w * t)), A * w * np.sin(w * t), A * w * w * np.cos(w * t)


def rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))
