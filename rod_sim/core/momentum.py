"""Momentum as a checked quantity: the rates the model's equations give the momentum of the
whole system (chains, a free base, its wheel) and the ledger that integrates them.

O(n): numpy, and the base's reaction one compiled pass over the rods
(:func:`~rod_sim.core.chain_momentum.chain_base_reaction`). For a free base the momentum
changes only by the applied loads and gravity (:func:`momentum_rates`); docs/spacecraft.md
derives which model conserves what:

- rigid and reduced models: their inertia is the rigid chords' (the reduced model drops the
  bending inertia), and the sum of their equations along a rigid translation or rotation of
  the whole system is exactly the rate of the chords' momentum: dP/dt = F and dH/dt = M_O
  hold exactly (P, H of :meth:`ChainModel.momentum`, chords only), so with no load they are
  conserved to round-off;
- full model: its mass matrix is the exact one at zero bending and its velocity terms are
  the paper's; the exact momentum of the bent rods (eq. (4)) then changes by a *defect*
  linear in the bending, which the ledger books (:func:`defect_rates`):
  D_P = -sum_j I_j (phi_j'' e_j + phi_j'^2 e_j^perp),
  D_H = sum_j I_j [e_j^perp x a_{j-1} - phi_j'' (r_{j-1} x e_j) - phi_j'^2 (r_{j-1} x e_j^perp)]
        + 2 phi_j' int m eta eta' + phi_j'' int m eta^2,
  I_j = int m eta ds = m_j l_j^2 (alpha_j - beta_j) / 12, r_{j-1}, a_{j-1} rod j's first node.
A fixed or prescribed base is an external support: its reaction (:func:`base_reaction`)
is what the ledger books for it.

Each function takes the state's arguments (t, y, held, mode) or ``state``, a
:class:`~rod_sim.core.state.State` of them whose quantities (the right-hand side, the node
positions, the momentum) it shares; its own result is kept there too.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import chain_momentum, kernels
from .kinematics import chain_nodes, pairs
from .state import cross as _cross


@dataclass(frozen=True)
class MomentumRates:
    """Rates [N, N m] at one instant: ``force`` (2,) and ``moment`` (about O) of the applied
    loads and gravity on the whole system (after a load that jumps at this instant) and
    ``force_before``, ``moment_before`` (before it; equal elsewhere); ``defect_force`` (2,),
    ``defect_moment``: the full model's defect (0 for the rigid and reduced models)."""

    force: np.ndarray
    moment: float
    defect_force: np.ndarray
    defect_moment: float
    force_before: np.ndarray | None = None
    moment_before: float | None = None


def _state(model, t, y, held, mode, state):
    """``state``, or a fresh :class:`~rod_sim.core.state.State` of the arguments."""
    return model.state(t, y, held, mode) if state is None else state


def _accelerations(s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(phi'' (n,), alpha'' - beta'' (n,), base accelerations (x, y, psi)) of the State ``s``
    from the model's rhs."""
    model, t = s.model, s.t
    dy = s.f
    n, d = model.n, model.dof
    ddphi = dy[d:d + n]
    dgam = dy[d + n:d + 2 * n] - dy[d + 2 * n:d + 3 * n] if model.dof_per_rod == 3 \
        else np.zeros(n)
    if model.nb:
        i = model.base_index
        acc = dy[d + i:d + i + 3]
    elif model.base_mode == kernels.MODE_PRESCRIBED:
        acc = np.array([kernels.motion_eval(model.chain.motion, r, float(t))[2]
                        for r in range(3)])
    else:
        acc = np.zeros(3)
    return ddphi, dgam, acc


def node_accelerations(model, t, y, ddphi, base_acc) -> np.ndarray:
    """Accelerations of the nodes of ``model.node_positions`` (n + nc, 2) [m/s^2]."""
    phi, dphi = model.phi(y), model.phi_rate(y)
    l = model.params.l
    st = model.base_state(t, y)
    c, s = np.cos(st.psi), np.sin(st.psi)
    tx = l * (-np.sin(phi) * ddphi - np.cos(phi) * dphi**2)
    ty = l * (np.cos(phi) * ddphi - np.sin(phi) * dphi**2)
    w2 = st.psi_rate**2
    ax, ay = model.chain.attach[:, 0], model.chain.attach[:, 1]
    rx, ry = c * ax - s * ay, s * ax + c * ay
    a0 = pairs(base_acc[0] - base_acc[2] * ry - w2 * rx,
               base_acc[1] + base_acc[2] * rx - w2 * ry)                     # (nc, 2)
    return chain_nodes(a0, pairs(tx, ty), model.table)


def _node_accelerations(s) -> np.ndarray:
    """:func:`node_accelerations` of the State ``s`` (its model's own accelerations)."""
    ddphi, _, base_acc = s.value(_accelerations)
    return node_accelerations(s.model, s.t, s.y, ddphi, base_acc)


def momentum_rates(model, t: float, y, held=None, mode=None, state=None) -> MomentumRates:
    """dP/dt and dH_O/dt of the whole system by the model's equations, split into the applied
    loads with gravity (the external force and moment about O) and the model's defect."""
    return _state(model, t, y, held, mode, state).value(_momentum_rates)


def _momentum_rates(s) -> MomentumRates:
    model, t, held = s.model, s.t, s.held
    tips = s.nodes[model.table.ends]
    mom = s.momentum
    b = model.chain.base
    rc = s.base_com if model.nb else None
    com = mom.com
    if model.name == "reduced" and b[kernels.B_GRAVITY] != 0.0:
        # its momentum is the chords' but gravity acts on the bent rods (quasi-static slopes)
        p = model.params
        alpha, beta = s.bending
        shift = model.rod_constants.C * (alpha - beta)
        com = com + np.array([-np.sum(shift * s.sin_phi), np.sum(shift * s.cos_phi)]) / mom.mass

    def applied(t_side):
        if t_side == t:
            loads = s.loads
        else:
            loads = np.zeros((model.n + 2, 3))
            kernels.load_forces(t, model.loads, model._held(held), t_side, loads)
        f = loads[:model.n, :2]
        force = f.sum(axis=0)
        moment = float(np.sum(_cross(tips, f)))
        if model.nb:
            force = force + loads[model.n, :2]
            moment += float(_cross(rc, loads[model.n, :2])) + float(loads[model.n, 2])
        if b[kernels.B_GRAVITY] != 0.0:
            g = np.array([b[kernels.B_GX], b[kernels.B_GY]])
            force = force + mom.mass * g
            moment += float(_cross(com, mom.mass * g))
        return force, moment

    force, moment = applied(t)
    before = (force, moment)
    if t in model.breakpoints:
        before = applied(np.nextafter(t, -np.inf))
    dP, dH = s.value(_defect_rates)
    return MomentumRates(force, moment, dP, dH, before[0], before[1])


def defect_rates(model, t: float, y, held=None, mode=None, state=None
                 ) -> tuple[np.ndarray, float]:
    """(D_P (2,), D_H): the full model's momentum defect (module docstring); zeros for the
    rigid and reduced models."""
    return _state(model, t, y, held, mode, state).value(_defect_rates)


def _defect_rates(s) -> tuple[np.ndarray, float]:
    model, y = s.model, s.y
    if model.dof_per_rod != 3:
        return np.zeros(2), 0.0
    n = model.n
    p = model.params
    phi, dphi = s.phi, s.phi_rate
    alpha, beta = y[n:2 * n], y[2 * n:3 * n]
    dalpha, dbeta = s.bending_rates
    ddphi, _, base_acc = s.value(_accelerations)
    e, ep = s.axes
    I1 = p.m * p.l**2 / 12.0 * (alpha - beta)
    l3 = p.m * p.l**3
    Iee = l3 / 105.0 * (alpha**2 + beta**2) - 2.0 * l3 / 140.0 * alpha * beta
    Ied = l3 / 105.0 * (alpha * dalpha + beta * dbeta) - l3 / 140.0 * (alpha * dbeta + beta * dalpha)
    i0 = model.rod_starts
    r = s.nodes[i0]
    a = s.value(_node_accelerations)[i0]
    dP = -(I1[:, None] * (ddphi[:, None] * e + (dphi**2)[:, None] * ep)).sum(axis=0)
    dH = float(np.sum(I1 * (_cross(ep, a) - ddphi * _cross(r, e) - dphi**2 * _cross(r, ep))
                      + 2.0 * dphi * Ied + ddphi * Iee))
    return dP, dH


class MomentumBalance:
    """The momentum ledger of a free base: P(t) - P(0) - int (F + D_P) dt and the same for the
    angular momentum about O, the integrals by the trapezoid rule over the samples given to
    :meth:`add` (its error falls with the square of the sample spacing)."""

    def __init__(self):
        self._last = None
        self.p0 = None
        self.h0 = 0.0
        self.impulse = np.zeros(2)
        self.angular_impulse = 0.0
        self.p = np.zeros(2)
        self.h = 0.0
        self.scale_p = 0.0
        self.scale_h = 0.0

    def add(self, t: float, momentum, rates: MomentumRates) -> None:
        """Book the sample at time t [s]: the momentum then and its rates."""
        f = rates.force + rates.defect_force
        m = rates.moment + rates.defect_moment
        fb = f if rates.force_before is None else rates.force_before + rates.defect_force
        mb = m if rates.moment_before is None else rates.moment_before + rates.defect_moment
        if self._last is None:
            self.p0, self.h0 = np.array(momentum.linear), momentum.angular_origin
        else:
            t0, f0, m0 = self._last
            self.impulse = self.impulse + 0.5 * (t - t0) * (f0 + fb)
            self.angular_impulse += 0.5 * (t - t0) * (m0 + mb)
        self._last = (t, f, m)
        self.p, self.h = np.array(momentum.linear), momentum.angular_origin
        self.scale_p = max(self.scale_p, float(np.max(np.abs(momentum.linear))),
                           float(np.max(np.abs(self.impulse))))
        self.scale_h = max(self.scale_h, abs(momentum.angular_origin), abs(self.angular_impulse))

    @property
    def residual_linear(self) -> np.ndarray:
        """P(t) - P(0) - int (F + D_P) dt (2,) [kg m/s]."""
        return self.p - self.p0 - self.impulse

    @property
    def residual_angular(self) -> float:
        """H(t) - H(0) - int (M + D_H) dt [kg m^2/s]."""
        return self.h - self.h0 - self.angular_impulse


def base_reaction(model, t: float, y, held=None, mode=None, state=None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """What each chain needs from the base at (t, y): the force (nc, 2) [N] the base exerts on
    the chain at its node 0, and the moment (nc,) [N m] the chain exerts on the base through
    its hinge 0 (spring, damper, motor, stop, lock: the chain's generalized force on psi).

    From the model's own accelerations: the force is the chain's rate of momentum (the
    paper's accelerations: rigid chords, plus the bending inertia and Coriolis terms of the
    full model) less its applied loads and weight; the moment is the moment about node 0 of
    the chain's loads and weight less the rate of its moment of momentum about node 0 (the sum
    of the chain's phi rows, in which every other hinge's moment cancels). Gravity acts on the
    bent rods of the full model and, through its quasi-static slopes, of the reduced model (as
    in their equations), on the chords of the rigid model. One compiled pass over the rods
    (:func:`~rod_sim.core.chain_momentum.chain_base_reaction`)."""
    return _state(model, t, y, held, mode, state).value(_base_reaction)


def _base_reaction(s) -> tuple[np.ndarray, np.ndarray]:
    model, y = s.model, s.y
    n, d = model.n, model.dof
    k = model.rod_constants
    ddphi, dgam, _ = s.value(_accelerations)
    full = model.dof_per_rod == 3
    b = model.chain.base
    gravity = b[kernels.B_GRAVITY] != 0.0
    gx, gy = (float(b[kernels.B_GX]), float(b[kernels.B_GY])) if gravity else (0.0, 0.0)
    # gravity acts on the bent rods of the full model and of the reduced model (its
    # quasi-static slopes), as in their equations; the reduced model's inertia is the chords'
    bent = bool(full or (gravity and model.name == "reduced"))
    if full:
        dgam_rate = y[d + n:d + 2 * n] - y[d + 2 * n:d + 3 * n]
        alpha, beta = y[n:2 * n], y[2 * n:3 * n]
        dy = s.f
        ddal, ddbe = dy[d + n:d + 2 * n], dy[d + 2 * n:d + 3 * n]
    else:
        dgam_rate = ddal = ddbe = k.zeros
        alpha, beta = s.bending if bent else (k.zeros, k.zeros)
    table = model.table
    force = np.empty((len(table.roots), 2))
    moment = np.empty(len(table.roots))
    chain_momentum.chain_base_reaction(
        s.nodes, s.value(_node_accelerations), model.rod_starts, table.roots, table.chain,
        s.cos_phi, s.sin_phi, s.phi_rate, ddphi, dgam, dgam_rate, alpha, beta, ddal, ddbe,
        k.half_l, k.ml, k.C, k.l3_3, k.l3_20, k.l3_30, k.half_ml_l, k.mu, s.loads, gx, gy,
        full, bent, force, moment)
    return force, moment


def injected_power(model, t: float, y, held=None, mode=None, state=None) -> float:
    """[W] the power a prescribed base delivers to the chains: sum over chains of F_c . v_0c
    - psi' M_c (:func:`base_reaction`; v_0c the velocity of the chain's node 0). 0 for a fixed
    or free base (a free base's work is internal to the system)."""
    if model.base_mode != kernels.MODE_PRESCRIBED:
        return 0.0
    return _state(model, t, y, held, mode, state).value(_injected_power)


def _injected_power(s) -> float:
    force, moment = s.value(_base_reaction)
    v0 = s.velocities[s.model.table.roots]
    return float(np.sum(force * v0) - s.base.psi_rate * np.sum(moment))
