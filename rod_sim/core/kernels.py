"""Compiled right-hand sides of the three models in O(n) time and memory (the hot path).

All kernels share one calling convention so that the compiled integrators can take any of
them: ``rhs(t, y, chain, extra, loads, held, t_side, out)`` writes dy/dt into ``out``.

- ``chain`` (:class:`Chain`): the scene's constant per-rod arrays (n,).
- ``extra`` (:class:`Extra`): the hinge features in the current mode and the kernel's
  scratch (a call allocates nothing, so the kernels are not re-entrant: one model instance per
  thread). A plain chain (no rest angle, stop or lock) runs exactly the paper's equations.
- ``loads`` = (node, axis, shape, amplitude, start, duration) arrays describing scripted loads;
  ``held`` (n, 3): the held (commanded) nodal forces X, Y [N] at nodes 1..n and motor moments
  T [N m] at hinges 0..n-1 (T_h acts +T on rod h and -T on rod h-1, like a hinge spring whose
  moment is -T); ``t_side`` a time strictly inside the current segment between load
  breakpoints, which decides which side of a jump applies.

**How the equations are solved in O(n).** The paper's mass matrix is dense but structured:
with e_k = (cos phi_k, sin phi_k), its entries for rods k < j are products of a vector of
rod k and a vector of rod j (m^{phi phi}_kj = (l_k e_k).(l_j M_j e_j), m^{phi alpha}_kj =
(l_k e_k).(C_j e_j), ...): a semiseparable matrix of rank 2 plus 3 x 3 diagonal blocks. So
every coupling between the rods before and after a node passes through two 2-vectors, the
node acceleration z = sum_{j<k} l_j e_j phi''_j and the "reaction" R = sum_{j>k} (...) e_j;
the reduced model adds the hinge-spring band (beta_{k-1} <-> alpha_k) and a locked hinge its
constraint (a rotation one way, a multiplier the other). :func:`chain_solve` eliminates the
rods from the tip to the root (each rod's influence on its parent is an affine map of the
4-vector interface u = (z, rotation-like, rotation-like), as in the articulated-body
algorithm), then substitutes forward: Gaussian elimination of the exact dense system in a
tree order, a 3 x 3 solve per rod. The velocity terms g Lambda phi' are prefix and suffix
sums of the same products. The dense formulation is kept as the test oracle
(test/dense_kernels.py).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .jit import njit

SHAPE_PULSE, SHAPE_CONSTANT, SHAPE_STEP = 0, 1, 2

# model kinds of chain_solve
KIND_REDUCED, KIND_FULL = 0, 1

# columns of Extra.work (n, N_WORK)
W_C, W_S, W_GP, W_GA, W_FP, W_FA, W_FB, W_X, W_A, W_B, W_COR = range(11)
W_REC = 11                # 15 columns: v0 (3) and V (3 x 4) of each rod's elimination
N_WORK = W_REC + 15
N_SMALL = 64              # Extra.small: the 4-vector P, 4 x 4 K and 3 x 5 systems


class Chain(NamedTuple):
    """Constant per-rod arrays, each (n,), SI units: rod length l [m], mass per length m
    [kg/m], node mass mu [kg] (nodes 1..n), Kt = 4 EI / l [N m/rad], hinge stiffness kappa
    [N m/rad] and damping nu [N m s/rad] of hinges 0..n-1, tail mass Mt_k [kg] (the paper's
    M_k), C = m l^2 / 12 [kg m], A_kk the diagonal of m^{phi phi} [kg m^2], c30 = m l^3 / 30,
    c20 = m l^3 / 20, c105 = m l^3 / 105, c140 = m l^3 / 140 [kg m^2] (bending inertia
    coefficients), kappa_tip = kappa of the hinge at the rod's tip (0 for the last rod)."""

    l: np.ndarray
    m: np.ndarray
    mu: np.ndarray
    Kt: np.ndarray
    kappa: np.ndarray
    nu: np.ndarray
    Mt: np.ndarray
    C: np.ndarray
    Akk: np.ndarray
    c30: np.ndarray
    c20: np.ndarray
    c105: np.ndarray
    c140: np.ndarray
    kappa_tip: np.ndarray


class Extra(NamedTuple):
    """Hinge features in one mode plus scratch; arrays (n,) unless stated.

    rest_phi, rest_alpha, rest_beta [N m]: rest-angle generalized forces kappa theta_rest
    dDelta/dq on phi, alpha, beta; stop_lower, stop_upper [rad] (+-inf: none), stop_k [N m/rad],
    stop_c [N m s/rad]; contact (+1 in contact with the upper stop, -1 the lower, 0 free: the
    contact law applies by mode, switched at located crossings); locked int64 (1: hinge held
    rigid, C x'' = 0, or with comp != 0 compliant: C x'' = -comp lambda, see
    :func:`chain_solve`); comp [rad/(N m)] (n,) compliance of locked hinges (0 in the
    dynamics); gw (n,): weight of a compliant hinge's multiplier on the slope rows of the
    reduced model (1: the hinge spring's own rows, alpha_h and beta_{h-1}; 0: the phi rows
    only, as a lock or a stop); pinned int64 (1: the rod's end slopes are zero: rigid rods, every rod of
    the rigid model); flags int64 (2,) = [any hinge in contact, any hinge locked]; work
    (n, N_WORK) and small (N_SMALL,) scratch; forces (n, 2) and tau (n + 1,) scratch; kind:
    KIND_REDUCED (rigid and reduced models) or KIND_FULL."""

    rest_phi: np.ndarray
    rest_alpha: np.ndarray
    rest_beta: np.ndarray
    stop_lower: np.ndarray
    stop_upper: np.ndarray
    stop_k: np.ndarray
    stop_c: np.ndarray
    contact: np.ndarray
    locked: np.ndarray
    comp: np.ndarray
    gw: np.ndarray
    pinned: np.ndarray
    flags: np.ndarray
    work: np.ndarray
    small: np.ndarray
    forces: np.ndarray
    tau: np.ndarray
    kind: int


def make_chain(l, m, mu, EI, kappa, nu) -> Chain:
    """:class:`Chain` from the per-rod constants (n,) each [SI]."""
    l, m, mu, EI, kappa, nu = (np.ascontiguousarray(a, dtype=float)
                               for a in (l, m, mu, EI, kappa, nu))
    ml = m * l
    Mt = np.cumsum((mu + ml)[::-1])[::-1] - ml / 2.0
    ml3 = m * l**3
    return Chain(l, m, mu, 4.0 * EI / l, kappa, nu, Mt, m * l**2 / 12.0,
                 l**2 * (Mt - ml / 2.0) + ml3 / 3.0, ml3 / 30.0, ml3 / 20.0, ml3 / 105.0,
                 ml3 / 140.0, np.append(kappa[1:], 0.0))


def make_extra(rest, stops, contact, locked, pinned, comp=None, kind=KIND_REDUCED,
               dtype=float) -> Extra:
    """:class:`Extra` for n rods: ``rest`` (3, n) [N m], ``stops`` (4, n) = lower, upper [rad],
    stiffness, damping; ``contact`` (n,) int; ``locked``, ``pinned`` (n,) bool; ``comp``
    (n,) compliance of the locked hinges (default 0: rigid); ``dtype`` of the solve's
    scratch and compliances (complex for Radau's complex Newton system)."""
    n = len(locked)
    f = lambda a: np.ascontiguousarray(a, dtype=float)  # noqa: E731
    i = lambda a: np.ascontiguousarray(a, dtype=np.int64)  # noqa: E731
    contact = f(contact)
    flags = np.array([int(np.any(contact != 0)), int(np.any(locked))], dtype=np.int64)
    return Extra(f(rest[0]), f(rest[1]), f(rest[2]), f(stops[0]), f(stops[1]), f(stops[2]),
                 f(stops[3]), contact, i(locked),
                 np.array(np.zeros(n) if comp is None else comp, dtype=dtype),
                 np.zeros(n, dtype=dtype), i(pinned), flags, np.zeros((n, N_WORK), dtype=dtype),
                 np.zeros(N_SMALL, dtype=dtype), np.zeros((n, 2)), np.zeros(n + 1), int(kind))


class Problem(NamedTuple):
    """What a right-hand side needs besides (t, y): ``chain`` (:class:`Chain`), ``extra``
    (:class:`Extra` of the current mode), ``loads`` (the scripted loads' arrays,
    ``models.load_table``) and ``held`` (n, 3): nodal forces X, Y [N] and hinge moments T
    [N m] held by the caller."""

    chain: Chain
    extra: Extra
    loads: tuple
    held: np.ndarray


class Span(NamedTuple):
    """Where a compiled driver call integrates: from state ``y0`` (size,) at ``t0`` [s]
    through the sorted output times ``t_out`` (N,) [s], ending steps exactly at the sorted
    load breakpoints ``breaks`` [s]."""

    y0: np.ndarray
    t0: float
    t_out: np.ndarray
    breaks: np.ndarray


class Control(NamedTuple):
    """Step control of a compiled driver call: tolerances ``rtol``, ``atol``; ``h_init`` [s]
    the first step to try (<= 0: choose one); ``max_step`` [s] the largest step (the step of
    a fixed-step method); ``max_steps`` accepted steps allowed; ``budget`` right-hand side
    evaluations before the call returns (the call's work bound)."""

    rtol: float
    atol: float
    h_init: float
    max_step: float
    max_steps: int
    budget: int


class EventTable(NamedTuple):
    """The event functions g_e = theta_{hinge_e} - angle_e of one mode (m of them):
    ``hinge`` (m,) int64, ``angle`` (m,) [rad], ``kind`` (m,) int64 (``hinges.EV_LATCH``:
    terminal; ``EV_UPPER``, ``EV_LOWER``: stop crossings)."""

    hinge: np.ndarray
    angle: np.ndarray
    kind: np.ndarray


class Events(NamedTuple):
    """An :class:`EventTable` and the buffer a compiled driver records located crossings in:
    ``t`` (cap,) [s], ``code`` (cap,) int64 = 2 e + (1 if g_e rises), ``y`` (cap, size) the
    states there, ``count`` (1,) int64 the crossings recorded."""

    hinge: np.ndarray
    angle: np.ndarray
    kind: np.ndarray
    t: np.ndarray
    code: np.ndarray
    y: np.ndarray
    count: np.ndarray


class Output(NamedTuple):
    """Where a compiled driver call writes: states ``Y`` (N, size) at the output times, work
    counters ``stats`` (int64: rhs evaluations, accepted, rejected steps[, Jacobians, LU
    factorisations, Newton iterations]) accumulated, and the event table and buffers
    ``events`` (:class:`Events`)."""

    Y: np.ndarray
    stats: np.ndarray
    events: tuple


@njit(inline="always")
def load_forces(t, loads, held, t_side, out):
    """Nodal forces (n, 2) [N] at time t: held forces plus scripted loads."""
    node, axis, shape, amp, start, dur = loads
    out[:, :] = held[:, :2]
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


@njit(inline="always")
def _generalized_forces(l, W, forces):
    """Q_k = l_k (c_k sum_{j>=k} Y_j - s_k sum_{j>=k} X_j) [N m] into W[:, W_FP]."""
    n = l.shape[0]
    sx = 0.0
    sy = 0.0
    for k in range(n - 1, -1, -1):
        sx += forces[k, 0]
        sy += forces[k, 1]
        W[k, W_FP] = l[k] * (W[k, W_C] * sy - W[k, W_S] * sx)


@njit(inline="always")
def _velocity_terms(ch, dphi, W):
    """g^{phi phi} Lambda phi' into W[:, W_GP] and g^{alpha phi} Lambda phi' into W[:, W_GA]
    (n,) [N m] (g^{beta phi} Lambda phi' = -g_alpha) from cos/sin in W[:, W_C], W[:, W_S]:
    sin(phi_k - phi_j) = s_k c_j - c_k s_j turns the pair sums into prefix/suffix sums."""
    n = dphi.shape[0]
    sc = 0.0
    ss = 0.0
    for k in range(n):
        c = W[k, W_C]
        s = W[k, W_S]
        low = s * sc - c * ss                   # sum_{j<k} l_j sin(phi_k - phi_j) phi_j'^2
        W[k, W_GP] = ch.l[k] * ch.Mt[k] * low
        W[k, W_GA] = ch.C[k] * low
        w = ch.l[k] * dphi[k] * dphi[k]
        sc += w * c
        ss += w * s
    sc = 0.0
    ss = 0.0
    for k in range(n - 1, -1, -1):
        c = W[k, W_C]
        s = W[k, W_S]
        W[k, W_GP] += ch.l[k] * (s * sc - c * ss)
        w = ch.l[k] * ch.Mt[k] * dphi[k] * dphi[k]
        sc += w * c
        ss += w * s


@njit(inline="always")
def _start(t, phi, dphi, ch, ex, loads, held, t_side):
    """What every kernel computes first: cos/sin, velocity terms, nodal forces, Q (into
    W[:, W_FP]); returns the work array W (n, N_WORK)."""
    W = ex.work
    n = phi.shape[0]
    for k in range(n):
        W[k, W_C] = math.cos(phi[k])
        W[k, W_S] = math.sin(phi[k])
    _velocity_terms(ch, dphi, W)
    load_forces(t, loads, held, t_side, ex.forces)
    _generalized_forces(ch.l, W, ex.forces)
    return W


@njit(inline="always")
def hinge_angle(phi, dphi, h):
    """Rigid hinge angle theta_h [rad] and its rate [rad/s] (phi_1; phi_{h+1} - phi_h)."""
    if h == 0:
        return phi[0], dphi[0]
    return phi[h] - phi[h - 1], dphi[h] - dphi[h - 1]


@njit(inline="always")
def _stop_moments(phi, dphi, ex, W):
    """Add the stop-contact moments (on the rigid hinge angles) to the phi rows W[:, W_FP]."""
    if ex.flags[0] == 0:
        return
    n = phi.shape[0]
    for h in range(n):
        th, dth = hinge_angle(phi, dphi, h)
        m = 0.0
        side = ex.contact[h]
        if side > 0.0:
            m = -max(0.0, ex.stop_k[h] * (th - ex.stop_upper[h]) + ex.stop_c[h] * dth)
        elif side < 0.0:
            m = max(0.0, ex.stop_k[h] * (ex.stop_lower[h] - th) - ex.stop_c[h] * dth)
        W[h, W_FP] += m
        if h > 0:
            W[h - 1, W_FP] -= m


@njit(inline="always")
def _solve3(E, G, ncol):
    """Solve E X = G in place for E (3, 3) and the first ``ncol`` columns of G (3, 5) by
    Gaussian elimination with partial pivoting (X overwrites G). False if E is singular."""
    for col in range(3):
        piv = col
        best = abs(E[col, col])
        for r in range(col + 1, 3):
            if abs(E[r, col]) > best:
                best = abs(E[r, col])
                piv = r
        if best == 0.0:
            return False
        if piv != col:
            for j in range(3):
                tmp = E[col, j]
                E[col, j] = E[piv, j]
                E[piv, j] = tmp
            for j in range(ncol):
                tmp = G[col, j]
                G[col, j] = G[piv, j]
                G[piv, j] = tmp
        inv = 1.0 / E[col, col]
        for r in range(col + 1, 3):
            f = E[r, col] * inv
            if f != 0.0:
                for j in range(col + 1, 3):
                    E[r, j] -= f * E[col, j]
                for j in range(ncol):
                    G[r, j] -= f * G[col, j]
    for r in range(2, -1, -1):
        inv = 1.0 / E[r, r]
        for j in range(ncol):
            acc = G[r, j]
            for c2 in range(r + 1, 3):
                acc -= E[r, c2] * G[c2, j]
            G[r, j] = acc * inv
    return True


@njit(inline="always")
def chain_solve(kind, ch, ex, W):
    """Solve the model's linear system for the accelerations in O(n).

    Inputs in W (n, N_WORK): cos/sin (W_C, W_S) and the right-hand sides of the phi, alpha and
    beta rows (W_FP, W_FA, W_FB). ``kind`` KIND_REDUCED: unknowns phi'' and the quasi-static
    end slopes alpha, beta of eq. (14) (the rows are [m^{pp} phi'' + kappa^{p gamma} gamma =
    F_p; m^{gamma p} phi'' + [b^{gamma gamma}] gamma = F_gamma], i.e. eq. (15) before the
    elimination of gamma); KIND_FULL: unknowns phi'', alpha'', beta'' of eqs. (9)-(10). Pinned
    rods have alpha = beta = 0 (their gamma rows dropped); locked hinges add C x'' = 0 with a
    multiplier (the projected equations T^T M T q = T^T f of a constraint basis T); with a
    compliance comp_h the hinge's row becomes d_h^T x'' = -comp_h lambda_h, which solves
    (M + s sum_h kappa'_h d_h d_h^T) x = f for comp_h = -1 / (s kappa'_h) (d_h: the hinge's
    relative rotation, dDelta_h/dq; used by the eigenvalue and Newton solves). Outputs
    phi'' (W_X), alpha or alpha'' (W_A), beta or beta'' (W_B). Returns False if singular."""
    n = W.shape[0]
    sm = ex.small
    P = sm[0:4]
    K = sm[4:20].reshape((4, 4))
    E = sm[20:29].reshape((3, 3))
    G = sm[29:44].reshape((3, 5))
    kx = sm[44:48]
    kb = sm[48:52]
    col = sm[52:55]
    xu = sm[55:60]      # [x0, X (4)] : phi'' of the rod as affine map of u
    nP = sm[60:64]
    full = kind == KIND_FULL
    P[:] = 0.0
    K[:, :] = 0.0
    for r in range(n - 1, -1, -1):
        L = ch.l[r]
        c = W[r, W_C]
        s = W[r, W_S]
        lc0 = L * c
        lc1 = L * s
        lM = L * ch.Mt[r]
        Cr = ch.C[r]
        # w_{r+1} = P + K u_{r+1}, u_{r+1} = (z + l e x, rho, x or -) : coefficients of x, beta
        for i in range(4):
            if full:
                kx[i] = lc0 * K[i, 0] + lc1 * K[i, 1] + K[i, 2]
            else:
                kx[i] = lc0 * K[i, 0] + lc1 * K[i, 1] + K[i, 3]
            kb[i] = K[i, 2]
        G[:, :] = 0.0
        if full:
            E[0, 0] = ch.Akk[r] + lc0 * kx[0] + lc1 * kx[1] - kx[2]
            E[0, 1] = ch.c30[r]
            E[0, 2] = -ch.c20[r] + lc0 * kb[0] + lc1 * kb[1] - kb[2]
            G[0, 0] = W[r, W_FP] - (lc0 * P[0] + lc1 * P[1] - P[2])
            G[0, 1] = -(lc0 * K[0, 0] + lc1 * K[1, 0] + lM * c - K[2, 0])
            G[0, 2] = -(lc0 * K[0, 1] + lc1 * K[1, 1] + lM * s - K[2, 1])
            E[1, 0] = ch.c30[r]
            E[1, 1] = ch.c105[r]
            E[1, 2] = -ch.c140[r]
            G[1, 0] = W[r, W_FA]
            G[1, 1] = -Cr * c
            G[1, 2] = -Cr * s
            E[2, 0] = -ch.c20[r] - kx[2]
            E[2, 1] = -ch.c140[r]
            E[2, 2] = ch.c105[r] - kb[2]
            G[2, 0] = W[r, W_FB] + P[2]
            G[2, 1] = Cr * c + K[2, 0]
            G[2, 2] = Cr * s + K[2, 1]
        else:
            ka = ch.kappa[r]
            kt = ch.kappa_tip[r]
            E[0, 0] = ch.Akk[r] + lc0 * kx[0] + lc1 * kx[1] - kt * kx[2] - kx[3]
            E[0, 1] = ka
            E[0, 2] = lc0 * kb[0] + lc1 * kb[1] + kt - kt * kb[2] - kb[3]
            G[0, 0] = W[r, W_FP] - (lc0 * P[0] + lc1 * P[1] - kt * P[2] - P[3])
            G[0, 1] = -(lc0 * K[0, 0] + lc1 * K[1, 0] + lM * c - kt * K[2, 0] - K[3, 0])
            G[0, 2] = -(lc0 * K[0, 1] + lc1 * K[1, 1] + lM * s - kt * K[2, 1] - K[3, 1])
            G[0, 3] = ka
            Ktr = ch.Kt[r]
            E[1, 0] = ch.c30[r]
            E[1, 1] = ka + Ktr
            E[1, 2] = 0.5 * Ktr
            G[1, 0] = W[r, W_FA]
            G[1, 1] = -Cr * c
            G[1, 2] = -Cr * s
            G[1, 3] = ka
            # beta row: -kappa_{r+1} alpha_{r+1} - gw_{r+1} lambda_{r+1}
            gt = ex.gw[r + 1] if r + 1 < n else 0.0
            E[2, 0] = -ch.c20[r] - kt * kx[2] - gt * kx[3]
            E[2, 1] = 0.5 * Ktr
            E[2, 2] = kt + Ktr - kt * kb[2] - gt * kb[3]
            G[2, 0] = W[r, W_FB] + kt * P[2] + gt * P[3]
            G[2, 1] = Cr * c + kt * K[2, 0] + gt * K[3, 0]
            G[2, 2] = Cr * s + kt * K[2, 1] + gt * K[3, 1]
        locked = ex.locked[r] != 0
        cr = ex.comp[r]
        if locked:
            # phi''_r is given by the rod before (reduced: x_{r-1} = u_3; full: rho - alpha''
            # with rho = u_2 = x_{r-1} + beta''_{r-1}), less comp * lambda for a compliant
            # hinge; slot 0 becomes the multiplier lambda
            for i in range(3):
                col[i] = E[i, 0]
            E[0, 0] = 1.0 - cr * col[0]
            E[1, 0] = (1.0 if full else ex.gw[r]) - cr * col[1]
            E[2, 0] = -cr * col[2]
            for i in range(3):
                if full:
                    E[i, 1] -= col[i]
                    G[i, 3] -= col[i]
                else:
                    G[i, 4] -= col[i]
        if ex.pinned[r] != 0:
            for i in (1, 2):
                for j in range(3):
                    E[i, j] = 0.0
                for j in range(5):
                    G[i, j] = 0.0
                E[i, i] = 1.0
        if not _solve3(E, G, 5):
            return False
        rec = W[r, W_REC:W_REC + 15]
        for i in range(3):
            for j in range(5):
                rec[5 * i + j] = G[i, j]
        # phi''_r as an affine map of u: xu = [x0, X_0..X_3]
        if not locked:
            for j in range(5):
                xu[j] = G[0, j]
        elif full:
            for j in range(5):
                xu[j] = -G[1, j] - cr * G[0, j]
            xu[3] += 1.0
        else:
            for j in range(5):
                xu[j] = -cr * G[0, j]
            xu[4] += 1.0
        # the interface to the rod before: w_r = (R_{r-1}, 2 more) = nP + nK u
        for i in range(2):
            e_i = c if i == 0 else s
            ax = kx[i] + lM * e_i
            if full:
                ab = kb[i] - Cr * e_i
                aa = Cr * e_i
            else:
                ab = kb[i]
                aa = 0.0
            nP[i] = P[i] + ax * xu[0] + ab * G[2, 0] + aa * G[1, 0]
            k0 = K[i, 0]
            k1 = K[i, 1]
            for j in range(4):
                K[i, j] = ax * xu[1 + j] + ab * G[2, 1 + j] + aa * G[1, 1 + j]
            K[i, 0] += k0
            K[i, 1] += k1
        for j in range(4):
            K[3, j] = 0.0
        if full:
            nP[2] = G[0, 0] if locked else 0.0
            for j in range(4):
                K[2, j] = G[0, 1 + j] if locked else 0.0
            nP[3] = 0.0
        else:
            nP[2] = G[1, 0]
            for j in range(4):
                K[2, j] = G[1, 1 + j]
            nP[3] = G[0, 0] if locked else 0.0
            if locked:
                for j in range(4):
                    K[3, j] = G[0, 1 + j]
        for i in range(4):
            P[i] = nP[i]
    # forward: u = (z, beta_{r-1} or rho_{r-1}, x_{r-1})
    u0 = 0.0
    u1 = 0.0
    u2 = 0.0
    u3 = 0.0
    for r in range(n):
        rec = W[r, W_REC:W_REC + 15]
        v0 = rec[0] + rec[1] * u0 + rec[2] * u1 + rec[3] * u2 + rec[4] * u3
        va = rec[5] + rec[6] * u0 + rec[7] * u1 + rec[8] * u2 + rec[9] * u3
        vb = rec[10] + rec[11] * u0 + rec[12] * u1 + rec[13] * u2 + rec[14] * u3
        if ex.locked[r] == 0:
            x = v0
        elif full:
            x = u2 - va - ex.comp[r] * v0
        else:
            x = u3 - ex.comp[r] * v0
        W[r, W_X] = x
        W[r, W_A] = va
        W[r, W_B] = vb
        L = ch.l[r]
        u0 += L * W[r, W_C] * x
        u1 += L * W[r, W_S] * x
        if full:
            u2 = x + vb
        else:
            u2 = vb
            u3 = x
    return True


@njit(inline="always")
def _hinge_moments(phi, dphi, ch, ex, held, W, tau):
    """tau_h = kappa_h Delta_h + nu_h Delta_h' - T_h (n + 1,) [N m] with the rigid hinge
    angles (gamma = 0; tau_n = 0), and the rest-angle forces added to W's right-hand sides."""
    n = phi.shape[0]
    for h in range(n):
        d, dd = hinge_angle(phi, dphi, h)
        tau[h] = ch.kappa[h] * d + ch.nu[h] * dd - held[h, 2]
        W[h, W_FA] = ex.rest_alpha[h]
        W[h, W_FB] = ex.rest_beta[h]
    tau[n] = 0.0


@njit(inline="always")
def _finish(n, W, dphi, out):
    """[phi', phi''] (2n,) into out from the solve's W_X column."""
    for k in range(n):
        out[k] = dphi[k]
        out[n + k] = W[k, W_X]


@njit(inline="always")
def _fill_nan(out):
    for i in range(out.shape[0]):
        out[i] = np.nan


@njit
def rigid_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Rigid chain (EI -> infinity): y = [phi, phi_dot] (2n,); every rod pinned."""
    n = chain.l.shape[0]
    phi = y[:n]
    dphi = y[n:]
    W = _start(t, phi, dphi, chain, extra, loads, held, t_side)
    tau = extra.tau
    _hinge_moments(phi, dphi, chain, extra, held, W, tau)
    for k in range(n):
        W[k, W_FP] += extra.rest_phi[k] - W[k, W_GP] - tau[k] + tau[k + 1]
    _stop_moments(phi, dphi, extra, W)
    if not chain_solve(KIND_REDUCED, chain, extra, W):
        _fill_nan(out)
        return
    _finish(n, W, dphi, out)


@njit
def reduced_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Reduced model, eq. (15) through (14): y = [phi, phi_dot] (2n,); the quasi-static end
    slopes alpha, beta are left in extra.work[:, W_A], extra.work[:, W_B]."""
    n = chain.l.shape[0]
    phi = y[:n]
    dphi = y[n:]
    W = _start(t, phi, dphi, chain, extra, loads, held, t_side)
    tau = extra.tau
    _hinge_moments(phi, dphi, chain, extra, held, W, tau)
    for k in range(n):
        ga = W[k, W_GA]
        W[k, W_FP] += extra.rest_phi[k] - W[k, W_GP] - tau[k] + tau[k + 1]
        W[k, W_FA] += -ga - tau[k]
        W[k, W_FB] += ga + tau[k + 1]
    _stop_moments(phi, dphi, extra, W)
    if not chain_solve(KIND_REDUCED, chain, extra, W):
        _fill_nan(out)
        return
    _finish(n, W, dphi, out)


@njit
def full_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Full model (9)-(10): y = [phi, alpha, beta, phi_dot, alpha_dot, beta_dot] (6n,)."""
    n = chain.l.shape[0]
    phi = y[:n]
    al = y[n:2 * n]
    be = y[2 * n:3 * n]
    dphi = y[3 * n:4 * n]
    dal = y[4 * n:5 * n]
    dbe = y[5 * n:6 * n]
    W = _start(t, phi, dphi, chain, extra, loads, held, t_side)
    tau = extra.tau
    for h in range(n):
        if h == 0:
            d = phi[0] + al[0]
            dd = dphi[0] + dal[0]
        else:
            d = phi[h] + al[h] - phi[h - 1] - be[h - 1]
            dd = dphi[h] + dal[h] - dphi[h - 1] - dbe[h - 1]
        tau[h] = chain.kappa[h] * d + chain.nu[h] * dd - held[h, 2]
    tau[n] = 0.0
    # 2 [g^{phi alpha}] Lambda alpha' + 2 [g^{phi beta}] Lambda beta': suffix sums over j > k
    sc = 0.0
    ss = 0.0
    for k in range(n - 1, -1, -1):
        c = W[k, W_C]
        s = W[k, W_S]
        cor = chain.l[k] * (s * sc - c * ss)
        w = chain.C[k] * dphi[k] * (dal[k] - dbe[k])
        sc += w * c
        ss += w * s
        ga = W[k, W_GA]
        Kt = chain.Kt[k]
        W[k, W_FP] += extra.rest_phi[k] - W[k, W_GP] - 2.0 * cor - tau[k] + tau[k + 1]
        W[k, W_FA] = -ga - tau[k] - Kt * (al[k] + 0.5 * be[k]) + extra.rest_alpha[k]
        W[k, W_FB] = ga + tau[k + 1] - Kt * (0.5 * al[k] + be[k]) + extra.rest_beta[k]
    _stop_moments(phi, dphi, extra, W)
    if not chain_solve(KIND_FULL, chain, extra, W):
        _fill_nan(out)
        return
    for k in range(3 * n):
        out[k] = y[3 * n + k]
    for k in range(n):
        out[3 * n + k] = W[k, W_X]
        out[4 * n + k] = W[k, W_A]
        out[5 * n + k] = W[k, W_B]


@njit(inline="always")
def inertia_columns(full, chain, W, V, VA, VB, FP, FA, FB):
    """Columns FP, FA, FB of W (n, ncol) = the paper's inertia blocks times the velocity
    columns V, VA, VB, in O(n): FP = m^{pp} V + m^{pa} VA + m^{pb} VB, FA = m^{ap} V + m^{aa}
    VA + m^{ab} VB, FB likewise, with cos, sin of the rod angles in columns W_C, W_S.
    ``full`` False: only FP = m^{pp} V (VA, VB, FA, FB unused). The output columns must
    differ from the input ones."""
    n = W.shape[0]
    zx = 0.0
    zy = 0.0
    for k in range(n):
        c = W[k, W_C]
        s = W[k, W_S]
        v = W[k, V]
        ez = c * zx + s * zy                    # e_k . sum_{j<k} l_j e_j v_j
        W[k, FP] = chain.Akk[k] * v + chain.l[k] * chain.Mt[k] * ez
        if full:
            va = W[k, VA]
            vb = W[k, VB]
            W[k, FP] += chain.c30[k] * va - chain.c20[k] * vb
            W[k, FA] = chain.C[k] * ez + chain.c30[k] * v + chain.c105[k] * va \
                - chain.c140[k] * vb
            W[k, FB] = -chain.C[k] * ez - chain.c20[k] * v - chain.c140[k] * va \
                + chain.c105[k] * vb
        zx += chain.l[k] * c * v
        zy += chain.l[k] * s * v
    rx = 0.0
    ry = 0.0
    for k in range(n - 1, -1, -1):
        c = W[k, W_C]
        s = W[k, W_S]
        W[k, FP] += chain.l[k] * (c * rx + s * ry)
        w = chain.l[k] * chain.Mt[k] * W[k, V]
        if full:
            w += chain.C[k] * (W[k, VA] - W[k, VB])
        rx += w * c
        ry += w * s


@njit
def mass_times(kind, phi, v, va, vb, chain, out, out_a, out_b):
    """out = m^{pp} v + m^{pa} va + m^{pb} vb, out_a = m^{ap} v + m^{aa} va + m^{ab} vb,
    out_b likewise (each (n,)) in O(n): the paper's inertia blocks times velocities
    (kind KIND_REDUCED: only out = m^{pp} v; va, vb ignored)."""
    n = phi.shape[0]
    full = kind == KIND_FULL
    W = np.zeros((n, 8))            # cos, sin, v, va, vb, out, out_a, out_b
    for k in range(n):
        W[k, W_C] = math.cos(phi[k])
        W[k, W_S] = math.sin(phi[k])
        W[k, 2] = v[k]
        if full:
            W[k, 3] = va[k]
            W[k, 4] = vb[k]
    inertia_columns(full, chain, W, 2, 3, 4, 5, 6, 7)
    for k in range(n):
        out[k] = W[k, 5]
        if full:
            out_a[k] = W[k, 6]
            out_b[k] = W[k, 7]


def inertia_times(kind, chain, phi, v) -> np.ndarray:
    """M v (3n,) [for the full kind; the reduced kind fills only the first n] at rod angles
    phi (n,) [rad] for velocities v: (n,) rod rates, or (3n,) [phi', alpha', beta'] (the
    slope parts are ignored by the reduced kind), O(n)."""
    phi = np.ascontiguousarray(phi, dtype=float)
    n = phi.shape[0]
    v = np.asarray(v, dtype=float)
    vv = np.zeros(3 * n)
    vv[:v.shape[0]] = v
    out = np.zeros(3 * n)
    mass_times(kind, phi, vv[:n], vv[n:2 * n], vv[2 * n:], chain, out[:n], out[n:2 * n],
               out[2 * n:])
    return out


@njit
def solve_with(kind, phi, chain, extra, fp, fa, fb, out, out_a, out_b):
    """The kernels' solve with given right-hand sides (n,) each: the model's accelerations
    (reduced: phi'' and the slopes) for the generalized forces fp, fa, fb. False if singular."""
    n = phi.shape[0]
    W = extra.work
    for k in range(n):
        W[k, W_C] = math.cos(phi[k])
        W[k, W_S] = math.sin(phi[k])
        W[k, W_FP] = fp[k]
        W[k, W_FA] = fa[k]
        W[k, W_FB] = fb[k]
    if not chain_solve(kind, chain, extra, W):
        return False
    for k in range(n):
        out[k] = W[k, W_X]
        out_a[k] = W[k, W_A]
        out_b[k] = W[k, W_B]
    return True
