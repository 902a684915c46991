"""Radau's Newton systems for the chain models in O(n): no Jacobian matrix, no dense LU.

Radau IIA needs (g I - J) z = r for the Jacobian J = [[0, I], [K, D]] of y = [q, v] at a real
g and a complex g (:mod:`rod_sim.core.radau`). Here K = da/dq and D = da/dv are replaced by
their elastic parts, K ~ -M^{-1} K_el and D ~ -M^{-1} C_el, with M the model's inertia at the
angles of the last "Jacobian" update, K_el the hinge springs (plus, for the rigid and reduced
models, the stop contacts in contact), the bending stiffness and the tension stiffness K_T
(diagonal: l_k times the average of rod k's end tensions, on its angle, at the Jacobian
update; the stiffness of a limp line under load, which the velocity terms and dM/dq a carry),
C_el the hinge dampers (plus the contacts' damping). Then

    (g^2 M + g C_el + K_el) x = M (r_v + g r_q) + C_el r_q,   z = [x, g x - r_q],

and (M + (C_el / g + K_el / g^2)) is the structure the kernels' chain solve takes: every
sprung hinge a compliant constraint with compliance -1 / (nu_h / g + kappa_h / g^2) (its
multiplier acts on the phi rows and, in the reduced model, on the hinge's slope rows), the
full model's bending stiffness folded into each rod's 2 x 2 bending block, K_T / g^2 added
to each rod's angle diagonal A_kk. One solve costs about one right-hand side. What is left
out (the rest of the velocity terms and of dM/dq times the accelerations, the load's
dependence on phi, and in the full model the stop contacts) only slows the simplified Newton
iteration down: docs/bench.md ("radau-jit") gives the measured
effect. What is kept exact is every lock's constraint (:func:`chain_solve`): an increment
that broke a lock and was solved as if it could not would never be corrected, and neither
the Newton test nor the error estimate would see it.

The Newton part of the Radau workspace (:class:`rod_sim.core.radau.RadauWork`): ``jac``
(2 n + 1,) = phi_J (n,) [rad], the base angle psi_J [rad] and K_T (n,) [N m/rad], ``real``,
``real_aux`` the real Newton Extra and Chain, ``cplx``,
``cplx_aux`` the complex Newton Extra and Chain (:func:`chain_workspace`).
"""
from __future__ import annotations

import math

import numpy as np

from . import kernels as _k
from .jit import njit


def chain_workspace(chain, extra, size):
    """The Newton part of the Radau workspace for a chain model: (jac, real, real_aux, cplx,
    cplx_aux) of :class:`rod_sim.core.radau.RadauWork`."""
    n = chain.l.shape[0]
    zeros3, zeros4 = np.zeros((3, n)), np.zeros((4, n))
    parts = [np.zeros(2 * n + 1)]         # phi_J, the base angle psi_J, the tension stiffness
    for dtype in (float, complex):
        ex = _k.make_extra(zeros3, zeros4, np.zeros(n), np.zeros(n, bool), np.zeros(n, bool),
                           kind=extra.kind, dtype=dtype, nchains=chain.seg.shape[0] - 1)
        ch = chain._replace(c105=np.array(chain.c105, dtype=dtype),
                            c140=np.array(chain.c140, dtype=dtype),
                            Akk=np.array(chain.Akk, dtype=dtype))
        parts += [ex, ch]
    return tuple(parts)


@njit
def tension_stiffness(problem, t_side, t, y, f, out):
    """out (n,) [N m/rad]: l_k times the average T_k of rod k's axial tensions at its two ends
    at (t, y) (0 where that is a compression), the diagonal that tension adds to the
    stiffness of the rods' angles (for a chain hanging under gravity, d^2V/dphi_k^2 = l_k T_k
    exactly). The tension comes from the chords' accelerations (phi'' and a free base's from
    f = rhs(t, y) (N,), a prescribed base's from its profiles), the node and rod masses, the
    applied nodal loads and gravity, summed from each chain's tip; the slopes' motion is left
    out (it is a Newton matrix, not the dynamics). Writes the loads and the base's state into
    the scratch of ``problem.extra``, as a right-hand side does."""
    chain, extra, loads, held = problem
    n = chain.l.shape[0]
    m = y.shape[0] // 2
    i0 = 3 * n if extra.kind == _k.KIND_FULL else n
    nb = m - i0
    forces = extra.forces
    _k.load_forces(t, loads, held, t_side, forces)
    _k._base_state(t, y, chain, extra, i0, m)
    bk = extra.bk
    gx = chain.base[_k.B_GX]
    gy = chain.base[_k.B_GY]
    if nb > 0:
        abx, aby, apsi = f[m + i0], f[m + i0 + 1], f[m + i0 + 2]
    else:
        abx, aby, apsi = bk[_k.BK_AX], bk[_k.BK_AY], bk[_k.BK_APSI]
    w2 = bk[_k.BK_W] * bk[_k.BK_W]
    cps = bk[_k.BK_COS]
    sps = bk[_k.BK_SIN]
    l = chain.l
    seg = chain.seg
    acc = np.empty((n, 4))            # rod k: its centre's and its tip node's accelerations
    for ci in range(seg.shape[0] - 1):
        k0, k1 = seg[ci], seg[ci + 1]
        rx = cps * chain.attach[ci, 0] - sps * chain.attach[ci, 1]
        ry = sps * chain.attach[ci, 0] + cps * chain.attach[ci, 1]
        px = abx - apsi * ry - w2 * rx                     # the chain's hinge-0 point
        py = aby + apsi * rx - w2 * ry
        for k in range(k0, k1):
            c, s = math.cos(y[k]), math.sin(y[k])
            tx = l[k] * (-s * f[m + k] - c * y[m + k] * y[m + k])
            ty = l[k] * (c * f[m + k] - s * y[m + k] * y[m + k])
            acc[k, 0] = px + 0.5 * tx
            acc[k, 1] = py + 0.5 * ty
            px += tx
            py += ty
            acc[k, 2] = px
            acc[k, 3] = py
        # the force the part beyond rod k's near end takes from the rod before it (or the
        # base), summed from the chain's tip: mass times (acceleration - gravity) less loads
        sx = sy = 0.0
        for k in range(k1 - 1, k0 - 1, -1):
            mu = chain.mu[k]
            far_x = sx + mu * (acc[k, 2] - gx) - forces[k, 0]
            far_y = sy + mu * (acc[k, 3] - gy) - forces[k, 1]
            mr = chain.m[k] * l[k]
            near_x = far_x + mr * (acc[k, 0] - gx)
            near_y = far_y + mr * (acc[k, 1] - gy)
            tension = -0.5 * (math.cos(y[k]) * (near_x + far_x)
                              + math.sin(y[k]) * (near_y + far_y))
            out[k] = l[k] * max(0.0, tension)
            sx, sy = near_x, near_y


@njit
def chain_jac(rhs, problem, t_side, t, y, f, work, stats):
    """The "Jacobian" update: the inertia is taken at the current angles, and the tension
    stiffness (:func:`tension_stiffness`) there."""
    chain = problem.chain
    phi_j = work.jac
    n = chain.l.shape[0]
    for k in range(n):
        phi_j[k] = y[k]
    nb = int(chain.base[_k.B_NB])
    phi_j[n] = y[y.shape[0] // 2 - nb + 2] if nb > 0 else 0.0
    tension_stiffness(problem, t_side, t, y, f, phi_j[n + 1:])
    if stats.shape[0] > 3:
        stats[3] += 1


@njit(inline="always")
def _setup(chain, extra, phi_j, g, nex, nch):
    """Compliances and weights of the Newton Extra ``nex``, the bending block of ``nch`` and
    its rods' angle diagonal (the tension stiffness of the Jacobian update, in ``phi_j``) for
    the shift g (real or complex) in the mode of ``extra``."""
    n = chain.l.shape[0]
    full = extra.kind == _k.KIND_FULL
    g2 = g * g
    for k in range(n):
        nch.Akk[k] = chain.Akk[k] + phi_j[n + 1 + k] / g2
    for h in range(n):
        nex.pinned[h] = extra.pinned[h]
        if extra.locked[h] != 0:
            nex.locked[h] = 1
            nex.comp[h] = 0.0
            nex.gw[h] = 0.0
            continue
        s_hinge = chain.nu[h] / g + chain.kappa[h] / g2
        s = s_hinge
        if not full and extra.contact[h] != 0.0:
            s = s + extra.stop_c[h] / g + extra.stop_k[h] / g2
        if s == 0.0:
            nex.locked[h] = 0
            nex.comp[h] = 0.0
            nex.gw[h] = 0.0
        else:
            nex.locked[h] = 1
            nex.comp[h] = -1.0 / s
            nex.gw[h] = s_hinge / s
    if full:
        for k in range(n):
            nch.c105[k] = chain.c105[k] + chain.Kt[k] / g2
            nch.c140[k] = chain.c140[k] - 0.5 * chain.Kt[k] / g2


@njit
def chain_factor(chain, extra, work, g_real, g_cplx, stats):
    """Set up the real and complex Newton systems (O(n)); always succeeds."""
    _setup(chain, extra, work.jac, g_real, work.real, work.real_aux)
    _setup(chain, extra, work.jac, g_cplx, work.cplx, work.cplx_aux)
    return True


@njit
def chain_solve(chain, extra, phi_j, nex, nch, g, r, out):
    """out (N,) = (g I - J)^{-1} r (N,) for the approximate J of the module docstring, through
    the Newton Extra ``nex`` / Chain ``nch`` set up for this g; ``out`` must not alias r. A
    free base's coordinates (after the chains' in q) are part of the system: its inertia and
    the hinge-0 dampers and springs couple it to every chain."""
    n = chain.l.shape[0]
    m = r.shape[0] // 2
    full = extra.kind == _k.KIND_FULL
    i0 = 3 * n if full else n
    nb = m - i0
    W = nex.work
    bk = nex.bk
    g2 = g * g
    for i in range(bk.shape[0]):
        bk[i] = 0.0
    psi = phi_j[n]
    bk[_k.BK_PSI] = psi
    bk[_k.BK_COS] = math.cos(psi)
    bk[_k.BK_SIN] = math.sin(psi)
    for i in range(nb):
        bk[_k.BK_V + i] = r[m + i0 + i] + g * r[i0 + i]
    # c' = r_v + g r_q into spare columns, then M c' + C r_q into the solve's right-hand side
    for k in range(n):
        W[k, _k.W_C] = math.cos(phi_j[k])
        W[k, _k.W_S] = math.sin(phi_j[k])
        W[k, _k.W_GP] = r[m + k] + g * r[k]
        W[k, _k.W_GA] = r[m + n + k] + g * r[n + k] if full else 0.0
        W[k, _k.W_COR] = r[m + 2 * n + k] + g * r[2 * n + k] if full else 0.0
    # A locked hinge h holds C_h q = const (between rods: phi_h (+ alpha_h) - phi_p
    # (- beta_p); hinge 0: phi_1 (+ alpha_1) - psi, psi = 0 on a fixed base, psi(t) on a
    # prescribed one), and the exact Jacobian's rows give C_h a = 0 (the lock's reaction makes
    # it so) or psi'': its increments are C_h x = C_h c' / g^2, not 0 (they are 0 only while
    # the stages keep the lock exactly; a predictor that does not would never be corrected,
    # nor would the Newton test or the error estimate see it). For each: d_h = C_h c', split off
    # d_h r_h (r_h: the rigid turn of rods h.. of its chain, C_h r_h = 1 and C_j r_h = 0 for
    # every other hinge; no spring, damper or bending acts on it, so A r_h = g^2 M r_h + K_T
    # r_h, the tension stiffness's part moved to the right-hand side below), solve the rest
    # with C x = 0, add d_h r_h / g^2 back (W_TN holds the sums of d over rods)
    any_lock = False
    seg = chain.seg
    for ci in range(seg.shape[0] - 1):
        k0 = seg[ci]
        acc = 0.0 * g
        for k in range(k0, seg[ci + 1]):
            if extra.locked[k] != 0:
                any_lock = True
                d = W[k, _k.W_GP] + W[k, _k.W_GA]
                if k > k0:
                    p = chain.prev[k]
                    d -= W[p, _k.W_GP] + W[p, _k.W_COR]
                elif nb > 0:
                    d -= bk[_k.BK_V + 2]              # a free base's psi
                acc += d
            W[k, _k.W_TN] = acc
    if any_lock:
        for k in range(n):
            W[k, _k.W_GP] -= W[k, _k.W_TN]
    # inertia product (full kind: the slope rows get m^{gamma phi} c' even for the reduced
    # model, whose Newton system keeps them)
    _k.inertia_columns(True, chain, W, _k.W_GP, _k.W_GA, _k.W_COR, _k.W_FP, _k.W_FA, _k.W_FB,
                       bk[_k.BK_V:_k.BK_V + 4], bk[_k.BK_M:_k.BK_M + 4], bk[_k.BK_COS],
                       bk[_k.BK_SIN])
    # damping C_el r_q
    r_psi = r[i0 + 2] if nb > 0 else 0.0
    for h in range(n):
        if extra.locked[h] != 0:
            continue
        p = chain.prev[h]
        sig = r[h] - (r[p] if p >= 0 else r_psi)
        if full:
            sig += r[n + h] - (r[2 * n + p] if p >= 0 else 0.0)
        nu = chain.nu[h]
        cphi = nu
        if not full and extra.contact[h] != 0.0:
            cphi += extra.stop_c[h]
        W[h, _k.W_FP] += cphi * sig
        W[h, _k.W_FA] += nu * sig
        if p >= 0:
            W[p, _k.W_FP] -= cphi * sig
            W[p, _k.W_FB] -= nu * sig
        else:
            bk[_k.BK_M + 2] -= cphi * sig
    for k in range(n):
        if any_lock:                            # the split-off rigid turns' K_T r_h d_h / g^2
            W[k, _k.W_FP] -= phi_j[n + 1 + k] * W[k, _k.W_TN] / g2
        W[k, _k.W_FP] /= g2
        W[k, _k.W_FA] /= g2
        W[k, _k.W_FB] /= g2
    bk[_k.BK_FX] = bk[_k.BK_M] / g2
    bk[_k.BK_FY] = bk[_k.BK_M + 1] / g2
    bk[_k.BK_FPSI] = bk[_k.BK_M + 2] / g2
    bk[_k.BK_FTH] = bk[_k.BK_M + 3] / g2
    if not _k.chain_solve(extra.kind, nch, nex, W):
        for i in range(out.shape[0]):
            out[i] = np.nan
        return
    for k in range(n):
        out[k] = W[k, _k.W_X]
        if any_lock:
            out[k] += W[k, _k.W_TN] / g2
        if full:
            out[n + k] = W[k, _k.W_A]
            out[2 * n + k] = W[k, _k.W_B]
    for i in range(nb):
        out[i0 + i] = bk[_k.BK_AX + i] if i < 3 else bk[_k.BK_ATH]
    for i in range(m):
        out[m + i] = g * out[i] - r[i]
