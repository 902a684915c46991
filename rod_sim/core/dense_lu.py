"""Dense LU with partial pivoting, real or complex (LAPACK getrf layout), compiled.

Used by :mod:`rod_sim.core.radau` for its Newton matrices (the right-hand sides themselves
never form an n x n matrix: :mod:`rod_sim.core.kernels`)."""
from __future__ import annotations

from .jit import njit


@njit(inline="always")
def _pivot(A, col):
    """(row of the largest |A[r, col]| for r >= col, that value): partial pivoting."""
    piv = col
    best = abs(A[col, col])
    for r in range(col + 1, A.shape[0]):
        v = abs(A[r, col])
        if v > best:
            best = v
            piv = r
    return piv, best


@njit(inline="always")
def lu_inplace(A, piv):
    """LU factorisation with partial pivoting of A (n, n), float64 or complex128, in place
    (LAPACK's getrf layout: unit-lower L below the diagonal, U on and above; rows swapped
    whole, piv[k] (n,) int64 = the row swapped with k at step k). Returns False for a zero
    pivot. (real and complex)."""
    n = A.shape[0]
    for col in range(n):
        p, best = _pivot(A, col)
        piv[col] = p
        if best == 0.0:
            return False
        if p != col:
            for c2 in range(n):
                tmp = A[col, c2]
                A[col, c2] = A[p, c2]
                A[p, c2] = tmp
        inv = 1.0 / A[col, col]
        # row slices (contiguous 1-D views) let LLVM vectorise the update (see solve_inplace)
        pivot_row = A[col, col + 1:]
        for r in range(col + 1, n):
            f = A[r, col] * inv
            A[r, col] = f
            row = A[r, col + 1:]
            for c2 in range(pivot_row.shape[0]):
                row[c2] -= f * pivot_row[c2]
    return True


@njit(inline="always")
def lu_solve(LU, piv, b):
    """Solve A x = b (b (n,), float64 or complex128) with the factors LU (n, n), piv (n,) of
    :func:`lu_inplace`; x overwrites b. The row swaps are applied first (the factors' L rows
    were swapped whole), then the two triangular solves."""
    n = b.shape[0]
    for i in range(n):
        p = piv[i]
        if p != i:
            tmp = b[i]
            b[i] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= LU[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= LU[i, j] * b[j]
        b[i] = acc / LU[i, i]


