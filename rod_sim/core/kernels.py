"""Compiled right-hand sides of the three models (the hot path).

All kernels share one calling convention so that the compiled integrators can take any of
them: ``rhs(t, y, chain, extra, loads, held, t_side, out)`` writes dy/dt into ``out``.

- ``chain`` = (l, m, mu, Kt, kappa, nu, Mt, C): arrays (n,) of rod length [m], mass per
  length [kg/m], node mass [kg], 4 EI / l [N m/rad], hinge stiffness [N m/rad], hinge damping
  [N m s/rad], tail mass M_k [kg] and m l^2 / 12 [kg m].
- ``extra``: model constants (reduced: P = [kappa^{gamma phi}]^T [b^{gamma gamma}]^{-1} split
  into its alpha and beta halves (n, n) each; other models: the same shapes, unused).
- ``loads`` = (node, axis, shape, amplitude, start, duration) arrays describing scripted loads;
  ``held`` (n, 2) the held (commanded) nodal forces [N]; ``t_side`` a time strictly inside the
  current segment between load breakpoints, which decides which side of a jump applies.

The mass matrix and velocity terms are assembled entry by entry in O(n^2) without Python
loops; the linear solve is a small in-place Gaussian elimination (O(n^3)).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit

SHAPE_PULSE, SHAPE_CONSTANT, SHAPE_STEP = 0, 1, 2


@njit
def load_forces(t, loads, held, t_side, out):
    """Nodal forces (n, 2) [N] at time t: held forces plus scripted loads."""
    node, axis, shape, amp, start, dur = loads
    out[:, :] = held
    for i in range(node.shape[0]):
        if t_side < start[i]:
            continue
        tau = t - start[i]
        sh = shape[i]
        if sh == SHAPE_CONSTANT:
            v = amp[i]
        elif sh == SHAPE_STEP:
            v = amp[i] if t_side < start[i] + dur[i] else 0.0
        else:
            if t_side > start[i] + dur[i]:
                v = 0.0
            else:
                v = amp[i] * (0.5 - 0.5 * math.cos(2.0 * math.pi * tau / dur[i]))
        out[node[i], axis[i]] += v


@njit
def generalized_forces(l, c, s, forces, out):
    """Q_k = l_k (c_k sum_{j>=k} Y_j - s_k sum_{j>=k} X_j) [N m] into out (n,)."""
    n = l.shape[0]
    sx = 0.0
    sy = 0.0
    for k in range(n - 1, -1, -1):
        sx += forces[k, 0]
        sy += forces[k, 1]
        out[k] = l[k] * (c[k] * sy - s[k] * sx)


@njit
def mass_blocks(phi, chain, A, Ma, Mb):
    """Inertia blocks m^{phi phi} (A), m^{phi alpha} (Ma), m^{phi beta} (Mb), each (n, n)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    c = np.cos(phi)
    s = np.sin(phi)
    for k in range(n):
        for j in range(n):
            ckj = c[k] * c[j] + s[k] * s[j]
            if j < k:
                A[k, j] = l[k] * l[j] * ckj * Mt[k]
                Ma[k, j] = 0.0
                Mb[k, j] = 0.0
            elif j > k:
                A[k, j] = l[k] * l[j] * ckj * Mt[j]
                Ma[k, j] = C[j] * l[k] * ckj
                Mb[k, j] = -Ma[k, j]
        ml3 = m[k] * l[k] ** 3
        A[k, k] = l[k] ** 2 * (Mt[k] - m[k] * l[k] / 2.0) + ml3 / 3.0
        Ma[k, k] = ml3 / 30.0
        Mb[k, k] = -ml3 / 20.0


@njit
def rigid_velocity_terms(phi, dphi, chain, g_phi, g_alpha):
    """g^{phi phi} Lambda phi_dot into g_phi (n,), g^{alpha phi} Lambda phi_dot into g_alpha
    (n,); g^{beta phi} Lambda phi_dot = -g_alpha."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    c = np.cos(phi)
    s = np.sin(phi)
    for k in range(n):
        gp = 0.0
        ga = 0.0
        for j in range(n):
            skj = s[k] * c[j] - c[k] * s[j]
            w = dphi[j] * dphi[j]
            if j < k:
                gp += l[k] * l[j] * skj * Mt[k] * w
                ga += C[k] * l[j] * skj * w
            elif j > k:
                gp += l[k] * l[j] * skj * Mt[j] * w
        g_phi[k] = gp
        g_alpha[k] = ga


@njit
def rigid_hinge_moments(phi, dphi, kappa, nu, out):
    """Hinge moments with gamma = 0: kappa_h dphi_h + nu_h d(dphi_h)/dt [N m] into out (n,)."""
    n = phi.shape[0]
    for h in range(n):
        if h == 0:
            d = phi[0]
            dd = dphi[0]
        else:
            d = phi[h] - phi[h - 1]
            dd = dphi[h] - dphi[h - 1]
        out[h] = kappa[h] * d + nu[h] * dd


@njit
def solve_inplace(A, b):
    """Solve A x = b by Gaussian elimination with partial pivoting; x overwrites b.

    A (n, n) is destroyed. Returns False when A is singular (a zero pivot)."""
    n = b.shape[0]
    for col in range(n):
        piv = col
        best = abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > best:
                best = abs(A[r, col])
                piv = r
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
        for r in range(col + 1, n):
            f = A[r, col] * inv
            if f != 0.0:
                for c2 in range(col + 1, n):
                    A[r, c2] -= f * A[col, c2]
                b[r] -= f * b[col]
    for r in range(n - 1, -1, -1):
        acc = b[r]
        for c2 in range(r + 1, n):
            acc -= A[r, c2] * b[c2]
        b[r] = acc / A[r, r]
    return True


@njit
def _fill_nan(out):
    for i in range(out.shape[0]):
        out[i] = np.nan


@njit
def rigid_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Rigid chain (EI -> infinity): y = [phi, phi_dot] (2n,)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    n = l.shape[0]
    phi = y[:n]
    dphi = y[n:]
    A = np.empty((n, n))
    Ma = np.empty((n, n))
    Mb = np.empty((n, n))
    mass_blocks(phi, chain, A, Ma, Mb)
    f = np.empty((n, 2))
    load_forces(t, loads, held, t_side, f)
    rhs = np.empty(n)
    generalized_forces(l, np.cos(phi), np.sin(phi), f, rhs)
    gp = np.empty(n)
    ga = np.empty(n)
    rigid_velocity_terms(phi, dphi, chain, gp, ga)
    tau = np.empty(n)
    rigid_hinge_moments(phi, dphi, kappa, nu, tau)
    for k in range(n):
        rhs[k] -= gp[k] + tau[k]
        if k + 1 < n:
            rhs[k] += tau[k + 1]
    out[:n] = dphi
    if not solve_inplace(A, rhs):
        _fill_nan(out)
        return
    out[n:] = rhs


@njit
def reduced_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Reduced model, eq. (15): y = [phi, phi_dot] (2n,); extra = (P_alpha, P_beta)."""
    l, m, mu, Kt, kappa, nu, Mt, C = chain
    Pa = extra[0]
    Pb = extra[1]
    n = l.shape[0]
    phi = y[:n]
    dphi = y[n:]
    A = np.empty((n, n))
    Ma = np.empty((n, n))
    Mb = np.empty((n, n))
    mass_blocks(phi, chain, A, Ma, Mb)
    f = np.empty((n, 2))
    load_forces(t, loads, held, t_side, f)
    rhs = np.empty(n)
    generalized_forces(l, np.cos(phi), np.sin(phi), f, rhs)
    gp = np.empty(n)
    ga = np.empty(n)
    rigid_velocity_terms(phi, dphi, chain, gp, ga)
    tau = np.empty(n)
    rigid_hinge_moments(phi, dphi, kappa, nu, tau)
    a_al = np.empty(n)
    a_be = np.empty(n)
    for k in range(n):
        nxt = tau[k + 1] if k + 1 < n else 0.0
        a_al[k] = ga[k] + tau[k]
        a_be[k] = -ga[k] - nxt
        rhs[k] -= gp[k] + tau[k] - nxt
    # M_r = A - P_alpha m^{alpha phi} - P_beta m^{beta phi}, m^{alpha phi} = Ma^T
    for k in range(n):
        acc = 0.0
        for j in range(n):
            acc += Pa[k, j] * a_al[j] + Pb[k, j] * a_be[j]
        rhs[k] += acc
        for i in range(n):
            acc = 0.0
            for j in range(i, n):
                acc += Pa[k, j] * Ma[i, j] + Pb[k, j] * Mb[i, j]
            A[k, i] -= acc
    out[:n] = dphi
    if not solve_inplace(A, rhs):
        _fill_nan(out)
        return
    out[n:] = rhs


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
    A = np.empty((n, n))
    Ma = np.empty((n, n))
    Mb = np.empty((n, n))
    mass_blocks(phi, chain, A, Ma, Mb)
    f = np.empty((n, 2))
    load_forces(t, loads, held, t_side, f)
    c = np.cos(phi)
    s = np.sin(phi)
    Fp = np.empty(n)
    generalized_forces(l, c, s, f, Fp)
    Fa = np.empty(n)
    Fb = np.empty(n)
    gp = np.empty(n)
    ga = np.empty(n)
    rigid_velocity_terms(phi, dphi, chain, gp, ga)
    tau = np.empty(n + 1)
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
        Fa[k] = -ga[k] - tau[k] - Kt[k] * (al[k] + 0.5 * be[k])
        Fb[k] = ga[k] + tau[k + 1] - Kt[k] * (0.5 * al[k] + be[k])
    # bending block per rod: [[a, b], [b, a]], a = m l^3/105, b = -m l^3/140
    ia = np.empty(n)
    ib = np.empty(n)
    for j in range(n):
        ml3 = m[j] * l[j] ** 3
        a = ml3 / 105.0
        b = -ml3 / 140.0
        det = a * a - b * b
        ia[j] = a / det
        ib[j] = -b / det
    Wa = np.empty((n, n))
    Wb = np.empty((n, n))
    for k in range(n):
        for j in range(n):
            Wa[k, j] = Ma[k, j] * ia[j] + Mb[k, j] * ib[j]
            Wb[k, j] = Ma[k, j] * ib[j] + Mb[k, j] * ia[j]
    x = np.empty(n)
    for k in range(n):
        acc = Fp[k]
        for j in range(k, n):
            acc -= Wa[k, j] * Fa[j] + Wb[k, j] * Fb[j]
        x[k] = acc
        for i in range(n):
            acc = 0.0
            for j in range(max(k, i), n):
                acc += Wa[k, j] * Ma[i, j] + Wb[k, j] * Mb[i, j]
            A[k, i] -= acc
    out[:3 * n] = y[3 * n:]
    if not solve_inplace(A, x):
        _fill_nan(out)
        return
    for j in range(n):
        ra = Fa[j]
        rb = Fb[j]
        for k in range(j + 1):
            ra -= Ma[k, j] * x[k]
            rb -= Mb[k, j] * x[k]
        out[3 * n + j] = x[j]
        out[4 * n + j] = ia[j] * ra + ib[j] * rb
        out[5 * n + j] = ib[j] * ra + ia[j] * rb
