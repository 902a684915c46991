"""The full model linearized about a configuration at rest: stiffness K, inertia M and the
shifted solves (M + s K)^{-1} that eigenvalue searches need, all in O(n).

Coordinates x = [phi, alpha, beta] (3n,). K is the constant elastic stiffness of (9)-(10):
the hinge springs, sum_h kappa_h d_h d_h^T with d_h = dDelta_h/dx (+1 on phi_h and alpha_h,
-1 on phi_{h-1} and beta_{h-1}), and the rods' bending, Kt_k [[1, 1/2], [1/2, 1]] on
(alpha_k, beta_k). The geometric terms of a prestressed configuration (hinge moments times
dM/dphi) and the stop contacts are left out. M is the paper's inertia matrix at phi
(:func:`rod_sim.core.kernels.mass_times`). (M + s K) x = f is solved by the kernels' chain
solve with every sprung hinge as a compliant constraint (compliance -1/(s kappa_h)) and the
bending stiffness folded into each rod's 2 x 2 bending block.
"""
from __future__ import annotations

import math

import numpy as np

from . import kernels

DENSE_UP_TO = 24
"""Up to this many coordinates the eigenproblem is solved densely (exactly, every mode)."""
MAX_ARNOLDI = 30
"""Restarts of ARPACK's Lanczos iteration per shift (its ``maxiter``): bounds the number of
O(n) solves (measured: 85 at n = 128, 259 at n = 2048 for the uniform chain)."""


def stiffness_times(model, v: np.ndarray) -> np.ndarray:
    """K v (3n,) [N m] for v (3n,) (model: a FullModel)."""
    n = model.n
    ch = model.chain
    phi, al, be = v[:n], v[n:2 * n], v[2 * n:]
    first = np.asarray(ch.prev) < 0                 # each chain's hinge 0 (on the base)
    left = np.concatenate([[0.0], phi[:-1] + be[:-1]])
    left[first] = 0.0
    delta = phi + al - left
    tau = ch.kappa * delta
    tau_next = np.append(tau[1:], 0.0)
    tau_next[np.append(first[1:], True)] = 0.0
    out = np.empty(3 * n)
    out[:n] = tau - tau_next
    out[n:2 * n] = tau + ch.Kt * (al + 0.5 * be)
    out[2 * n:] = -tau_next + ch.Kt * (0.5 * al + be)
    return out


def _clamped(chain):
    """The chains on a base held still: the bending modes here are those of the chains on a
    fixed base (a moving base's coordinates are left out of the linearization)."""
    return chain._replace(base=np.zeros(kernels.N_BASE))


def mass_times(model, phi: np.ndarray, v: np.ndarray) -> np.ndarray:
    """M v (3n,) at rod angles phi (n,) for v (3n,) (the base held still)."""
    return kernels.inertia_times(kernels.KIND_FULL, _clamped(model.chain), phi, v)


def shifted_solver(model, phi: np.ndarray, s: float):
    """f (3n,) -> x (3n,) with (M(phi) + s K) x = f on the constraint set (locked hinges, rigid
    rods), O(n) per call."""
    n = model.n
    ch = model.chain
    sc = model.scene
    locked = np.asarray(sc.hinge_locked, dtype=bool)
    sprung = (ch.kappa > 0.0) & ~locked
    comp = np.zeros(n)
    comp[sprung] = -1.0 / (s * ch.kappa[sprung])
    chain = _clamped(ch)._replace(c105=ch.c105 + s * ch.Kt, c140=ch.c140 - 0.5 * s * ch.Kt,
                                  kappa=np.zeros(n), kappa_tip=np.zeros(n))
    extra = kernels.make_extra(np.zeros((3, n)), np.zeros((4, n)), np.zeros(n),
                               locked | sprung, np.asarray(sc.rod_rigid, dtype=bool), comp,
                               kind=kernels.KIND_FULL, nchains=len(ch.seg) - 1)
    phi = np.ascontiguousarray(phi, dtype=float)

    def solve(f):
        f = np.asarray(f, dtype=float)
        x = np.empty(3 * n)
        ok = kernels.solve_with(kernels.KIND_FULL, phi, chain, extra, np.ascontiguousarray(f[:n]),
                                np.ascontiguousarray(f[n:2 * n]), np.ascontiguousarray(f[2 * n:]),
                                x[:n], x[n:2 * n], x[2 * n:], np.zeros(4), np.zeros(4), 0.0)
        if not ok:
            raise np.linalg.LinAlgError("singular shifted stiffness")
        return x

    return solve


def _bending_share(model, phi, vec) -> float:
    """Fraction of a mode's kinetic energy (v^T M v) in its alpha, beta part."""
    n = model.n
    total = float(vec @ mass_times(model, phi, vec))
    b = vec.copy()
    b[:n] = 0.0
    bend = float(b @ mass_times(model, phi, b))
    return bend / total if total > 0 else 0.0


def lowest_bending_mode(model, phi: np.ndarray, guess_omega: float) -> float:
    """Lowest angular frequency omega [rad/s] of K x = omega^2 M x (free coordinates: locked
    hinges and rigid rods constrained) whose mode has more than half of its kinetic energy in
    the bending slopes; inf if there is none. Small chains: every mode (dense); long ones:
    shift-invert Lanczos (scipy's eigsh, ARPACK, tolerance 1e-3) on the O(n) operators with
    the shift at 0.9 ``guess_omega`` [rad/s]: the lowest bending-dominated mode among the 4
    modes nearest to the shift, the shift moved up 2x in omega^2 while none is (without
    convergence within :data:`MAX_ARNOLDI` restarts: the converged modes, else the guess). The lowest
    chord-fixed rod frequency is the guess: the chain's bending modes cluster just below it
    (within 1 % on the shipped scenes), and a shift between the hinge modes (far lower) and
    that cluster finds the cluster's bottom in a few dozen O(n) solves; a bending mode more
    than ~2x below the guess would be missed."""
    n = model.n
    d = 3 * n
    free = _free_coordinates(model)
    if free.size <= DENSE_UP_TO:
        return _dense_lowest(model, phi, free)
    from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh  # ~0.3 s

    sigma = (0.9 * guess_omega) ** 2
    M = LinearOperator((d, d), matvec=lambda v: mass_times(model, phi, v), dtype=float)
    K = LinearOperator((d, d), matvec=lambda v: stiffness_times(model, v), dtype=float)
    k = min(4, free.size - 2)
    for _ in range(12):
        solve = shifted_solver(model, phi, -1.0 / sigma)
        opinv = LinearOperator((d, d), matvec=lambda b, solve=solve, sigma=sigma:
                               -solve(b) / sigma, dtype=float)
        try:
            w2, vecs = eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=opinv,
                             v0=np.ones(d), tol=1e-3, maxiter=MAX_ARNOLDI)
        except ArpackNoConvergence as exc:
            w2, vecs = exc.eigenvalues, exc.eigenvectors
            if w2.size == 0:
                return guess_omega
        for i in np.argsort(w2):
            if w2[i] > 0 and _bending_share(model, phi, vecs[:, i]) > 0.5:
                return math.sqrt(w2[i])
        sigma = 2.0 * max(sigma, float(np.max(w2)))
    return math.inf


def _free_coordinates(model) -> np.ndarray:
    """Indices of the coordinates a rigid rod does not pin (its slopes are constrained)."""
    n = model.n
    rigid = np.asarray(model.scene.rod_rigid, dtype=bool)
    keep = np.ones(3 * n, dtype=bool)
    keep[n:2 * n][rigid] = False
    keep[2 * n:][rigid] = False
    return np.flatnonzero(keep)


def _dense_lowest(model, phi, free) -> float:
    """Small chains: every mode of the constrained problem densely (locked hinges removed
    through a null-space basis)."""
    from scipy.linalg import eigh, null_space

    n = model.n
    d = 3 * n
    eye = np.eye(d)
    M = np.column_stack([mass_times(model, phi, eye[i]) for i in range(d)])
    K = np.column_stack([stiffness_times(model, eye[i]) for i in range(d)])
    rows = []
    for h in np.flatnonzero(np.asarray(model.scene.hinge_locked, dtype=bool)):
        r = np.zeros(d)
        r[h] = r[n + h] = 1.0
        if h > 0:
            r[h - 1] = r[2 * n + h - 1] = -1.0
        rows.append(r)
    for i in set(range(d)) - set(free.tolist()):
        r = np.zeros(d)
        r[i] = 1.0
        rows.append(r)
    T = null_space(np.array(rows)) if rows else eye
    if T.shape[1] == 0:
        return math.inf
    w2, vecs = eigh(T.T @ K @ T, T.T @ M @ T)
    for i in np.argsort(w2):
        v = T @ vecs[:, i]
        if w2[i] > 0 and _bending_share(model, phi, v) > 0.5:
            return math.sqrt(w2[i])
    return math.inf
