"""The hinge rates and the power of the applied loads and of the hinge dampers, compiled.

:class:`~rod_sim.core.state.State` evaluates these laws for one state, and a balance sample's
central difference evaluates them for its two moved states in one call
(:func:`net_power_pair`): both through the helpers below, so that each law is written once.
Sums run from rod 0 to rod n - 1.
"""
from __future__ import annotations

import numpy as np

from .chain_momentum import chain_base_reaction
from .jit import njit
from .kernels import load_forces, motion_eval


@njit(inline="always")
def _deflection_rate(dphi, dalpha, dbeta, i):
    """d/dt Delta phi_i [rad/s] of hinge i > 0 joining rods i - 1 and i (eq. (2))."""
    return dphi[i] + dalpha[i] - (dphi[i - 1] + dbeta[i - 1])


@njit
def deflection_rates(dphi, dalpha, dbeta, first, first_rate, out):
    """d/dt Delta phi_h (n,) [rad/s] into ``out`` from phi', alpha', beta' (n,) [rad/s]: each
    hinge's right rod's phi' + alpha' minus its left rod's phi' + beta'; the rods ``first``
    (each chain's first rod, int array; rod 0 always) turn against ``first_rate`` (the
    base's rate [rad/s]) instead."""
    n = dphi.shape[0]
    if n:
        out[0] = dphi[0] + dalpha[0] - 0.0
    for i in range(1, n):
        out[i] = _deflection_rate(dphi, dalpha, dbeta, i)
    for j in range(first.shape[0]):
        i = first[j]
        out[i] = dphi[i] + dalpha[i] - first_rate


@njit(inline="always")
def _power_terms(f, i, vx, vy, d, nu):
    """Node i + 1's force on its velocity (vx, vy) plus hinge i's motor on its rate d, and
    hinge i's damper power nu_i d^2 [W]."""
    return f[i, 0] * vx + f[i, 1] * vy + f[i, 2] * d, nu[i] * d * d


@njit
def chain_powers(vx, vy, ddelta, nu, f, out):
    """The power of the nodal forces and the hinge motors, sum_k F_k . v_k + sum_h T_h
    Delta phi_h', and the power dissipated in the hinge dampers, sum_h nu_h Delta phi_h'^2
    [W], into ``out`` (2,). ``vx``, ``vy`` (n,) [m/s]: the end node of each rod; ``ddelta``
    (n,) [rad/s]: the hinge rates; ``nu`` (n,) [N m s/rad]; ``f`` (>= n, 3): rows X, Y [N] at
    node k + 1 and T [N m] at hinge k."""
    load = 0.0
    damper = 0.0
    for i in range(ddelta.shape[0]):
        a, b = _power_terms(f, i, vx[i], vy[i], ddelta[i], nu)
        load += a
        damper += b
    out[0] = load
    out[1] = damper


@njit(inline="always")
def _span_powers(neg_l, l, nu, sin_phi, cos_phi, dphi, ddelta, f, a, b, v0x, v0y, load,
                 damper):
    """(load, damper) [W] plus the load and damper powers of rods a .. b - 1 of one chain
    whose node 0 moves at (v0x, v0y) [m/s]: each end node moves at that velocity plus the
    prefix sum of l_j phi_j' (-sin phi_j, cos phi_j) from rod a (``origin + cumsum``, as
    :func:`~rod_sim.core.kinematics.chain_nodes`; ``neg_l`` = -l); the sums run rod by rod
    on from the ``load`` and ``damper`` given."""
    sx = 0.0
    sy = 0.0
    for i in range(a, b):
        sx += neg_l[i] * sin_phi[i] * dphi[i]
        sy += l[i] * cos_phi[i] * dphi[i]
        p, d = _power_terms(f, i, v0x + sx, v0y + sy, ddelta[i], nu)
        load += p
        damper += d
    return load, damper


@njit
def plain_powers(neg_l, l, nu, sin_phi, cos_phi, dphi, ddelta, f, out):
    """:func:`chain_powers` of one chain on a fixed base (the paper's layout)
    from its rods' sin phi, cos phi, phi' [rad/s] and hinge rates (n,) each, into ``out``
    (2,); ``l`` (n,) [m], ``neg_l`` = -l."""
    out[0], out[1] = _span_powers(neg_l, l, nu, sin_phi, cos_phi, dphi, ddelta, f, 0,
                                  dphi.shape[0], 0.0, 0.0, 0.0, 0.0)


@njit(inline="always")
def _base_load_power(f, n, cos_psi, sin_psi, cx, cy, vx, vy, wz, w):
    """The power [W] of a free base's loads and wheel motor: row n of ``f`` (Fx, Fy [N] at
    the base's centre of mass, moment [N m]) on the centre's velocity and the base's rate
    ``wz`` [rad/s], and the wheel motor (row n + 1, column 2 [N m]) on the wheel's relative
    rate ``w`` [rad/s]; (cx, cy) [m] the centre in the base frame, (vx, vy) [m/s] the frame
    origin's velocity, psi its angle."""
    rc0 = cos_psi * cx - sin_psi * cy
    rc1 = sin_psi * cx + cos_psi * cy
    vc0 = vx - wz * rc1
    vc1 = vy + wz * rc0
    return f[n, 0] * vc0 + f[n, 1] * vc1 + f[n, 2] * wz + f[n + 1, 2] * w


@njit
def base_load_power(f, n, cos_psi, sin_psi, cx, cy, vx, vy, wz, w):
    """:func:`_base_load_power` from Python (one state's powers)."""
    return _base_load_power(f, n, cos_psi, sin_psi, cx, cy, vx, vy, wz, w)


@njit(inline="always")
def _rigid_hinge(yr, dof, seg, j, i, psi, wz):
    """(theta [rad], theta' [rad/s]) of hinge i of chain j (rods seg[j] .. seg[j + 1] - 1) at
    the state ``yr``: rod i's angle less its left rod's, or less the base's angle ``psi`` (rate
    ``wz``) for the chain's first hinge."""
    if i == seg[j]:
        return yr[i] - psi, yr[dof + i] - wz
    return yr[i] - yr[i - 1], yr[dof + i] - yr[dof + i - 1]


@njit(inline="always")
def _beyond_a_stop(yr, dof, seg, psi, wz, stops):
    """Whether a hinge of the state ``yr`` is beyond one of its stops (:func:`_rigid_hinge`)."""
    for j in range(seg.shape[0] - 1):
        for i in range(seg[j], seg[j + 1]):
            theta, _ = _rigid_hinge(yr, dof, seg, j, i, psi, wz)
            if theta - stops[1, i] > 0.0 or stops[0, i] - theta > 0.0:
                return True
    return False


@njit(inline="always")
def _stop_dissipation(yr, dof, seg, psi, wz, stops, locked):
    """The power [W] the stop contacts dissipate at the state ``yr`` (the part of
    :attr:`~rod_sim.core.state.State.damper_power` beyond the hinge dampers): the sum over
    hinges of (m_h - m_h^elastic) theta_h' with the contact moments m_h of
    :func:`~rod_sim.core.hinges.contact_moments` and their elastic part -k (max(0, theta -
    upper) - max(0, lower - theta)), both zero on the ``locked`` hinges (n,) bool, on the rigid
    hinge angles (:func:`_rigid_hinge`); 0.0 when no hinge is beyond a stop. ``stops`` (4, n):
    lower, upper [rad], stiffness [N m/rad], damping [N m s/rad]."""
    if not _beyond_a_stop(yr, dof, seg, psi, wz, stops):
        return 0.0
    total = 0.0
    for j in range(seg.shape[0] - 1):
        for i in range(seg[j], seg[j + 1]):
            if locked[i]:
                continue
            theta, rate = _rigid_hinge(yr, dof, seg, j, i, psi, wz)
            k = stops[2, i]
            p_hi = theta - stops[1, i]
            p_lo = stops[0, i] - theta
            m = 0.0
            if p_hi > 0.0:
                m = -max(0.0, k * p_hi + stops[3, i] * rate)
            if p_lo > 0.0:
                m = max(0.0, k * p_lo - stops[3, i] * rate)
            elastic = -k * (max(0.0, p_hi) - max(0.0, p_lo))
            total += (m - elastic) * rate
    return total


@njit(inline="always")
def _move(y, hf, r, yr):
    """``yr`` = y + hf (r = 0) or y - hf (r = 1): a balance pair's moved state."""
    if r == 0:
        for i in range(y.shape[0]):
            yr[i] = y[i] + hf[i]
    else:
        for i in range(y.shape[0]):
            yr[i] = y[i] - hf[i]


@njit(inline="always")
def _moved_powers(yr, t, n, dof, seg, first, neg_l, l, nu, table, rows, psi, cb, sb, vx, vy,
                  wz, attach_x, attach_y, stops, locked, has_stops, s, c, zeros, ddelta, f):
    """(load power, damper power) [W] of the moved state ``yr`` at time t [s] with the base
    frame at angle psi (cos, sin = cb, sb), its origin moving at (vx, vy) [m/s] and turning at
    wz [rad/s]: the chains' nodal forces and motors, the hinge dampers and, with
    ``has_stops``, the stop contacts (a free base's own loads are the caller's). Leaves sin
    phi, cos phi in ``s``, ``c``, the hinge rates in ``ddelta`` and the loads in ``f``."""
    for i in range(n):
        s[i] = np.sin(yr[i])
        c[i] = np.cos(yr[i])
    dphi = yr[dof:dof + n]
    deflection_rates(dphi, zeros, zeros, first, wz, ddelta)
    load_forces(t, table, rows, t, f)
    load = 0.0
    damper = 0.0
    for j in range(seg.shape[0] - 1):
        ax, ay = attach_x[j], attach_y[j]
        load, damper = _span_powers(neg_l, l, nu, s, c, dphi, ddelta, f, seg[j],
                                    seg[j + 1], vx - wz * (sb * ax + cb * ay),
                                    vy + wz * (cb * ax - sb * ay), load, damper)
    if has_stops:
        damper -= _stop_dissipation(yr, dof, seg, psi, wz, stops, locked)
    return load, damper


@njit
def net_power_pair(y, hf, n, dof, seg, neg_l, l, nu, table, rows, t_up, t_down, base, free,
                   nb, attach_x, attach_y, cx, cy, stops, locked, has_stops, out):
    """The net power (load power minus damper power) [W] at (t_up, y + hf) and
    (t_down, y - hf), into ``out`` (2,): a balance sample's central difference in one call,
    for a model whose state carries no slope rates (reduced, rigid), on a fixed or free base
    (not a prescribed one: :func:`prescribed_net_power_pair`), any number of chains.

    ``y``, ``hf`` (state_size,): the state [q, q'] with phi' at ``dof``; chain c holds rods
    ``seg[c]`` .. ``seg[c + 1] - 1`` and is attached at (attach_x[c], attach_y[c]) [m] of the
    base frame; ``base`` (3,): the fixed base's pose (x, y [m], psi [rad]); ``free``: the
    base's pose and twist are y's coordinates n .. n + nb - 1 and their rates (``nb`` of
    them: x, y, psi and, with a wheel (nb = 4), its angle); (cx, cy) [m]: its centre of mass in
    its frame.
    The loads at each time are ``rows`` (n + 2, 3), the held inputs, plus the scripted loads
    of ``table`` (:func:`~rod_sim.core.kernels.load_forces`, the one scripted-load law). The
    laws are :class:`~rod_sim.core.state.State`'s: each rod's end node moves at its chain's
    attach point's velocity plus the prefix sum of l_j phi_j' (-sin phi_j, cos phi_j)
    (``origin + cumsum``, as :func:`~rod_sim.core.kinematics.chain_nodes`), each chain's
    first hinge turns against the base's rate, then :func:`_span_powers` chain by chain and a
    free base's :func:`_base_load_power`. With ``has_stops``, the stop contacts' dissipation
    (:func:`_stop_dissipation`; ``stops`` (4, n), ``locked`` (n,) bool: the hinges held
    rigid) joins the damper power."""
    yr = np.empty(y.shape[0])
    s = np.empty(n)
    c = np.empty(n)
    zeros = np.zeros(n)
    first = seg[:-1].astype(np.int64)
    ddelta = np.empty(n)
    f = np.empty((n + 2, 3))
    bi = n                  # x_B in q: after the chains' angles (one coordinate per rod)
    for r in range(2):
        _move(y, hf, r, yr)
        t = t_up if r == 0 else t_down
        if free:
            psi = yr[bi + 2]
            vx, vy, wz = yr[dof + bi], yr[dof + bi + 1], yr[dof + bi + 2]
            w = yr[dof + bi + 3] if nb > 3 else 0.0
        else:
            psi = base[2]
            vx = vy = wz = w = 0.0
        cb, sb = np.cos(psi), np.sin(psi)
        load, damper = _moved_powers(yr, t, n, dof, seg, first, neg_l, l, nu, table, rows,
                                     psi, cb, sb, vx, vy, wz, attach_x, attach_y, stops,
                                     locked, has_stops, s, c, zeros, ddelta, f)
        if free:
            load += _base_load_power(f, n, cb, sb, cx, cy, vx, vy, wz, w)
        out[r] = load - damper


@njit
def prescribed_net_power_pair(y, hf, f_up, f_down, alpha_up, beta_up, alpha_down, beta_down, n,
                              dof, seg, first, starts, roots, chain_of_rod, neg_l, l, nu, table,
                              rows, t_up, t_down, base, motion, attach_x, attach_y, half_l, ml,
                              C, l3_3, l3_20, l3_30, half_ml_l, mu, gx, gy, bent, stops,
                              locked, has_stops, out):
    """:func:`net_power_pair` on a prescribed base: the net power [W] at (t_up, y + hf) and
    (t_down, y - hf), into ``out`` (2,), for a model without slope rates (reduced, rigid),
    any number of chains: the load power minus the damper power (with the stop contacts'
    dissipation when ``has_stops``, as in :func:`net_power_pair`) plus the power
    the base delivers to the chains (:func:`~rod_sim.core.momentum.injected_power`: sum over
    chains of F_c . v_0c - psi' M_c, the base's reaction
    :func:`~rod_sim.core.chain_momentum.chain_base_reaction`).

    The reaction needs each moved state's accelerations: ``f_up``, ``f_down``
    (state_size,) are the right-hand sides at the two moved states and ``alpha_*``,
    ``beta_*`` (n,) [rad] their slopes (used when ``bent``: gravity on the reduced model's
    bent rods; zeros otherwise). The base's pose, twist and acceleration at each time are
    ``base`` (3,) (x, y [m], psi [rad] at rest) plus the profiles ``motion`` (rows x, y, psi:
    :func:`~rod_sim.core.kernels.motion_eval`). ``first`` (each chain's first rod), ``starts``
    (n,) (each rod's start node row), ``roots`` (nc,) (each chain's node 0 row) and
    ``chain_of_rod`` (n,) index the nodes (n + nc, 2) in scene order; ``half_l`` .. ``mu`` (n,)
    the :class:`~rod_sim.core.models.RodConstants`; (gx, gy) [m/s^2] gravity. The laws are
    :class:`~rod_sim.core.state.State`'s (nodes and their velocities and accelerations as
    ``origin + cumsum``, the first hinge of each chain turning against psi'), with numba's
    sines and cosines."""
    nc = seg.shape[0] - 1
    yr = np.empty(y.shape[0])
    s = np.empty(n)
    c = np.empty(n)
    zeros = np.zeros(n)
    ddelta = np.empty(n)
    f = np.empty((n + 2, 3))
    nodes = np.empty((n + nc, 2))
    acc = np.empty((n + nc, 2))
    v0 = np.empty((nc, 2))
    force = np.empty((nc, 2))
    moment = np.empty(nc)
    for r in range(2):
        _move(y, hf, r, yr)
        if r == 0:
            t, fr, alpha, beta = t_up, f_up, alpha_up, beta_up
        else:
            t, fr, alpha, beta = t_down, f_down, alpha_down, beta_down
        px, vx, ax_b = motion_eval(motion, 0, t)
        py, vy, ay_b = motion_eval(motion, 1, t)
        pp, wz, al_b = motion_eval(motion, 2, t)
        bx = base[0] + px
        by = base[1] + py
        psi = base[2] + pp
        cb, sb = np.cos(psi), np.sin(psi)
        load, damper = _moved_powers(yr, t, n, dof, seg, first, neg_l, l, nu, table, rows,
                                     psi, cb, sb, vx, vy, wz, attach_x, attach_y, stops,
                                     locked, has_stops, s, c, zeros, ddelta, f)
        w2 = wz * wz
        dphi = yr[dof:dof + n]
        ddphi = fr[dof:dof + n]
        for j in range(nc):
            ax, ay = attach_x[j], attach_y[j]
            rx = cb * ax - sb * ay
            ry = sb * ax + cb * ay
            ox = bx + cb * ax - sb * ay         # not bx + rx: the State's rounding
            oy = by + sb * ax + cb * ay
            v0[j, 0] = vx - wz * (sb * ax + cb * ay)
            v0[j, 1] = vy + wz * (cb * ax - sb * ay)
            a0x = ax_b - al_b * ry - w2 * rx
            a0y = ay_b + al_b * rx - w2 * ry
            o = roots[j]
            nodes[o, 0] = ox
            nodes[o, 1] = oy
            acc[o, 0] = a0x
            acc[o, 1] = a0y
            sx = sy = qx = qy = 0.0
            for k in range(seg[j], seg[j + 1]):
                sx += l[k] * c[k]
                sy += l[k] * s[k]
                w = dphi[k] * dphi[k]
                qx += l[k] * (-s[k] * ddphi[k] - c[k] * w)
                qy += l[k] * (c[k] * ddphi[k] - s[k] * w)
                e = o + 1 + k - seg[j]
                nodes[e, 0] = ox + sx
                nodes[e, 1] = oy + sy
                acc[e, 0] = a0x + qx
                acc[e, 1] = a0y + qy
        chain_base_reaction(nodes, acc, starts, roots, chain_of_rod, c, s, dphi, ddphi, zeros,
                            zeros, alpha, beta, zeros, zeros, half_l, ml, C, l3_3, l3_20, l3_30,
                            half_ml_l, mu, f, gx, gy, False, bent, force, moment)
        injected = 0.0
        turning = 0.0
        for j in range(nc):
            injected += force[j, 0] * v0[j, 0] + force[j, 1] * v0[j, 1]
            turning += moment[j]
        out[r] = (load - damper) + (injected - wz * turning)
