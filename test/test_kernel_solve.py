"""The kernels' small solve and the tip-hinge moments, against plain-Python oracles, bit for bit.

:func:`rod_sim.core.kernels._solve3` (elimination in local variables, :func:`_factor3` and
:func:`_subst3`, which the tip-to-root sweep uses rod by rod) must do the operations of
row-wise Gaussian elimination with partial pivoting of [E | G] in the same order: the
trajectories are reproducible bit for bit across this rewrite (test/trajectory_dump.py), so
any reordering shows here as a differing bit. :func:`_tip_moments` gives each rod the moment
of the hinge at its tip, zero at a chain's last rod."""
from __future__ import annotations

import numpy as np

from rod_sim.core import kernels


def rowwise_solve3(E, G, ncol):
    """The elimination the kernels did with arrays before: [E | G] row by row, partial
    pivoting, rows exchanged whole, multipliers that are exactly zero skipped."""
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
            E[[col, piv], :] = E[[piv, col], :]
            G[[col, piv], :ncol] = G[[piv, col], :ncol]
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


def systems(rng, count):
    """Random 3 x 3 systems over 7 decades, with exact zeros (skipped multipliers), pivots
    that need exchanges, zero columns and singular matrices mixed in."""
    for i in range(count):
        E = rng.standard_normal((3, 3)) * 10.0 ** rng.integers(-3, 4, (3, 3))
        if i % 5 == 0:
            E[rng.integers(3), rng.integers(3)] = 0.0
        if i % 7 == 0:
            E[0, 0] = 0.0                       # row exchange forced
        if i % 11 == 0:
            E[:, rng.integers(3)] = 0.0         # singular
        if i % 13 == 0:
            E[2] = E[0] * 2.0                   # singular after elimination
        G = rng.standard_normal((3, 5)) * 10.0 ** rng.integers(-3, 4, (3, 5))
        if i % 3 == 0:
            G[:, 4] = 0.0
        yield E, G


def test_solve3_matches_rowwise_elimination_bit_for_bit():
    rng = np.random.default_rng(26)
    singular = 0
    for E, G in systems(rng, 3000):
        for ncol in (1, 5):
            want_G = G.copy()
            ok_want = rowwise_solve3(E.copy(), want_G, ncol)
            got_G = G.copy()
            ok = kernels._solve3(E.copy(), got_G, ncol)
            assert ok == ok_want
            if ok:
                # same bits, including the sign of zeros
                assert np.array_equal(got_G.view(np.int64), want_G.view(np.int64)), (E, G)
            else:
                singular += 1
    assert singular > 100                       # the singular cases were exercised


def test_tip_moments_per_chain():
    # three chains of 3, 1 and 2 rods: the last rod of each has no hinge at its tip
    n = 6
    chain = kernels.make_chain(*(np.ones(n),) * 6, seg=[0, 3, 4, 6])
    tau = np.arange(1.0, n + 2.0)               # (n + 1,), tau[n] = 7 is never a tip's
    W = np.full((n, kernels.N_WORK), np.nan)
    kernels._tip_moments(chain, tau, W)
    assert W[:, kernels.W_TN].tolist() == [2.0, 3.0, 0.0, 0.0, 6.0, 0.0]
