"""Compiled right-hand sides of the three models in O(n) time and memory (the hot path).

All kernels share one calling convention so that the compiled integrators can take any of
them: ``rhs(t, y, chain, extra, loads, held, t_side, out)`` writes dy/dt into ``out``.

- ``chain`` (:class:`Chain`): the scene's constant per-rod arrays (n,).
- ``extra`` (:class:`Extra`): the hinge features in the current mode and the kernel's
  scratch (a call allocates nothing, so the kernels are not re-entrant: one model instance per
  thread). A plain chain (no rest angle, stop or lock) runs exactly the paper's equations.
- ``loads`` (:class:`~rod_sim.core.loadlaw.Loads`): the scripted loads' table (row, column,
  shape, amplitude, start, duration arrays);
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

from . import loadlaw
from .jit import njit
from .loadlaw import SHAPE_CONSTANT, SHAPE_PULSE, SHAPE_STEP, Loads  # noqa: F401
from .motion import profile_at

# model kinds of chain_solve
KIND_REDUCED, KIND_FULL = 0, 1

# columns of Extra.work (n, N_WORK)
W_C, W_S, W_GP, W_GA, W_FP, W_FA, W_FB, W_X, W_A, W_B, W_COR = range(11)
W_REC = 11                # 15 columns: v0 (3) and V (3 x 4) of each rod's elimination
W_G = W_REC + 15          # reduced model with gravity: C_k (g . e_k), the slopes' weight term
W_TN = W_G + 1            # the moment tau of the hinge at the rod's tip (:func:`_tip_moments`)
N_WORK = W_TN + 1
N_SMALL = 64              # Extra.small: the 4-vector P, 4 x 4 K and 3 x 5 systems


class Chain(NamedTuple):
    """Constant per-rod arrays, each (n,), SI units: rod length l [m], mass per length m
    [kg/m], node mass mu [kg] (nodes 1..n), Kt = 4 EI / l [N m/rad], hinge stiffness kappa
    [N m/rad] and damping nu [N m s/rad] of hinges 0..n-1, tail mass Mt_k [kg] (the paper's
    M_k), C = m l^2 / 12 [kg m], A_kk the diagonal of m^{phi phi} [kg m^2], c30 = m l^3 / 30,
    c20 = m l^3 / 20, c105 = m l^3 / 105, c140 = m l^3 / 140 [kg m^2] (bending inertia
    coefficients), kappa_tip = kappa of the hinge at the rod's tip (0 for a chain's last rod).

    Several chains on one base: the per-rod arrays are the chains' concatenated in scene order;
    ``prev`` int64 (n,) is the rod before rod k in its chain (-1 for a chain's first rod, whose
    hinge joins it to the base), ``seg`` int64 (nc + 1,) the first rod of each chain and then
    n, ``attach`` (nc, 2) [m] each chain's hinge 0 in the base frame, ``Mc`` (nc,) [kg] each
    chain's mass, ``base`` (N_BASE,) the base's constants (indices ``B_*``: mode, mass [kg],
    inertia about its centre of mass [kg m^2], centre of mass in the base frame [m], wheel
    inertia [kg m^2] (0: none), gravity [m/s^2], pose of a fixed base or offsets of a
    prescribed one [m, rad], the number of base coordinates in the state) and ``motion``
    (3, N_MOTION) the prescribed x, y, psi profiles (:func:`motion_eval`)."""

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
    prev: np.ndarray
    seg: np.ndarray
    attach: np.ndarray
    Mc: np.ndarray
    base: np.ndarray
    motion: np.ndarray


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
    (n, N_WORK) and small (N_SMALL,) scratch; forces (n + 2, 3) the applied loads (rows 0..n-1:
    X, Y [N] at the rods' tip nodes and the motor moment T [N m] of their hinges; row n: the
    base's Fx, Fy [N] at its centre of mass and moment [N m]; row n + 1: the wheel's motor
    torque in column 2) and tau (n + 1,) scratch; kind: KIND_REDUCED (rigid and reduced
    models) or KIND_FULL; bk (N_BK,): the base's pose, rates and accelerations and the base
    rows of the solve (indices ``BK_*``); roots (nc, N_ROOT): each chain's root map."""

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
    bk: np.ndarray
    roots: np.ndarray


# base modes and the indices of Chain.base
MODE_FIXED, MODE_FREE, MODE_PRESCRIBED = 0, 1, 2
(B_MODE, B_MASS, B_INERTIA, B_CX, B_CY, B_WHEEL, B_GX, B_GY, B_X, B_Y, B_PSI, B_NB,
 B_GRAVITY) = range(13)
N_BASE = 13
# prescribed motion profiles: rows of Chain.motion, column 0 the shape code, then parameters
MO_X, MO_Y, MO_PSI = 0, 1, 2
N_MOTION = 4
# Extra.bk (base kinematics and the base solve), by index
(BK_X, BK_Y, BK_PSI, BK_VX, BK_VY, BK_W, BK_AX, BK_AY, BK_APSI, BK_FX, BK_FY, BK_FPSI,
 BK_FTH, BK_ATH, BK_COS, BK_SIN) = range(16)
BK_V = 16       # 4 slots: a base velocity-like column for inertia_columns
BK_M = 20       # 4 slots: the base rows it returns
N_BK = 24
# Extra.roots (nc, N_ROOT): each chain's root map w = P + K u after the tip-to-root sweep
R_P, R_K = 0, 4
N_ROOT = 20


def make_chain(l, m, mu, EI, kappa, nu, seg=None, attach=None, base=None,
               motion=None) -> Chain:
    """:class:`Chain` from the per-rod constants (n,) each [SI]; ``seg`` (nc + 1,) the first
    rod of each chain and n (default: one chain), ``attach`` (nc, 2) [m] (default origin),
    ``base`` (N_BASE,) and ``motion`` (3, N_MOTION) (default: a fixed base at the origin)."""
    l, m, mu, EI, kappa, nu = (np.ascontiguousarray(a, dtype=float)
                               for a in (l, m, mu, EI, kappa, nu))
    n = l.shape[0]
    seg = np.array([0, n] if seg is None else seg, dtype=np.int64)
    nc = seg.shape[0] - 1
    attach = np.zeros((nc, 2)) if attach is None else np.array(attach, dtype=float).reshape(nc, 2)
    ml = m * l
    Mt = np.empty(n)
    kappa_tip = np.empty(n)
    prev = np.arange(-1, n - 1, dtype=np.int64)
    Mc = np.empty(nc)
    for c in range(nc):
        a, b = seg[c], seg[c + 1]
        Mt[a:b] = np.cumsum((mu[a:b] + ml[a:b])[::-1])[::-1] - ml[a:b] / 2.0
        kappa_tip[a:b] = np.append(kappa[a + 1:b], 0.0)
        prev[a] = -1
        Mc[c] = float(np.sum(mu[a:b] + ml[a:b]))
    ml3 = m * l**3
    base = np.zeros(N_BASE) if base is None else np.array(base, dtype=float)
    motion = np.zeros((3, N_MOTION)) if motion is None else np.array(motion, dtype=float)
    return Chain(l, m, mu, 4.0 * EI / l, kappa, nu, Mt, m * l**2 / 12.0,
                 l**2 * (Mt - ml / 2.0) + ml3 / 3.0, ml3 / 30.0, ml3 / 20.0, ml3 / 105.0,
                 ml3 / 140.0, kappa_tip, prev, seg, attach, Mc, base, motion)


def make_extra(rest, stops, contact, locked, pinned, comp=None, kind=KIND_REDUCED,
               dtype=float, nchains=1) -> Extra:
    """:class:`Extra` for n rods: ``rest`` (3, n) [N m], ``stops`` (4, n) = lower, upper [rad],
    stiffness, damping; ``contact`` (n,) int; ``locked``, ``pinned`` (n,) bool; ``comp``
    (n,) compliance of the locked hinges (default 0: rigid); ``dtype`` of the solve's
    scratch and compliances (complex for Radau's complex Newton system); ``nchains`` the
    number of chains (Chain.seg)."""
    n = len(locked)
    f = lambda a: np.ascontiguousarray(a, dtype=float)  # noqa: E731
    i = lambda a: np.ascontiguousarray(a, dtype=np.int64)  # noqa: E731
    contact = f(contact)
    flags = np.array([int(np.any(contact != 0)), int(np.any(locked))], dtype=np.int64)
    return Extra(f(rest[0]), f(rest[1]), f(rest[2]), f(stops[0]), f(stops[1]), f(stops[2]),
                 f(stops[3]), contact, i(locked),
                 np.array(np.zeros(n) if comp is None else comp, dtype=dtype),
                 np.zeros(n, dtype=dtype), i(pinned), flags, np.zeros((n, N_WORK), dtype=dtype),
                 np.zeros(N_SMALL, dtype=dtype), np.zeros((n + 2, 3)), np.zeros(n + 1), int(kind),
                 np.zeros(N_BK, dtype=dtype), np.zeros((nchains, N_ROOT), dtype=dtype))


class Problem(NamedTuple):
    """What a right-hand side needs besides (t, y): ``chain`` (:class:`Chain`), ``extra``
    (:class:`Extra` of the current mode), ``loads`` (the scripted loads,
    :class:`~rod_sim.core.loadlaw.Loads` of ``models.load_table``) and ``held`` (n + 2, 3): the
    held inputs (nodal forces X, Y [N], hinge motor moments T [N m]; base and wheel rows)."""

    chain: Chain
    extra: Extra
    loads: Loads
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
    """The event functions g_e(t, y) = theta_{hinge_e} - angle_e of one mode (m of them):
    ``hinge`` (m,) int64, ``angle`` (m,) [rad], ``kind`` (m,) int64 (``hinges.EV_LATCH``:
    terminal; ``EV_UPPER``, ``EV_LOWER``: stop crossings), ``other`` (m,) int64: the state
    index of the angle on the hinge's other side (the rod before, a free base's psi; -1: a
    fixed or prescribed base, whose constant angle psi_0 is folded into ``angle``), theta =
    y[hinge] - y[other], or y[hinge] - p(t) for other = -1 with ``ground`` (N_MOTION,) the
    profile of a prescribed base's psi = psi_0 + p(t) (a row of Chain.motion; code 0, p = 0:
    a fixed base), :func:`ground_angle`."""

    hinge: np.ndarray
    angle: np.ndarray
    kind: np.ndarray
    other: np.ndarray
    ground: np.ndarray


class Events(NamedTuple):
    """An :class:`EventTable` and the buffer a compiled driver records located crossings in:
    ``t`` (cap,) [s], ``code`` (cap,) int64 = 2 e + (1 if g_e rises), ``y`` (cap, size) the
    states there, ``count`` (1,) int64 the crossings recorded."""

    hinge: np.ndarray
    angle: np.ndarray
    kind: np.ndarray
    other: np.ndarray
    ground: np.ndarray
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
    """Applied loads (n + 2, 3) at time t: the held inputs (n + 2, 3) plus the scripted loads
    ``loads`` (:class:`~rod_sim.core.loadlaw.Loads`; rows and columns as Extra.forces), each
    by :func:`scripted_value`."""
    out[:, :] = held
    for i in range(loads.row.shape[0]):
        out[loads.row[i], loads.col[i]] += scripted_value(t, loads.shape[i], loads.amp[i],
                                                          loads.start[i], loads.dur[i], t_side)


scripted_value = njit(inline="always")(loadlaw.scripted_value)
"""One scripted load's value: :func:`rod_sim.core.loadlaw.scripted_value` compiled, the one
scripted-load law of Python and kernels."""


_profile_at = njit(inline="always")(profile_at)


@njit(inline="always")
def motion_eval(motion, r, t):
    """Value, rate and acceleration of the prescribed profile ``motion[r]`` = (code, a, b,
    start) at time t [s]: :func:`rod_sim.core.motion.profile_at`, the one law of Python and
    kernels (units of the coordinate: m or rad)."""
    return _profile_at(int(motion[r, 0]), motion[r, 1], motion[r, 2], motion[r, 3], t)


@njit(inline="always")
def ground_angle(profile, t):
    """p(t) [rad]: the prescribed part of a base's angle psi = psi_0 + p(t) from its profile
    ``profile`` (N_MOTION,) = (code, a, b, start) (the row MO_PSI of Chain.motion) at time t
    [s], by :func:`rod_sim.core.motion.profile_at` (the law of :func:`motion_eval`); 0 for
    code 0 (hold, or a fixed base's zero row). What a hinge-0 event function subtracts
    (:class:`EventTable`)."""
    return _profile_at(int(profile[0]), profile[1], profile[2], profile[3], t)[0]


@njit(inline="always")
def _generalized_forces(ch, W, forces):
    """Q_k = l_k (c_k sum_{j>=k} Y_j - s_k sum_{j>=k} X_j) [N m] over the nodes j of rod k's
    chain, plus gravity on everything beyond node k-1 (l_k M_k (c_k g_y - s_k g_x)), into
    W[:, W_FP]."""
    l = ch.l
    seg = ch.seg
    grav = ch.base[B_GRAVITY] != 0.0
    gx = ch.base[B_GX]
    gy = ch.base[B_GY]
    for ci in range(seg.shape[0] - 1):
        sx = 0.0
        sy = 0.0
        for k in range(seg[ci + 1] - 1, seg[ci] - 1, -1):
            sx += forces[k, 0]
            sy += forces[k, 1]
            W[k, W_FP] = l[k] * (W[k, W_C] * sy - W[k, W_S] * sx)
            if grav:
                W[k, W_FP] += l[k] * ch.Mt[k] * (W[k, W_C] * gy - W[k, W_S] * gx)


@njit(inline="always")
def _velocity_terms(ch, dphi, W):
    """g^{phi phi} Lambda phi' into W[:, W_GP] and g^{alpha phi} Lambda phi' into W[:, W_GA]
    (n,) [N m] (g^{beta phi} Lambda phi' = -g_alpha) from cos/sin in W[:, W_C], W[:, W_S]:
    sin(phi_k - phi_j) = s_k c_j - c_k s_j turns the pair sums into prefix/suffix sums (over
    the rods of one chain)."""
    seg = ch.seg
    for ci in range(seg.shape[0] - 1):
        k0 = seg[ci]
        k1 = seg[ci + 1]
        sc = 0.0
        ss = 0.0
        for k in range(k0, k1):
            c = W[k, W_C]
            s = W[k, W_S]
            low = s * sc - c * ss               # sum_{j<k} l_j sin(phi_k - phi_j) phi_j'^2
            W[k, W_GP] = ch.l[k] * ch.Mt[k] * low
            W[k, W_GA] = ch.C[k] * low
            w = ch.l[k] * dphi[k] * dphi[k]
            sc += w * c
            ss += w * s
        sc = 0.0
        ss = 0.0
        for k in range(k1 - 1, k0 - 1, -1):
            c = W[k, W_C]
            s = W[k, W_S]
            W[k, W_GP] += ch.l[k] * (s * sc - c * ss)
            w = ch.l[k] * ch.Mt[k] * dphi[k] * dphi[k]
            sc += w * c
            ss += w * s


@njit(inline="always")
def _start(t, phi, dphi, ch, ex, loads, held, t_side):
    """What every kernel computes first: cos/sin, velocity terms, applied loads, Q (into
    W[:, W_FP]); returns the work array W (n, N_WORK)."""
    W = ex.work
    n = phi.shape[0]
    for k in range(n):
        W[k, W_C] = math.cos(phi[k])
        W[k, W_S] = math.sin(phi[k])
    _velocity_terms(ch, dphi, W)
    load_forces(t, loads, held, t_side, ex.forces)
    _generalized_forces(ch, W, ex.forces)
    return W


@njit(inline="always")
def _base_state(t, y, ch, ex, i0, dof):
    """The base frame's pose, rates and known accelerations into ex.bk (the rest of bk
    zeroed): a free base's from y (x_B at index i0, q of size dof), a prescribed one's from
    its profiles, a fixed one's pose from the scene."""
    b = ch.base
    bk = ex.bk
    for i in range(bk.shape[0]):
        bk[i] = 0.0
    mode = b[B_MODE]
    if mode == MODE_FREE:
        for i in range(3):
            bk[BK_X + i] = y[i0 + i]
            bk[BK_VX + i] = y[dof + i0 + i]
    elif mode == MODE_PRESCRIBED:
        for i in range(3):
            v, vd, vdd = motion_eval(ch.motion, i, t)
            bk[BK_X + i] = b[B_X + i] + v
            bk[BK_VX + i] = vd
            bk[BK_AX + i] = vdd
    else:
        for i in range(3):
            bk[BK_X + i] = b[B_X + i]
    bk[BK_COS] = math.cos(bk[BK_PSI])
    bk[BK_SIN] = math.sin(bk[BK_PSI])


@njit(inline="always")
def hinge_angle(phi, dphi, h, ch, bk):
    """Rigid hinge angle theta_h [rad] and its rate [rad/s]: phi_{h+1} - phi_h inside a
    chain, phi_1 - psi (the base's angle) at a chain's hinge 0."""
    p = ch.prev[h]
    if p < 0:
        return phi[h] - bk[BK_PSI], dphi[h] - bk[BK_W]
    return phi[h] - phi[p], dphi[h] - dphi[p]


@njit(inline="always")
def _stop_moments(phi, dphi, ch, ex, W):
    """Add the stop-contact moments (on the rigid hinge angles) to the phi rows W[:, W_FP]
    (at a chain's hinge 0 the opposite moment goes to the base's psi row, bk[BK_FPSI])."""
    if ex.flags[0] == 0:
        return
    n = phi.shape[0]
    for h in range(n):
        th, dth = hinge_angle(phi, dphi, h, ch, ex.bk)
        m = 0.0
        side = ex.contact[h]
        if side > 0.0:
            m = -max(0.0, ex.stop_k[h] * (th - ex.stop_upper[h]) + ex.stop_c[h] * dth)
        elif side < 0.0:
            m = max(0.0, ex.stop_k[h] * (ex.stop_lower[h] - th) - ex.stop_c[h] * dth)
        W[h, W_FP] += m
        p = ch.prev[h]
        if p >= 0:
            W[p, W_FP] -= m
        else:
            ex.bk[BK_FPSI] -= m


@njit(inline="always")
def _base_forces(full, ch, ex, W, dphi, dal, dbe, tau):
    """The free base's right-hand sides into bk: BK_FX, BK_FY (translation), BK_FPSI
    (rotation about the base frame's origin) and BK_FTH (the wheel): the base's loads and
    weight, its centre of mass's centripetal term and, per chain, the applied force and
    weight less the chain's velocity terms, moved to the node-0 point, plus the hinge-0
    moment (tau, rest angle); the chains' inertia coupling is added by :func:`chain_solve`."""
    b = ch.base
    bk = ex.bk
    n = dphi.shape[0]
    cps = bk[BK_COS]
    sps = bk[BK_SIN]
    w2 = bk[BK_W] * bk[BK_W]
    gx = b[B_GX]
    gy = b[B_GY]
    mB = b[B_MASS]
    rcx = cps * b[B_CX] - sps * b[B_CY]
    rcy = sps * b[B_CX] + cps * b[B_CY]
    fbx = ex.forces[n, 0] + mB * gx
    fby = ex.forces[n, 1] + mB * gy
    fx = fbx + mB * w2 * rcx
    fy = fby + mB * w2 * rcy
    fpsi = ex.forces[n, 2] + (-rcy * fbx + rcx * fby)
    seg = ch.seg
    for ci in range(seg.shape[0] - 1):
        k0 = seg[ci]
        ex_x = ch.Mc[ci] * gx
        ex_y = ch.Mc[ci] * gy
        for k in range(k0, seg[ci + 1]):
            v = ch.l[k] * ch.Mt[k] * dphi[k] * dphi[k]
            if full:
                v += 2.0 * ch.C[k] * dphi[k] * (dal[k] - dbe[k])
            ex_x += ex.forces[k, 0] + v * W[k, W_C]
            ex_y += ex.forces[k, 1] + v * W[k, W_S]
        rax = cps * ch.attach[ci, 0] - sps * ch.attach[ci, 1]
        ray = sps * ch.attach[ci, 0] + cps * ch.attach[ci, 1]
        fx += ex_x
        fy += ex_y
        fpsi += -ray * ex_x + rax * ex_y + tau[k0] - ex.rest_alpha[k0]
    bk[BK_FX] = fx
    bk[BK_FY] = fy
    bk[BK_FPSI] = fpsi
    bk[BK_FTH] = ex.forces[n + 1, 2]


@njit(inline="always")
def _factor3(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """Gaussian elimination with partial pivoting of the 3 x 3 matrix with rows (a0, a1, a2),
    (b0, b1, b2), (c0, c1, c2), in scalars: (ok, p0, p1, f1, f2, f3, a1, a2, b2, inv0, inv1,
    inv2) with ok False if the matrix is singular, p0 the row exchanged with row 0 (0, 1, 2),
    p1 the row exchanged with row 1 (1, 2), f1, f2, f3 the multipliers of rows 1, 2 (by row
    0) and of row 2 (by row 1), the upper triangle's a1, a2, b2 and the reciprocals of its
    diagonal; :func:`_subst3` applies them to a right-hand side."""
    p0 = 0
    best = abs(a0)
    if abs(b0) > best:
        best = abs(b0)
        p0 = 1
    if abs(c0) > best:
        best = abs(c0)
        p0 = 2
    if best == 0.0:
        return False, 0, 0, a0, a0, a0, a1, a2, b2, a0, a0, a0
    if p0 == 1:
        a0, a1, a2, b0, b1, b2 = b0, b1, b2, a0, a1, a2
    elif p0 == 2:
        a0, a1, a2, c0, c1, c2 = c0, c1, c2, a0, a1, a2
    inv0 = 1.0 / a0
    f1 = b0 * inv0
    if f1 != 0.0:
        b1 -= f1 * a1
        b2 -= f1 * a2
    f2 = c0 * inv0
    if f2 != 0.0:
        c1 -= f2 * a1
        c2 -= f2 * a2
    p1 = 1
    best = abs(b1)
    if abs(c1) > best:
        best = abs(c1)
        p1 = 2
    if best == 0.0:
        return False, 0, 0, a0, a0, a0, a1, a2, b2, a0, a0, a0
    if p1 == 2:
        b1, b2, c1, c2 = c1, c2, b1, b2
    inv1 = 1.0 / b1
    f3 = c1 * inv1
    if f3 != 0.0:
        c2 -= f3 * b2
    if abs(c2) == 0.0:
        return False, 0, 0, a0, a0, a0, a1, a2, b2, a0, a0, a0
    return True, p0, p1, f1, f2, f3, a1, a2, b2, inv0, inv1, 1.0 / c2


@njit(inline="always")
def _subst3(lu, g0, g1, g2):
    """The solution (x0, x1, x2) for the right-hand side (g0, g1, g2) of the elimination
    ``lu`` of :func:`_factor3`: the row exchanges and eliminations, then back substitution,
    each operation as row-wise elimination of [E | g] does it."""
    _, p0, p1, f1, f2, f3, a1, a2, b2, inv0, inv1, inv2 = lu
    if p0 == 1:
        g0, g1 = g1, g0
    elif p0 == 2:
        g0, g2 = g2, g0
    if f1 != 0.0:
        g1 -= f1 * g0
    if f2 != 0.0:
        g2 -= f2 * g0
    if p1 == 2:
        g1, g2 = g2, g1
    if f3 != 0.0:
        g2 -= f3 * g1
    x2 = g2 * inv2
    x1 = (g1 - b2 * x2) * inv1
    return (g0 - a1 * x1 - a2 * x2) * inv0, x1, x2


@njit(inline="always")
def _solve3(E, G, ncol):
    """Solve E X = G in place for E (3, 3) and the first ``ncol`` columns of G (3, 5) by
    Gaussian elimination with partial pivoting (:func:`_factor3`, :func:`_subst3`; X
    overwrites G, E is left as it was). False if E is singular."""
    lu = _factor3(E[0, 0], E[0, 1], E[0, 2], E[1, 0], E[1, 1], E[1, 2], E[2, 0], E[2, 1],
                  E[2, 2])
    if not lu[0]:
        return False
    for j in range(ncol):
        x0, x1, x2 = _subst3(lu, G[0, j], G[1, j], G[2, j])
        G[0, j] = x0
        G[1, j] = x1
        G[2, j] = x2
    return True


@njit(inline="always")
def _sweep_back(kind, ch, ex, W, r0, r1):
    """Eliminate rods r1-1 .. r0 (one chain) from the tip to the root: leaves the chain's root
    map w = P + K u (P = ex.small[0:4], K = ex.small[4:20] as 4 x 4) of the interface u =
    (z (2), rho or beta, x) of the rod before rod r0 and each rod's affine record in W.
    False if singular.

    Each rod's 3 x 5 system [E | G] (the rod's three rows; columns: the constant and the
    coefficients of u) and the map (P, K) carried from rod to rod are local variables
    (e_ij, g_ij, p_i, k_ij), not arrays: the rods are eliminated one after the other, each
    from the previous one's map, and a round trip through memory of each intermediate value
    lengthened that chain (the operations and their order are those of the array version)."""
    full = kind == KIND_FULL
    grav = not full and ch.base[B_GRAVITY] != 0.0
    l = ch.l
    Mt = ch.Mt
    Cc = ch.C
    Akk = ch.Akk
    c30 = ch.c30
    c20 = ch.c20
    c105 = ch.c105
    c140 = ch.c140
    Kt = ch.Kt
    kappa = ch.kappa
    kappa_tip = ch.kappa_tip
    locked_ = ex.locked
    comp = ex.comp
    gw = ex.gw
    pinned = ex.pinned
    p0 = p1 = p2 = p3 = 0.0
    k00 = k01 = k02 = k03 = 0.0
    k10 = k11 = k12 = k13 = 0.0
    k20 = k21 = k22 = k23 = 0.0
    k30 = k31 = k32 = k33 = 0.0
    for r in range(r1 - 1, r0 - 1, -1):
        L = l[r]
        c = W[r, W_C]
        s = W[r, W_S]
        lc0 = L * c
        lc1 = L * s
        lM = L * Mt[r]
        Cr = Cc[r]
        # w_{r+1} = P + K u_{r+1}, u_{r+1} = (z + l e x, rho, x or -) : coefficients of x, beta
        if full:
            kx0 = lc0 * k00 + lc1 * k01 + k02
            kx1 = lc0 * k10 + lc1 * k11 + k12
            kx2 = lc0 * k20 + lc1 * k21 + k22
            kx3 = lc0 * k30 + lc1 * k31 + k32
        else:
            kx0 = lc0 * k00 + lc1 * k01 + k03
            kx1 = lc0 * k10 + lc1 * k11 + k13
            kx2 = lc0 * k20 + lc1 * k21 + k23
            kx3 = lc0 * k30 + lc1 * k31 + k33
        kb0 = k02
        kb1 = k12
        kb2 = k22
        kb3 = k32
        g03 = g04 = g13 = g14 = g23 = g24 = 0.0
        if full:
            e00 = Akk[r] + lc0 * kx0 + lc1 * kx1 - kx2
            e01 = c30[r]
            e02 = -c20[r] + lc0 * kb0 + lc1 * kb1 - kb2
            g00 = W[r, W_FP] - (lc0 * p0 + lc1 * p1 - p2)
            g01 = -(lc0 * k00 + lc1 * k10 + lM * c - k20)
            g02 = -(lc0 * k01 + lc1 * k11 + lM * s - k21)
            e10 = c30[r]
            e11 = c105[r]
            e12 = -c140[r]
            g10 = W[r, W_FA]
            g11 = -Cr * c
            g12 = -Cr * s
            e20 = -c20[r] - kx2
            e21 = -c140[r]
            e22 = c105[r] - kb2
            g20 = W[r, W_FB] + p2
            g21 = Cr * c + k20
            g22 = Cr * s + k21
        else:
            ka = kappa[r]
            kt = kappa_tip[r]
            e00 = Akk[r] + lc0 * kx0 + lc1 * kx1 - kt * kx2 - kx3
            e01 = ka
            e02 = lc0 * kb0 + lc1 * kb1 + kt - kt * kb2 - kb3
            if grav:
                # gravity's bending term -C (g . e)(alpha - beta) of the phi row, moved left
                e01 += W[r, W_G]
                e02 -= W[r, W_G]
            g00 = W[r, W_FP] - (lc0 * p0 + lc1 * p1 - kt * p2 - p3)
            g01 = -(lc0 * k00 + lc1 * k10 + lM * c - kt * k20 - k30)
            g02 = -(lc0 * k01 + lc1 * k11 + lM * s - kt * k21 - k31)
            g03 = ka
            Ktr = Kt[r]
            e10 = c30[r]
            e11 = ka + Ktr
            e12 = 0.5 * Ktr
            g10 = W[r, W_FA]
            g11 = -Cr * c
            g12 = -Cr * s
            g13 = ka
            # beta row: -kappa_{r+1} alpha_{r+1} - gw_{r+1} lambda_{r+1}
            gt = gw[r + 1] if r + 1 < r1 else 0.0
            e20 = -c20[r] - kt * kx2 - gt * kx3
            e21 = 0.5 * Ktr
            e22 = kt + Ktr - kt * kb2 - gt * kb3
            g20 = W[r, W_FB] + kt * p2 + gt * p3
            g21 = Cr * c + kt * k20 + gt * k30
            g22 = Cr * s + kt * k21 + gt * k31
        locked = locked_[r] != 0
        cr = comp[r]
        if locked:
            # phi''_r is given by the rod before (reduced: x_{r-1} = u_3; full: rho - alpha''
            # with rho = u_2 = x_{r-1} + beta''_{r-1}), less comp * lambda for a compliant
            # hinge; slot 0 becomes the multiplier lambda
            col0 = e00
            col1 = e10
            col2 = e20
            e00 = 1.0 - cr * col0
            e10 = (1.0 if full else gw[r]) - cr * col1
            e20 = -cr * col2
            if full:
                e01 -= col0
                e11 -= col1
                e21 -= col2
                g03 -= col0
                g13 -= col1
                g23 -= col2
            else:
                g04 -= col0
                g14 -= col1
                g24 -= col2
        if pinned[r] != 0:
            e10 = e12 = e20 = e21 = 0.0
            e11 = e22 = 1.0
            g10 = g11 = g12 = g13 = g14 = 0.0
            g20 = g21 = g22 = g23 = g24 = 0.0
        lu = _factor3(e00, e01, e02, e10, e11, e12, e20, e21, e22)
        if not lu[0]:
            return False
        g00, g10, g20 = _subst3(lu, g00, g10, g20)
        g01, g11, g21 = _subst3(lu, g01, g11, g21)
        g02, g12, g22 = _subst3(lu, g02, g12, g22)
        g03, g13, g23 = _subst3(lu, g03, g13, g23)
        g04, g14, g24 = _subst3(lu, g04, g14, g24)
        W[r, W_REC] = g00
        W[r, W_REC + 1] = g01
        W[r, W_REC + 2] = g02
        W[r, W_REC + 3] = g03
        W[r, W_REC + 4] = g04
        W[r, W_REC + 5] = g10
        W[r, W_REC + 6] = g11
        W[r, W_REC + 7] = g12
        W[r, W_REC + 8] = g13
        W[r, W_REC + 9] = g14
        W[r, W_REC + 10] = g20
        W[r, W_REC + 11] = g21
        W[r, W_REC + 12] = g22
        W[r, W_REC + 13] = g23
        W[r, W_REC + 14] = g24
        # phi''_r as an affine map of u: xu = [x0, X_0..X_3]
        if not locked:
            xu0, xu1, xu2, xu3, xu4 = g00, g01, g02, g03, g04
        elif full:
            xu0 = -g10 - cr * g00
            xu1 = -g11 - cr * g01
            xu2 = -g12 - cr * g02
            xu3 = -g13 - cr * g03
            xu4 = -g14 - cr * g04
            xu3 += 1.0
        else:
            xu0 = -cr * g00
            xu1 = -cr * g01
            xu2 = -cr * g02
            xu3 = -cr * g03
            xu4 = -cr * g04
            xu4 += 1.0
        # the interface to the rod before: w_r = (R_{r-1}, 2 more) = nP + nK u
        ax = kx0 + lM * c
        if full:
            ab = kb0 - Cr * c
            aa = Cr * c
        else:
            ab = kb0
            aa = 0.0
        q0 = p0 + ax * xu0 + ab * g20 + aa * g10
        n00 = ax * xu1 + ab * g21 + aa * g11
        n01 = ax * xu2 + ab * g22 + aa * g12
        n02 = ax * xu3 + ab * g23 + aa * g13
        n03 = ax * xu4 + ab * g24 + aa * g14
        n00 += k00
        n01 += k01
        ax = kx1 + lM * s
        if full:
            ab = kb1 - Cr * s
            aa = Cr * s
        else:
            ab = kb1
            aa = 0.0
        q1 = p1 + ax * xu0 + ab * g20 + aa * g10
        n10 = ax * xu1 + ab * g21 + aa * g11
        n11 = ax * xu2 + ab * g22 + aa * g12
        n12 = ax * xu3 + ab * g23 + aa * g13
        n13 = ax * xu4 + ab * g24 + aa * g14
        n10 += k10
        n11 += k11
        k00, k01, k02, k03 = n00, n01, n02, n03
        k10, k11, k12, k13 = n10, n11, n12, n13
        k30 = k31 = k32 = k33 = 0.0
        if full:
            if locked:
                p2 = g00
                k20, k21, k22, k23 = g01, g02, g03, g04
            else:
                p2 = 0.0
                k20 = k21 = k22 = k23 = 0.0
            p3 = 0.0
        else:
            p2 = g10
            k20, k21, k22, k23 = g11, g12, g13, g14
            if locked:
                p3 = g00
                k30, k31, k32, k33 = g01, g02, g03, g04
            else:
                p3 = 0.0
        p0 = q0
        p1 = q1
    sm = ex.small
    sm[0] = p0
    sm[1] = p1
    sm[2] = p2
    sm[3] = p3
    sm[4] = k00
    sm[5] = k01
    sm[6] = k02
    sm[7] = k03
    sm[8] = k10
    sm[9] = k11
    sm[10] = k12
    sm[11] = k13
    sm[12] = k20
    sm[13] = k21
    sm[14] = k22
    sm[15] = k23
    sm[16] = k30
    sm[17] = k31
    sm[18] = k32
    sm[19] = k33
    return True


@njit(inline="always")
def _sweep_fwd(kind, ch, ex, W, r0, r1, u0, u1, u2, u3):
    """Substitute forward through rods r0 .. r1-1 from the root interface u = (u0, u1, u2, u3):
    phi'' (W_X), alpha or alpha'' (W_A), beta or beta'' (W_B)."""
    full = kind == KIND_FULL
    for r in range(r0, r1):
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
    seg = ch.seg
    nc = seg.shape[0] - 1
    mode = ch.base[B_MODE]
    bk = ex.bk
    cps = bk[BK_COS]
    sps = bk[BK_SIN]
    w2 = bk[BK_W] * bk[BK_W]
    # one call site of each sweep: numba types and lowers an inlined helper at every site,
    # and the backward sweep is most of a kernel's compile time
    for ci in range(nc):
        if not _sweep_back(kind, ch, ex, W, seg[ci], seg[ci + 1]):
            return False
        if mode == MODE_FREE:
            for i in range(20):
                ex.roots[ci, i] = ex.small[i]
        else:
            _forward_from_base(kind, ch, ex, W, ci, cps, sps, w2, mode == MODE_PRESCRIBED)
    if mode == MODE_FREE:
        return _free_base_solve(kind, ch, ex, W, cps, sps, w2)
    return True


@njit(inline="always")
def _free_base_solve(kind, ch, ex, W, cps, sps, w2):
    """A free base, after :func:`chain_solve`'s backward sweeps left every chain's root map
    in ex.roots: the base's 3 x 3 system for (x_B'', y_B'', psi'') (the base's rows with each
    chain's inertia, hinge-0 moment and lock multiplier as affine maps of the base's
    accelerations: the Schur complement of the chains), then every chain forward from its
    node-0 acceleration. Right-hand sides of the base rows in
    bk[BK_FX..BK_FTH]; accelerations out in bk[BK_AX], bk[BK_AY], bk[BK_APSI], bk[BK_ATH]."""
    full = kind == KIND_FULL
    b = ch.base
    bk = ex.bk
    seg = ch.seg
    nc = seg.shape[0] - 1
    sm = ex.small
    A = sm[20:29].reshape((3, 3))
    G = sm[29:44].reshape((3, 5))
    mB = b[B_MASS]
    rcx = cps * b[B_CX] - sps * b[B_CY]
    rcy = sps * b[B_CX] + cps * b[B_CY]
    for i in range(3):
        for j in range(3):
            A[i, j] = 0.0
        for j in range(5):
            G[i, j] = 0.0
    A[0, 0] = mB
    A[1, 1] = mB
    A[0, 2] = -mB * rcy
    A[1, 2] = mB * rcx
    A[2, 0] = -mB * rcy
    A[2, 1] = mB * rcx
    A[2, 2] = b[B_INERTIA] + mB * (rcx * rcx + rcy * rcy)
    G[0, 0] = bk[BK_FX]
    G[1, 0] = bk[BK_FY]
    G[2, 0] = bk[BK_FPSI] - bk[BK_FTH]
    sl = 2 if full else 3                   # the root slot that takes psi''
    for ci in range(nc):
        P = ex.roots[ci, R_P:R_P + 4]
        K = ex.roots[ci, R_K:R_K + 16].reshape((4, 4))
        Mc = ch.Mc[ci]
        rax = cps * ch.attach[ci, 0] - sps * ch.attach[ci, 1]
        ray = sps * ch.attach[ci, 0] + cps * ch.attach[ci, 1]
        ex_ = -ray                          # e = J R a: node 0's velocity per unit psi'
        ey_ = rax
        kx = -w2 * rax                      # known (centripetal) part of node 0's acceleration
        ky = -w2 * ray
        kap = 0.0 if full else ch.kappa[seg[ci]]
        # columns: 0 constant (u = u_k = J^T a0k), 1 x_B'', 2 y_B'', 3 psi''
        for col in range(4):
            if col == 0:
                acx, acy = kx, ky
            elif col == 1:
                acx, acy = 1.0, 0.0
            elif col == 2:
                acx, acy = 0.0, 1.0
            else:
                acx, acy = ex_, ey_
            # the root map w = P + K u at this column's u (u = (a0_y, -a0_x, psi'' slot))
            w0 = K[0, 0] * acy - K[0, 1] * acx
            w1 = K[1, 0] * acy - K[1, 1] * acx
            w2_ = K[2, 0] * acy - K[2, 1] * acx
            w3 = K[3, 0] * acy - K[3, 1] * acx
            if col == 3:
                w0 += K[0, sl]
                w1 += K[1, sl]
                w2_ += K[2, sl]
                w3 += K[3, sl]
            if col == 0:
                w0 += P[0]
                w1 += P[1]
                w2_ += P[2]
                w3 += P[3]
            fx = Mc * acx - w1              # chain inertia force: Mc a0 + J R
            fy = Mc * acy + w0
            fp = ex_ * fx + ey_ * fy - (w2_ if full else kap * w2_ + w3)
            if col == 0:
                G[0, 0] -= fx
                G[1, 0] -= fy
                G[2, 0] -= fp
            else:
                A[0, col - 1] += fx
                A[1, col - 1] += fy
                A[2, col - 1] += fp
    if not _solve3(A, G, 1):
        return False
    ax = G[0, 0]
    ay = G[1, 0]
    ap = G[2, 0]
    bk[BK_AX] = ax
    bk[BK_AY] = ay
    bk[BK_APSI] = ap
    bk[BK_ATH] = bk[BK_FTH] / b[B_WHEEL] - ap if b[B_WHEEL] > 0.0 else 0.0 * ap
    for ci in range(nc):
        _forward_from_base(kind, ch, ex, W, ci, cps, sps, w2, True)
    return True


@njit(inline="always")
def _forward_from_base(kind, ch, ex, W, ci, cps, sps, w2, moving):
    """Chain ci forward from its node 0. On a fixed base (``moving`` False) the root
    interface is u = 0; on a moving one node 0's acceleration follows from the base's
    (x_B'', y_B'', psi'') = ex.bk[BK_AX, BK_AY, BK_APSI], its rate squared w2 and the cos, sin
    of its angle: a_0 = a_B + psi'' J R a - psi'^2 R a, the root interface u = (J^T a_0,
    psi'' in the model's rotation slot)."""
    seg = ch.seg
    u0 = u1 = u2 = u3 = 0.0
    if moving:
        bk = ex.bk
        ax = bk[BK_AX]
        ay = bk[BK_AY]
        ap = bk[BK_APSI]
        rax = cps * ch.attach[ci, 0] - sps * ch.attach[ci, 1]
        ray = sps * ch.attach[ci, 0] + cps * ch.attach[ci, 1]
        a0x = ax - ap * ray - w2 * rax
        a0y = ay + ap * rax - w2 * ray
        u0 = a0y
        u1 = -a0x
        if kind == KIND_FULL:
            u2 = ap
        else:
            u3 = ap
    _sweep_fwd(kind, ch, ex, W, seg[ci], seg[ci + 1], u0, u1, u2, u3)


@njit(inline="always")
def _hinge_moments(phi, dphi, ch, ex, W, tau):
    """tau_h = kappa_h Delta_h + nu_h Delta_h' - T_h (n + 1,) [N m] with the rigid hinge
    angles (gamma = 0; tau_n = 0), and the rest-angle forces added to W's right-hand sides."""
    n = phi.shape[0]
    for h in range(n):
        d, dd = hinge_angle(phi, dphi, h, ch, ex.bk)
        tau[h] = ch.kappa[h] * d + ch.nu[h] * dd - ex.forces[h, 2]
        W[h, W_FA] = ex.rest_alpha[h]
        W[h, W_FB] = ex.rest_beta[h]
    tau[n] = 0.0


@njit(inline="always")
def _tip_moments(ch, tau, W):
    """W[k, W_TN] = the moment tau (n + 1,) of the hinge at rod k's tip (0 at a chain's last
    rod) [N m], for every rod k. One loop over the rods, so that the per-rod loops that use it
    pass no Chain to a helper: a helper called per rod with the Chain (20 arrays) made numba
    count references to every one of its arrays on every call where its pruning of those
    counts fails (a conditional expression: ~100 ns per call at n = 1024, half of
    reduced_rhs)."""
    n = W.shape[0]
    prev = ch.prev
    for k in range(n):
        W[k, W_TN] = tau[k + 1] if k + 1 < n and prev[k + 1] == k else 0.0


@njit(inline="always")
def _layout(kind, ch):
    """(n, i0, dof): rods, the index of the base's first coordinate in q (= the chains'
    coordinates), the size of q."""
    n = ch.l.shape[0]
    i0 = 3 * n if kind == KIND_FULL else n
    return n, i0, i0 + int(ch.base[B_NB])


@njit(inline="always")
def _finish(n, i0, dof, W, y, ex, out):
    """dq/dt = the velocities and the accelerations (phi'' from the solve's W_X column; a free
    base's from ex.bk) into out for the rigid and reduced models."""
    for k in range(n):
        out[k] = y[dof + k]
        out[dof + k] = W[k, W_X]
    _finish_base(i0, dof, y, ex, out)


@njit(inline="always")
def _finish_base(i0, dof, y, ex, out):
    nb = dof - i0
    for i in range(nb):
        out[i0 + i] = y[dof + i0 + i]
    if nb > 0:
        out[dof + i0] = ex.bk[BK_AX]
        out[dof + i0 + 1] = ex.bk[BK_AY]
        out[dof + i0 + 2] = ex.bk[BK_APSI]
    if nb > 3:
        out[dof + i0 + 3] = ex.bk[BK_ATH]


@njit(inline="always")
def _fill_nan(out):
    for i in range(out.shape[0]):
        out[i] = np.nan


@njit
def rigid_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Rigid chains (EI -> infinity): y = [phi, base, phi', base'] (base: x_B, y_B, psi
    [, theta_w] of a free base); every rod pinned."""
    n, i0, dof = _layout(KIND_REDUCED, chain)
    phi = y[:n]
    dphi = y[dof:dof + n]
    _base_state(t, y, chain, extra, i0, dof)
    W = _start(t, phi, dphi, chain, extra, loads, held, t_side)
    tau = extra.tau
    _hinge_moments(phi, dphi, chain, extra, W, tau)
    _tip_moments(chain, tau, W)
    for k in range(n):
        W[k, W_FP] += extra.rest_phi[k] - W[k, W_GP] - tau[k] + W[k, W_TN]
        W[k, W_G] = 0.0                     # rigid rods: no bending term
    if chain.base[B_MODE] == MODE_FREE:
        _base_forces(False, chain, extra, W, dphi, dphi, dphi, tau)
    _stop_moments(phi, dphi, chain, extra, W)
    if not chain_solve(KIND_REDUCED, chain, extra, W):
        _fill_nan(out)
        return
    _finish(n, i0, dof, W, y, extra, out)


@njit
def reduced_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Reduced model, eq. (15) through (14): y = [phi, base, phi', base']; the quasi-static
    end slopes alpha, beta are left in extra.work[:, W_A], extra.work[:, W_B]."""
    n, i0, dof = _layout(KIND_REDUCED, chain)
    phi = y[:n]
    dphi = y[dof:dof + n]
    _base_state(t, y, chain, extra, i0, dof)
    W = _start(t, phi, dphi, chain, extra, loads, held, t_side)
    tau = extra.tau
    _hinge_moments(phi, dphi, chain, extra, W, tau)
    _tip_moments(chain, tau, W)
    grav = chain.base[B_GRAVITY] != 0.0
    gx = chain.base[B_GX]
    gy = chain.base[B_GY]
    for k in range(n):
        ga = W[k, W_GA]
        tn = W[k, W_TN]
        W[k, W_FP] += extra.rest_phi[k] - W[k, W_GP] - tau[k] + tn
        W[k, W_FA] += -ga - tau[k]
        W[k, W_FB] += ga + tn
        if grav:
            gp = chain.C[k] * (W[k, W_C] * gy - W[k, W_S] * gx)
            W[k, W_FA] += gp
            W[k, W_FB] -= gp
            W[k, W_G] = chain.C[k] * (W[k, W_C] * gx + W[k, W_S] * gy)
    if chain.base[B_MODE] == MODE_FREE:
        _base_forces(False, chain, extra, W, dphi, dphi, dphi, tau)
    _stop_moments(phi, dphi, chain, extra, W)
    if not chain_solve(KIND_REDUCED, chain, extra, W):
        _fill_nan(out)
        return
    _finish(n, i0, dof, W, y, extra, out)


@njit
def full_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Full model (9)-(10): y = [phi, alpha, beta, base, phi', alpha', beta', base']."""
    n, i0, dof = _layout(KIND_FULL, chain)
    phi = y[:n]
    al = y[n:2 * n]
    be = y[2 * n:3 * n]
    dphi = y[dof:dof + n]
    dal = y[dof + n:dof + 2 * n]
    dbe = y[dof + 2 * n:dof + 3 * n]
    _base_state(t, y, chain, extra, i0, dof)
    W = _start(t, phi, dphi, chain, extra, loads, held, t_side)
    tau = extra.tau
    bk = extra.bk
    for h in range(n):
        p = chain.prev[h]
        if p < 0:
            d = phi[h] + al[h] - bk[BK_PSI]
            dd = dphi[h] + dal[h] - bk[BK_W]
        else:
            d = phi[h] + al[h] - phi[p] - be[p]
            dd = dphi[h] + dal[h] - dphi[p] - dbe[p]
        tau[h] = chain.kappa[h] * d + chain.nu[h] * dd - extra.forces[h, 2]
    tau[n] = 0.0
    _tip_moments(chain, tau, W)
    grav = chain.base[B_GRAVITY] != 0.0
    gx = chain.base[B_GX]
    gy = chain.base[B_GY]
    # 2 [g^{phi alpha}] Lambda alpha' + 2 [g^{phi beta}] Lambda beta': suffix sums over j > k
    seg = chain.seg
    for ci in range(seg.shape[0] - 1):
        sc = 0.0
        ss = 0.0
        for k in range(seg[ci + 1] - 1, seg[ci] - 1, -1):
            c = W[k, W_C]
            s = W[k, W_S]
            cor = chain.l[k] * (s * sc - c * ss)
            w = chain.C[k] * dphi[k] * (dal[k] - dbe[k])
            sc += w * c
            ss += w * s
            ga = W[k, W_GA]
            Kt = chain.Kt[k]
            tn = W[k, W_TN]
            W[k, W_FP] += extra.rest_phi[k] - W[k, W_GP] - 2.0 * cor - tau[k] + tn
            W[k, W_FA] = -ga - tau[k] - Kt * (al[k] + 0.5 * be[k]) + extra.rest_alpha[k]
            W[k, W_FB] = ga + tn - Kt * (0.5 * al[k] + be[k]) + extra.rest_beta[k]
            if grav:
                gp = chain.C[k] * (c * gy - s * gx)
                W[k, W_FA] += gp
                W[k, W_FB] -= gp
                W[k, W_FP] -= chain.C[k] * (c * gx + s * gy) * (al[k] - be[k])
    if chain.base[B_MODE] == MODE_FREE:
        _base_forces(True, chain, extra, W, dphi, dal, dbe, tau)
    _stop_moments(phi, dphi, chain, extra, W)
    if not chain_solve(KIND_FULL, chain, extra, W):
        _fill_nan(out)
        return
    for k in range(3 * n):
        out[k] = y[dof + k]
    for k in range(n):
        out[dof + k] = W[k, W_X]
        out[dof + n + k] = W[k, W_A]
        out[dof + 2 * n + k] = W[k, W_B]
    _finish_base(i0, dof, y, extra, out)


@njit(inline="always")
def inertia_columns(full, chain, W, V, VA, VB, FP, FA, FB, vb, fb, cps, sps):
    """Columns FP, FA, FB of W (n, ncol) = the inertia blocks times the velocity columns V, VA,
    VB, in O(n): FP = m^{pp} V + m^{pa} VA + m^{pb} VB, FA = m^{ap} V + m^{aa} VA + m^{ab} VB,
    FB likewise, with cos, sin of the rod angles in columns W_C, W_S. ``full`` False: only FP
    = m^{pp} V (VA, VB, FA, FB unused). The output columns must differ from the input ones.
    A free base (Chain.base[B_NB] > 0): ``vb`` (4,) its velocity-like column (x_B, y_B, psi,
    theta_w), entering every chain through its node 0 (z_0 = J^T (v_B + psi' J R a)); the
    base rows of M v go to ``fb`` (4,) (cps, sps: cos, sin of the base's angle)."""
    seg = chain.seg
    b = chain.base
    nb = int(b[B_NB])
    if nb > 0:
        mB = b[B_MASS]
        rcx = cps * b[B_CX] - sps * b[B_CY]
        rcy = sps * b[B_CX] + cps * b[B_CY]
        ecx = -rcy
        ecy = rcx
        vcx = vb[0] + vb[2] * ecx
        vcy = vb[1] + vb[2] * ecy
        fb[0] = mB * vcx
        fb[1] = mB * vcy
        fb[2] = b[B_INERTIA] * vb[2] + mB * (ecx * vcx + ecy * vcy)
        fb[3] = 0.0
        if nb > 3:
            fb[3] = b[B_WHEEL] * (vb[2] + vb[3])
            fb[2] += fb[3]
    for ci in range(seg.shape[0] - 1):
        k0 = seg[ci]
        k1 = seg[ci + 1]
        zx = 0.0
        zy = 0.0
        if nb > 0:
            rax = cps * chain.attach[ci, 0] - sps * chain.attach[ci, 1]
            ray = sps * chain.attach[ci, 0] + cps * chain.attach[ci, 1]
            v0x = vb[0] - vb[2] * ray
            v0y = vb[1] + vb[2] * rax
            zx = zx + v0y
            zy = zy - v0x
        for k in range(k0, k1):
            c = W[k, W_C]
            s = W[k, W_S]
            v = W[k, V]
            ez = c * zx + s * zy                # e_k . (z_0 + sum_{j<k} l_j e_j v_j)
            W[k, FP] = chain.Akk[k] * v + chain.l[k] * chain.Mt[k] * ez
            if full:
                va = W[k, VA]
                vb_ = W[k, VB]
                W[k, FP] += chain.c30[k] * va - chain.c20[k] * vb_
                W[k, FA] = chain.C[k] * ez + chain.c30[k] * v + chain.c105[k] * va \
                    - chain.c140[k] * vb_
                W[k, FB] = -chain.C[k] * ez - chain.c20[k] * v - chain.c140[k] * va \
                    + chain.c105[k] * vb_
            zx += chain.l[k] * c * v
            zy += chain.l[k] * s * v
        rx = 0.0
        ry = 0.0
        for k in range(k1 - 1, k0 - 1, -1):
            c = W[k, W_C]
            s = W[k, W_S]
            W[k, FP] += chain.l[k] * (c * rx + s * ry)
            w = chain.l[k] * chain.Mt[k] * W[k, V]
            if full:
                w += chain.C[k] * (W[k, VA] - W[k, VB])
            rx += w * c
            ry += w * s
        if nb > 0:
            Mc = chain.Mc[ci]
            fx = Mc * v0x - ry                  # the chain's momentum: Mc v_0 + J R
            fy = Mc * v0y + rx
            fb[0] += fx
            fb[1] += fy
            fb[2] += -ray * fx + rax * fy


@njit
def mass_times(kind, phi, v, va, vb, chain, out, out_a, out_b, vbase, out_base, psi):
    """out = m^{pp} v + m^{pa} va + m^{pb} vb, out_a = m^{ap} v + m^{aa} va + m^{ab} vb,
    out_b likewise (each (n,)) in O(n): the inertia blocks times velocities (kind
    KIND_REDUCED: only out = m^{pp} v; va, vb ignored); a free base: its velocities
    ``vbase`` (4,) and its rows ``out_base`` (4,) at the base angle psi [rad]."""
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
    inertia_columns(full, chain, W, 2, 3, 4, 5, 6, 7, vbase, out_base, math.cos(psi),
                    math.sin(psi))
    for k in range(n):
        out[k] = W[k, 5]
        if full:
            out_a[k] = W[k, 6]
            out_b[k] = W[k, 7]


def inertia_times(kind, chain, phi, v, psi=0.0) -> np.ndarray:
    """M v (3n + nb,) [for the full kind; the reduced kind fills only the first n and the base
    rows] at rod angles phi (n,) [rad] and base angle psi [rad] for velocities v: (n + nb,)
    [phi', base'] or (3n + nb,) [phi', alpha', beta', base'] (nb = the free base's
    coordinates), O(n). The slope parts are ignored by the reduced kind."""
    phi = np.ascontiguousarray(phi, dtype=float)
    n = phi.shape[0]
    nb = int(chain.base[B_NB])
    v = np.asarray(v, dtype=float)
    vv = np.zeros(3 * n)
    vb = np.zeros(4)
    vv[:v.shape[0] - nb] = v[:v.shape[0] - nb]
    vb[:nb] = v[v.shape[0] - nb:]
    out = np.zeros(3 * n + nb)
    ob = np.zeros(4)
    mass_times(kind, phi, vv[:n], vv[n:2 * n], vv[2 * n:], chain, out[:n], out[n:2 * n],
               out[2 * n:3 * n], vb, ob, float(psi))
    out[3 * n:] = ob[:nb]
    return out


@njit
def solve_with(kind, phi, chain, extra, fp, fa, fb, out, out_a, out_b, fbase, out_base, psi):
    """The kernels' solve with given right-hand sides (n,) each: the model's accelerations
    (reduced: phi'' and the slopes) for the generalized forces fp, fa, fb, and a free base's
    rows ``fbase`` (4,) -> its accelerations ``out_base`` (4,), at base angle psi (a fixed or
    prescribed base does not move in this solve). False if singular."""
    n = phi.shape[0]
    W = extra.work
    bk = extra.bk
    for i in range(bk.shape[0]):
        bk[i] = 0.0
    bk[BK_PSI] = psi
    bk[BK_COS] = math.cos(psi)
    bk[BK_SIN] = math.sin(psi)
    bk[BK_FX] = fbase[0]
    bk[BK_FY] = fbase[1]
    bk[BK_FPSI] = fbase[2]
    bk[BK_FTH] = fbase[3]
    for k in range(n):
        W[k, W_C] = math.cos(phi[k])
        W[k, W_S] = math.sin(phi[k])
        W[k, W_FP] = fp[k]
        W[k, W_FA] = fa[k]
        W[k, W_FB] = fb[k]
        W[k, W_G] = 0.0                     # the inertia structure only (no gravity term)
    if not chain_solve(kind, chain, extra, W):
        return False
    for k in range(n):
        out[k] = W[k, W_X]
        out_a[k] = W[k, W_A]
        out_b[k] = W[k, W_B]
    out_base[0] = bk[BK_AX]
    out_base[1] = bk[BK_AY]
    out_base[2] = bk[BK_APSI]
    out_base[3] = bk[BK_ATH]
    return True
