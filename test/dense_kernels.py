"""Compiled right-hand sides of the three models (the hot path).

All kernels share one calling convention so that the compiled integrators can take any of
them: ``rhs(t, y, chain, extra, loads, held, t_side, out)`` writes dy/dt into ``out``.

- ``chain`` = (l, m, mu, Kt, kappa, nu, Mt, C): arrays (n,) of rod length [m], mass per
  length [kg/m], node mass [kg], 4 EI / l [N m/rad], hinge stiffness [N m/rad], hinge damping
  [N m s/rad], tail mass M_k [kg] and m l^2 / 12 [kg m].
- ``extra`` = (P_alpha, P_beta, B_inv, work, *hinge): reduced-model constants P =
  [kappa^{gamma phi}]^T [b^{gamma gamma}]^{-1} split into its alpha and beta halves (n, n)
  each and B_inv = [b^{gamma gamma}]^{-1} (2n, 2n) (other models: zeros, unused), ``work``, a
  scratch array of ``workspace_size(n)`` floats so that a call allocates nothing (the
  kernels are therefore not re-entrant: one model instance per thread), and ``hinge``, the
  hinge features in the current mode, flat in ``extra[4:]`` (see :data:`HINGE_FIELDS`; all
  zeros/infinite for a plain chain, which then runs exactly the paper's equations; flat
  because every read of a nested tuple would reference-count all of its arrays).
- ``loads`` = (node, axis, shape, amplitude, start, duration) arrays describing scripted loads;
  ``held`` (n, 2) the held (commanded) nodal forces [N]; ``t_side`` a time strictly inside the
  current segment between load breakpoints, which decides which side of a jump applies.

The mass matrix and velocity terms are assembled entry by entry in O(n^2) without Python
loops; the linear solve is a small in-place Gaussian elimination (O(n^3)). The helpers are
inlined into the kernels at numba IR level (``inline="always"``): at n = 8 the array views and
reference counting of separate calls cost ~20 % of a right-hand side.
"""
from __future__ import annotations

import math

import numpy as np

from rod_sim.core.dense_lu import _pivot, lu_inplace, lu_solve  # noqa: F401
from rod_sim.core.jit import njit
from rod_sim.core.kernels import scripted_value  # noqa: F401  (the one load law, not under test)


@njit(inline="always")
def hinge_angle(phi, dphi, h):
    """Rigid hinge angle theta_h [rad] and its rate of the one chain on the ground."""
    if h == 0:
        return phi[0], dphi[0]
    return phi[h] - phi[h - 1], dphi[h] - dphi[h - 1]


@njit(inline="always")
def load_forces(t, loads, held, t_side, out):
    """Nodal forces (n, 2) [N]: the held ones (held[:, :2]) plus the scripted chain-node loads
    (rows < n, columns x, y of the models' load table)."""
    row, col, shape, amp, start, dur = loads
    n = out.shape[0]
    for k in range(n):
        out[k, 0] = held[k, 0]
        out[k, 1] = held[k, 1]
    for i in range(row.shape[0]):
        if row[i] < n and col[i] < 2:
            out[row[i], col[i]] += scripted_value(t, shape[i], amp[i], start[i], dur[i], t_side)

SHAPE_PULSE, SHAPE_CONSTANT, SHAPE_STEP = 0, 1, 2

HINGE_FIELDS = ("H", "flags", "T_row", "T_col", "T_val", "C_row", "C_col", "C_val", "pivots",
                "scratch")
"""``extra[4:14]``. ``H`` (8, n) float, rows: rest-angle generalized forces on phi, alpha,
beta [N m] (kappa theta_rest dDelta/dq: kr_h - kr_{h+1}, kr_h, -kr_{h+1}); stop angles lower,
upper [rad] (+-inf: none); contact stiffness [N m/rad] and damping [N m s/rad]; contact
state (+1 in contact with the upper stop, -1 the lower, 0 free: the contact law applies by
mode, switched at located crossings, not by the sign of the penetration). ``flags`` int64
(4,) = [any hinge in contact, constrained, r, rows of C]; the constraint basis T (dof, r)
and the constraint matrix C (rows, dof) as coordinate lists (row, col int64, value float;
the full model solves with Lagrange multipliers through its Schur complement, the others
with T); ``pivots`` int64 (n,) and ``scratch`` floats (3 dof^2 + 2 dof) for those solves."""


@njit(inline="always")
def generalized_forces(l, c, s, forces, out):
    """Q_k = l_k (c_k sum_{j>=k} Y_j - s_k sum_{j>=k} X_j) [N m] into out (n,)."""
    n = l.shape[0]
    sx = 0.0
    sy = 0.0
    for k in range(n - 1, -1, -1):
        sx += forces[k, 0]
        sy += forces[k, 1]
        out[k] = l[k] * (c[k] * sy - s[k] * sx)


@njit(inline="always")
def assemble(c, s, dphi, chain, A, Ma, Mb, g_phi, g_alpha):
    """One pass over rod pairs, given c = cos(phi), s = sin(phi) (n,) and phi_dot (n,):
    the inertia blocks m^{phi phi} (A), m^{phi alpha} (Ma), m^{phi beta} (Mb), each (n, n),
    g^{phi phi} Lambda phi_dot into g_phi (n,) and g^{alpha phi} Lambda phi_dot into
    g_alpha (n,) (g^{beta phi} Lambda phi_dot = -g_alpha)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    for k in range(n):
        gp = 0.0
        ga = 0.0
        for j in range(n):
            ckj = c[k] * c[j] + s[k] * s[j]
            skj = s[k] * c[j] - c[k] * s[j]
            w = dphi[j] * dphi[j]
            if j < k:
                llM = l[k] * l[j] * Mt[k]
                A[k, j] = llM * ckj
                gp += llM * skj * w
                ga += C[k] * l[j] * skj * w
                Ma[k, j] = 0.0
                Mb[k, j] = 0.0
            elif j > k:
                llM = l[k] * l[j] * Mt[j]
                A[k, j] = llM * ckj
                gp += llM * skj * w
                Ma[k, j] = C[j] * l[k] * ckj
                Mb[k, j] = -Ma[k, j]
        ml3 = m[k] * l[k] ** 3
        A[k, k] = l[k] ** 2 * (Mt[k] - m[k] * l[k] / 2.0) + ml3 / 3.0
        Ma[k, k] = ml3 / 30.0
        Mb[k, k] = -ml3 / 20.0
        g_phi[k] = gp
        g_alpha[k] = ga


@njit
def mass_blocks(phi, chain, A, Ma, Mb):
    """Inertia blocks m^{phi phi} (A), m^{phi alpha} (Ma), m^{phi beta} (Mb), each (n, n)."""
    n = phi.shape[0]
    assemble(np.cos(phi), np.sin(phi), np.zeros(n), chain, A, Ma, Mb, np.empty(n), np.empty(n))


@njit
def rigid_velocity_terms(phi, dphi, chain, g_phi, g_alpha):
    """g^{phi phi} Lambda phi_dot into g_phi (n,), g^{alpha phi} Lambda phi_dot into g_alpha
    (n,); g^{beta phi} Lambda phi_dot = -g_alpha."""
    n = phi.shape[0]
    assemble(np.cos(phi), np.sin(phi), dphi, chain, np.empty((n, n)), np.empty((n, n)),
             np.empty((n, n)), g_phi, g_alpha)


@njit(inline="always")
def rigid_hinge_moments(phi, dphi, kappa, nu, out):
    """Hinge moments with gamma = 0: kappa_h dphi_h + nu_h d(dphi_h)/dt [N m] into out (n,)."""
    n = phi.shape[0]
    for h in range(n):
        d, dd = hinge_angle(phi, dphi, h)
        out[h] = kappa[h] * d + nu[h] * dd


@njit(inline="always")
def solve_inplace(A, b):
    """Solve A x = b by Gaussian elimination with partial pivoting; x overwrites b.

    A (n, n) is destroyed. Returns False when A is singular (a zero pivot)."""
    n = b.shape[0]
    for col in range(n):
        piv, best = _pivot(A, col)
        if best == 0.0:
            return False
        if piv != col:
            for c2 in range(col, n):
                tmp = A[col, c2]
                A[col, c2] = A[piv, c2]
                A[piv, c2] = tmp
            tmp = b[col]
            b[col] = b[piv]
            b[piv] = tmp
        inv = 1.0 / A[col, col]
        # Row slices (contiguous 1-D views) let LLVM vectorise the update: 2x faster at
        # n = 128 than indexing A[r, c2] (same operations in the same order).
        pivot_row = A[col, col + 1:]
        b_col = b[col]
        for r in range(col + 1, n):
            f = A[r, col] * inv
            row = A[r, col + 1:]
            for c2 in range(pivot_row.shape[0]):
                row[c2] -= f * pivot_row[c2]
            b[r] -= f * b_col
    for r in range(n - 1, -1, -1):
        acc = b[r]
        for c2 in range(r + 1, n):
            acc -= A[r, c2] * b[c2]
        b[r] = acc / A[r, r]
    return True


@njit(inline="always")
def hinge_forces(phi, dphi, H, flags, out):
    """Add the rest-angle and stop-contact generalized forces on phi (n,) [N m] to out."""
    n = phi.shape[0]
    for k in range(n):
        out[k] += H[0, k]
    if flags[0] == 0:
        return
    for h in range(n):
        th, dth = hinge_angle(phi, dphi, h)
        m = 0.0
        if H[7, h] > 0.0:
            m = -max(0.0, H[5, h] * (th - H[4, h]) + H[6, h] * dth)
        elif H[7, h] < 0.0:
            m = max(0.0, H[5, h] * (H[3, h] - th) - H[6, h] * dth)
        out[h] += m
        if h > 0:
            out[h - 1] -= m


@njit(inline="always")
def projected_solve(M, f, r, rows, cols, vals, ws, out):
    """out = T (T^T M T)^{-1} T^T f for the constraint basis T (d, r) given as coordinate
    lists (M (d, d) and f (d,) are kept; ws scratch). Returns False when T^T M T is
    singular."""
    d = f.shape[0]
    for i in range(d):
        out[i] = 0.0
    if r == 0:
        return True
    MT = ws[0:d * r].reshape((d, r))
    R = ws[d * r:d * r + r * r].reshape((r, r))
    q = ws[d * r + r * r:d * r + r * r + r]
    MT[:, :] = 0.0
    R[:, :] = 0.0
    q[:] = 0.0
    for e in range(rows.shape[0]):
        i = rows[e]
        c = cols[e]
        v = vals[e]
        for a in range(d):
            MT[a, c] += M[a, i] * v
    for e in range(rows.shape[0]):
        i = rows[e]
        c = cols[e]
        v = vals[e]
        q[c] += v * f[i]
        for c2 in range(r):
            R[c, c2] += v * MT[i, c2]
    if not solve_inplace(R, q):
        return False
    for e in range(rows.shape[0]):
        out[rows[e]] += vals[e] * q[cols[e]]
    return True


@njit(inline="always")
def _fill_nan(out):
    for i in range(out.shape[0]):
        out[i] = np.nan


@njit
def workspace_size(n):
    """Length of the scratch array a kernel needs for n rods (see ``extra``)."""
    return 5 * n * n + 16 * n


@njit(inline="always")
def _carve(ws, n):
    """Scratch views: three (n, n) blocks and ten (n,) vectors (no allocation)."""
    nn = n * n
    A = ws[0:nn].reshape((n, n))
    Ma = ws[nn:2 * nn].reshape((n, n))
    Mb = ws[2 * nn:3 * nn].reshape((n, n))
    o = 5 * nn
    return (A, Ma, Mb, ws[3 * nn:4 * nn].reshape((n, n)), ws[4 * nn:5 * nn].reshape((n, n)),
            ws[o:o + n], ws[o + n:o + 2 * n], ws[o + 2 * n:o + 3 * n], ws[o + 3 * n:o + 4 * n],
            ws[o + 4 * n:o + 5 * n], ws[o + 5 * n:o + 6 * n], ws[o + 6 * n:o + 7 * n],
            ws[o + 7 * n:o + 8 * n], ws[o + 8 * n:o + 9 * n], ws[o + 9 * n:o + 11 * n].reshape((n, 2)),
            ws[o + 11 * n:o + 12 * n + 1])


@njit(inline="always")
def _chain_terms(t, phi, dphi, chain, loads, held, t_side, A, Ma, Mb, c, s, gp, ga, f, Q):
    """What every kernel computes first at time t [s] from phi [rad], phi_dot [rad/s] (n,):
    c = cos(phi), s = sin(phi) (n,), the inertia blocks A, Ma, Mb (n, n) and the velocity
    terms gp, ga (n,) (:func:`assemble`), the nodal forces f (n, 2) [N] (:func:`load_forces`)
    and the generalised forces Q (n,) [N m] (:func:`generalized_forces`)."""
    for k in range(phi.shape[0]):
        c[k] = math.cos(phi[k])
        s[k] = math.sin(phi[k])
    assemble(c, s, dphi, chain, A, Ma, Mb, gp, ga)
    load_forces(t, loads, held, t_side, f)
    generalized_forces(chain[0], c, s, f, Q)


@njit(inline="always")
def _rigid_terms(t, phi, dphi, chain, work, loads, held, t_side):
    """What the rigid and reduced kernels share, in scratch views of ``work`` (extra[3]): the
    inertia blocks, cos/sin of phi, the velocity terms, Q (in ``rhs``) and the gamma = 0 hinge
    moments (in ``tau``); v1, v2 are free (n,) scratch vectors."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    A, Ma, Mb, W1, W2, c, s, gp, ga, rhs, tau, v1, v2, v3, f, tau1 = _carve(work, n)
    _chain_terms(t, phi, dphi, chain, loads, held, t_side, A, Ma, Mb, c, s, gp, ga, f, rhs)
    rigid_hinge_moments(phi, dphi, kappa, nu, tau)
    return A, Ma, Mb, c, s, gp, ga, rhs, tau, v1, v2


@njit
def rigid_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Rigid chain (EI -> infinity): y = [phi, phi_dot] (2n,)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    phi = y[:n]
    dphi = y[n:]
    A, Ma, Mb, c, s, gp, ga, rhs, tau, v1, v2 = _rigid_terms(t, phi, dphi, chain, extra[3],
                                                             loads, held, t_side)
    for k in range(n):
        rhs[k] -= gp[k] + tau[k]
        if k + 1 < n:
            rhs[k] += tau[k + 1]
    _finish(phi, dphi, A, rhs, extra[4], extra[5], extra[6], extra[7], extra[8], extra[13],
            out)


@njit(inline="always")
def _finish(phi, dphi, A, rhs, H, flags, T_row, T_col, T_val, scratch, out):
    """Rigid and reduced models: add the hinge features' forces, solve A phi_dd = rhs (on
    the constraint set when hinges are locked), write [phi_dot, phi_dd] into out."""
    n = phi.shape[0]
    hinge_forces(phi, dphi, H, flags, rhs)
    out[:n] = dphi
    if flags[1]:
        ok = projected_solve(A, rhs, flags[2], T_row, T_col, T_val, scratch, out[n:])
    else:
        ok = solve_inplace(A, rhs)
        out[n:] = rhs
    if not ok:
        _fill_nan(out)


@njit
def reduced_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Reduced model, eq. (15): y = [phi, phi_dot] (2n,); extra = (P_alpha, P_beta, ...)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    Pa = extra[0]
    Pb = extra[1]
    n = l.shape[0]
    phi = y[:n]
    dphi = y[n:]
    A, Ma, Mb, c, s, gp, ga, rhs, tau, v1, v2 = _rigid_terms(t, phi, dphi, chain, extra[3],
                                                             loads, held, t_side)
    a_al = v1
    a_be = v2
    H = extra[4]
    for k in range(n):
        nxt = tau[k + 1] if k + 1 < n else 0.0
        a_al[k] = ga[k] + tau[k] - H[1, k]
        a_be[k] = -ga[k] - nxt - H[2, k]
        rhs[k] -= gp[k] + tau[k] - nxt
    # M_r = A - P_alpha m^{alpha phi} - P_beta m^{beta phi} with m^{alpha phi} = Ma^T.
    # Off the diagonal Ma[i, j] = C_j l_i cos(phi_i - phi_j) = -Mb[i, j] (j > i), so
    # sum_{j>i} (Pa - Pb)[k, j] C_j cos(phi_i - phi_j) = c_i U[k, i] + s_i V[k, i] with
    # suffix sums U, V: O(n^2) instead of O(n^3).
    for k in range(n):
        acc = 0.0
        for j in range(n):
            acc += Pa[k, j] * a_al[j] + Pb[k, j] * a_be[j]
        rhs[k] += acc
        su = 0.0
        sv = 0.0
        for i in range(n - 1, -1, -1):
            A[k, i] -= (Pa[k, i] * Ma[i, i] + Pb[k, i] * Mb[i, i]
                        + l[i] * (c[i] * su + s[i] * sv))
            r = (Pa[k, i] - Pb[k, i]) * C[i]
            su += r * c[i]
            sv += r * s[i]
    _finish(phi, dphi, A, rhs, extra[4], extra[5], extra[6], extra[7], extra[8], extra[13],
            out)


@njit
def full_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Full model (9)-(10): y = [phi, alpha, beta, phi_dot, alpha_dot, beta_dot] (6n,).

    The 3n x 3n mass matrix is solved through the Schur complement of its constant
    block-diagonal bending part (one 2 x 2 block per rod)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    phi = y[:n]
    al = y[n:2 * n]
    be = y[2 * n:3 * n]
    dphi = y[3 * n:4 * n]
    dal = y[4 * n:5 * n]
    dbe = y[5 * n:6 * n]
    A, Ma, Mb, Wa, Wb, c, s, gp, ga, Fp, Fa, Fb, ia, ib, f, tau = _carve(extra[3], n)
    H = extra[4]
    flags = extra[5]
    _chain_terms(t, phi, dphi, chain, loads, held, t_side, A, Ma, Mb, c, s, gp, ga, f, Fp)
    for h in range(n):
        if h == 0:
            d = phi[0] + al[0]
            dd = dphi[0] + dal[0]
        else:
            d = phi[h] + al[h] - phi[h - 1] - be[h - 1]
            dd = dphi[h] + dal[h] - dphi[h - 1] - dbe[h - 1]
        tau[h] = kappa[h] * d + nu[h] * dd
    tau[n] = 0.0
    for k in range(n):
        # 2 [g^{phi alpha}] Lambda alpha_dot + 2 [g^{phi beta}] Lambda beta_dot
        cor = 0.0
        for j in range(k + 1, n):
            skj = s[k] * c[j] - c[k] * s[j]
            cor += C[j] * l[k] * skj * dphi[j] * (dal[j] - dbe[j])
        Fp[k] -= gp[k] + 2.0 * cor + tau[k] - tau[k + 1]
        Fa[k] = -ga[k] - tau[k] - Kt[k] * (al[k] + 0.5 * be[k]) + H[1, k]
        Fb[k] = ga[k] + tau[k + 1] - Kt[k] * (0.5 * al[k] + be[k]) + H[2, k]
    hinge_forces(phi, dphi, H, flags, Fp)
    out[:3 * n] = y[3 * n:]
    # bending block per rod: [[a, b], [b, a]], a = m l^3/105, b = -m l^3/140
    for j in range(n):
        ml3 = m[j] * l[j] ** 3
        a = ml3 / 105.0
        b = -ml3 / 140.0
        det = a * a - b * b
        ia[j] = a / det
        ib[j] = -b / det
    for k in range(n):
        for j in range(n):
            Wa[k, j] = Ma[k, j] * ia[j] + Mb[k, j] * ib[j]
            Wb[k, j] = Ma[k, j] * ib[j] + Mb[k, j] * ia[j]
    for k in range(n):
        for i in range(n):
            acc = 0.0
            for j in range(max(k, i), n):
                acc += Wa[k, j] * Ma[i, j] + Wb[k, j] * Mb[i, j]
            A[k, i] -= acc
    if flags[1]:
        _full_lagrange(A, Ma, Mb, Wa, Wb, ia, ib, Fp, Fa, Fb, flags[3], extra[9], extra[10],
                       extra[11], extra[12], extra[13], out[3 * n:])
        return
    x = gp  # g_phi is folded into Fp above; reuse its storage for the solve
    _schur_rhs(Wa, Wb, Fp, Fa, Fb, x)
    if not solve_inplace(A, x):
        _fill_nan(out)
        return
    out[3 * n:4 * n] = x
    _bending_accelerations(Ma, Mb, ia, ib, Fa, Fb, x, out[4 * n:5 * n], out[5 * n:])


@njit(inline="always")
def _schur_solve(LU, piv, Ma, Mb, Wa, Wb, ia, ib, gp, ga, gb, out):
    """Full model: M z = (gp, ga, gb) through the factored Schur complement LU of the
    bending block; z (3n,) into out (its phi part is solved in place there)."""
    n = gp.shape[0]
    x = out[:n]
    _schur_rhs(Wa, Wb, gp, ga, gb, x)
    lu_solve(LU, piv, x)
    _bending_accelerations(Ma, Mb, ia, ib, ga, gb, x, out[n:2 * n], out[2 * n:])


@njit(inline="always")
def _schur_rhs(Wa, Wb, gp, ga, gb, x):
    """Right-hand side of the Schur-complement system for phi_dd: gp - W (ga, gb) into x."""
    n = gp.shape[0]
    for k in range(n):
        acc = gp[k]
        for j in range(k, n):
            acc -= Wa[k, j] * ga[j] + Wb[k, j] * gb[j]
        x[k] = acc


@njit(inline="always")
def _bending_accelerations(Ma, Mb, ia, ib, ga, gb, x, out_a, out_b):
    """alpha_dd, beta_dd (n,) each from phi_dd = x: the 2 x 2 bending block per rod."""
    n = x.shape[0]
    for j in range(n):
        ra = ga[j]
        rb = gb[j]
        for k in range(j + 1):
            ra -= Ma[k, j] * x[k]
            rb -= Mb[k, j] * x[k]
        out_a[j] = ia[j] * ra + ib[j] * rb
        out_b[j] = ib[j] * ra + ia[j] * rb


@njit(inline="always")
def _full_lagrange(A, Ma, Mb, Wa, Wb, ia, ib, Fp, Fa, Fb, nc, rows, cols, vals, piv, ws, acc):
    """Full model on the constraint set C x'' = 0 (M symmetric, so equal to the projected
    equations): x'' = M^{-1} (f + C^T lambda) with (C M^{-1} C^T) lambda = -C M^{-1} f, every
    solve through the Schur complement A (Schur-reduced on entry) factored once: 1 + rows(C)
    solves of O(n^2) each instead of a dense 3n x 3n system."""
    n = Fp.shape[0]
    d = 3 * n
    Zt = ws[0:nc * d].reshape((nc, d))
    o = nc * d
    g = ws[o:o + d]
    S = ws[o + d:o + d + nc * nc].reshape((nc, nc))
    lam = ws[o + d + nc * nc:o + d + nc * nc + nc]
    if not lu_inplace(A, piv):
        for i in range(d):
            acc[i] = np.nan
        return
    _schur_solve(A, piv, Ma, Mb, Wa, Wb, ia, ib, Fp, Fa, Fb, acc)
    for i in range(nc):
        g[:] = 0.0
        for e in range(rows.shape[0]):
            if rows[e] == i:
                g[cols[e]] = vals[e]
        _schur_solve(A, piv, Ma, Mb, Wa, Wb, ia, ib, g[:n], g[n:2 * n], g[2 * n:], Zt[i])
    S[:, :] = 0.0
    lam[:] = 0.0
    for e in range(rows.shape[0]):
        i = rows[e]
        lam[i] -= vals[e] * acc[cols[e]]
        for j in range(nc):
            S[i, j] += vals[e] * Zt[j, cols[e]]
    if not solve_inplace(S, lam):
        for i in range(d):
            acc[i] = np.nan
        return
    for j in range(nc):
        for i in range(d):
            acc[i] += Zt[j, i] * lam[j]


# ---------------------------------------------------------------- the oracle's entry point
def dense_rhs(model_name: str, scene, t, y, held=None, locked=None, side=None):
    """dy/dt of the dense O(n^2)/O(n^3) formulation (the engine before the O(n) kernels,
    kept as the test oracle): model 'rigid', 'reduced' or 'full' of ``scene`` at (t, y) with
    held nodal forces (n, 2) [N] (or (n, 3) with hinge motor moments, which the dense
    formulation takes as rest-angle-like generalized forces), ``locked`` (n,) bool hinges and
    stop ``side`` (n,) int contacts."""
    import numpy as np

    from rod_sim.core.matrices import ChainParams
    from rod_sim.core.models import load_table

    p = ChainParams.from_scene(scene)
    n = p.n
    dof_per_rod = 3 if model_name == "full" else 1
    locked = np.zeros(n, bool) if locked is None else np.asarray(locked, bool)
    side = np.zeros(n, np.int8) if side is None else np.asarray(side, np.int8)
    side = np.where(locked, 0, side)
    h3 = np.zeros((n, 3))
    if held is not None:
        h = np.asarray(held, float)
        if h.size == 3 * n:
            h3[:] = h.reshape(n, 3)
        else:
            h3[:, :2] = h.reshape(n, 2)
    _, chain, P, B_inv = _dense_setup(scene)
    if model_name == "reduced":
        red = (np.ascontiguousarray(P[:, :n]), np.ascontiguousarray(P[:, n:]), B_inv)
    else:
        red = (np.zeros((n, n)), np.zeros((n, n)), np.zeros((2 * n, 2 * n)))
    kr = p.kappa * np.asarray(scene.hinge_rest_angle, float) + h3[:, 2]
    kr_next = np.append(kr[1:], 0.0)
    rest = (kr - kr_next, kr, -kr_next)
    C = constraint_matrix(scene, dof_per_rod, locked)
    T = None
    if C.shape[0]:
        order = (list(range(n, 3 * n)) if dof_per_rod == 3 else []) + list(range(n - 1, -1, -1))
        T = constraint_basis(C, order)
    d = dof_per_rod * n
    r = T.shape[1] if T is not None else 0
    rows, cols = np.nonzero(T) if T is not None else (np.zeros(0, int), np.zeros(0, int))
    vals = T[rows, cols] if T is not None else np.zeros(0)
    flags = np.array([int(np.any(side != 0)), int(T is not None), r, C.shape[0]], np.int64)
    c_rows, c_cols = np.nonzero(C)
    H = np.ascontiguousarray(np.vstack([*rest, scene.stop_lower, scene.stop_upper,
                                        scene.stop_stiffness, scene.stop_damping,
                                        side.astype(float)]))
    extra = red + (np.zeros(workspace_size(n)), H, flags, rows.astype(np.int64),
                   cols.astype(np.int64), np.ascontiguousarray(vals, float),
                   c_rows.astype(np.int64), c_cols.astype(np.int64),
                   np.ascontiguousarray(C[c_rows, c_cols], float), np.zeros(n, np.int64),
                   np.zeros(3 * d * d + 2 * d if T is not None else 1))
    kernel = {"rigid": rigid_rhs, "reduced": reduced_rhs, "full": full_rhs}[model_name]
    out = np.empty(2 * d)
    kernel(float(t), np.ascontiguousarray(y, float), chain, extra, load_table(scene),
           np.ascontiguousarray(h3[:, :2]), float(t), out)
    return out


def constraint_matrix(scene, dof_per_rod: int, locked: np.ndarray) -> np.ndarray:
    """C (rows, dof): C x' = 0 for the locked hinges (and rigid rods in the full model)."""
    n = scene.n
    dof = n * dof_per_rod
    full = dof_per_rod == 3
    rows = []
    for h in np.flatnonzero(locked):
        r = np.zeros(dof)
        r[h] = 1.0
        if full:
            r[n + h] = 1.0               # Delta_h = phi_h + alpha_h - phi_{h-1} - beta_{h-1}
        if h > 0:
            r[h - 1] = -1.0
            if full:
                r[2 * n + h - 1] = -1.0
        rows.append(r)
    if full:
        for k in np.flatnonzero(scene.rod_rigid):
            for off in (n, 2 * n):
                r = np.zeros(dof)
                r[off + k] = 1.0
                rows.append(r)
    return np.array(rows).reshape(len(rows), dof)


def constraint_basis(C: np.ndarray, pivot_order) -> np.ndarray:
    """T (dof, r), a basis of null(C) from its reduced row echelon form: pivots are tried in
    ``pivot_order`` (coordinates to eliminate first), every free coordinate gets a column
    with 1 at itself and minus its pivot-row entries. Sparse for the hinge constraints."""
    R = np.array(C, dtype=float)
    rows, dof = R.shape
    pivots: list[int] = []
    r = 0
    for col in pivot_order:
        if r == rows:
            break
        i = r + int(np.argmax(np.abs(R[r:, col])))
        if abs(R[i, col]) < 1e-12:
            continue
        R[[r, i]] = R[[i, r]]
        R[r] /= R[r, col]
        for k in range(rows):
            if k != r and R[k, col] != 0.0:
                R[k] -= R[k, col] * R[r]
        pivots.append(col)
        r += 1
    free = [j for j in range(dof) if j not in pivots]
    T = np.zeros((dof, len(free)))
    for c, j in enumerate(free):
        T[j, c] = 1.0
        for k, p in enumerate(pivots):
            T[p, c] = -R[k, j]
    T[np.abs(T) < 1e-15] = 0.0
    return T




def dense_mass_matrix(model, y):
    """The model's inertia matrix M (dof, dof) at y, column by column from its O(n) product
    ``model.mass_times`` (rigid: m^{phi phi}; full: the 3n x 3n matrix of (9)-(10))."""
    import numpy as np

    d = model.dof
    return np.column_stack([model.mass_times(y, np.eye(d)[i]) for i in range(d)])


def dense_reduced_mass(scene, phi):
    """M_r (n, n) of eq. (15) at phi with the scene's rigid rods (their gamma rows removed),
    from the dense blocks."""
    import numpy as np

    p, chain, P, _ = _dense_setup(scene)
    n = p.n
    A, Ma, Mb = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    mass_blocks(np.ascontiguousarray(phi, dtype=float), chain, A, Ma, Mb)
    return A - P[:, :n] @ Ma.T - P[:, n:] @ Mb.T


def _dense_setup(scene):
    """(ChainParams, the old kernels' chain tuple, P = K^T B^-1 (n, 2n), B^-1 (2n, 2n)) with
    the scene's rigid rods' gamma rows removed."""
    import numpy as np

    from rod_sim.core.matrices import ChainParams, reduction_matrices

    p = ChainParams.from_scene(scene)
    n = p.n
    K_gp, B = reduction_matrices(p)
    rigid = np.asarray(scene.rod_rigid, dtype=bool)
    keep = np.flatnonzero(np.concatenate([~rigid, ~rigid]))
    B_inv = np.zeros((2 * n, 2 * n))
    B_inv[np.ix_(keep, keep)] = np.linalg.inv(B[np.ix_(keep, keep)])
    chain = (p.l, p.m, p.mu, p.bending_stiffness_diag(), p.kappa, p.nu, p.tail_mass(),
             p.m * p.l ** 2 / 12.0)
    return p, chain, K_gp.T @ B_inv, B_inv
