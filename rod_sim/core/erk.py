"""Compiled explicit Runge-Kutta drivers: adaptive DOP853 with dense output, and fixed-step
methods given by a Butcher tableau.

Both integrate a whole output grid in one compiled call, restarting at load breakpoints
(where a scripted force or its derivatives jump), so their accuracy is not spoiled by the
forcing. ``rhs`` is any kernel of :mod:`rod_sim.core.kernels`.

Status codes returned: 0 success, 1 step size underflow, 2 too many steps, 3 non-finite state.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop

from .jit import njit

STATUS_OK, STATUS_STEP_UNDERFLOW, STATUS_MAX_STEPS, STATUS_NONFINITE = 0, 1, 2, 3
STATUS_TEXT = {
    STATUS_OK: "ok",
    STATUS_STEP_UNDERFLOW: "step size fell below the minimum (the solution is not smooth "
                           "enough or it diverges)",
    STATUS_MAX_STEPS: "too many steps",
    STATUS_NONFINITE: "the state became non-finite (NaN/Inf)",
}

# Dormand-Prince 8(5,3) coefficients, Hairer's DOP853, as shipped by scipy.
N_STAGES = _dop.N_STAGES
A_DOP = np.ascontiguousarray(_dop.A)
B_DOP = np.ascontiguousarray(_dop.B)
C_DOP = np.ascontiguousarray(_dop.C)
E3_DOP = np.ascontiguousarray(_dop.E3)
E5_DOP = np.ascontiguousarray(_dop.E5)
D_DOP = np.ascontiguousarray(_dop.D)


@njit
def _rms(x, scale):
    acc = 0.0
    for i in range(x.shape[0]):
        v = x[i] / scale[i]
        acc += v * v
    return np.sqrt(acc / x.shape[0])


@njit
def _all_finite(y):
    for i in range(y.shape[0]):
        if not np.isfinite(y[i]):
            return False
    return True


@njit
def _initial_step(rhs, chain, extra, loads, held, t_side, t0, y0, f0, t_bound, rtol, atol, stats):
    """Hairer's starting step (Solving ODEs I, II.4), as scipy's select_initial_step."""
    n = y0.shape[0]
    scale = atol + np.abs(y0) * rtol
    d0 = _rms(y0, scale)
    d1 = _rms(f0, scale)
    length = t_bound - t0
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, length)
    if not h0 > 0.0:   # f0 infinite or NaN: no usable step; the caller reports underflow
        return 0.0
    y1 = y0 + h0 * f0
    f1 = np.empty(n)
    rhs(t0 + h0, y1, chain, extra, loads, held, t_side, f1)
    stats[0] += 1
    d2 = _rms(f1 - f0, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, length)


@njit
def dop853_run(rhs, chain, extra, loads, held, y0, t0, t_out, breaks, rtol, atol, h_init,
               max_step, max_steps, Y_out, stats):
    """Integrate from (t0, y0) through every time of ``t_out`` (sorted, > t0 or == t0).

    ``breaks`` (sorted) are times where the forcing jumps: steps end exactly there.
    Writes y(t_out[i]) into Y_out[i]. ``stats`` = [rhs evaluations, accepted steps,
    rejected steps] is accumulated. ``h_init`` <= 0 selects the first step automatically.
    Returns (y_end, t_end, h_next, status).
    """
    n = y0.shape[0]
    n_out = t_out.shape[0]
    t_final = t_out[n_out - 1]
    K = np.empty((16, n))
    F = np.empty((7, n))
    y = y0.copy()
    t = t0
    i_out = 0
    while i_out < n_out and t_out[i_out] <= t0:
        Y_out[i_out, :] = y0
        i_out += 1
    if i_out == n_out:
        return y, t, h_init, STATUS_OK
    h = h_init
    n_steps = 0
    safety = 0.9
    min_factor = 0.2
    max_factor = 10.0
    exponent = -1.0 / 8.0
    f = np.empty(n)
    y_new = np.empty(n)
    f_new = np.empty(n)
    yy = np.empty(n)
    scale = np.empty(n)
    while t < t_final:
        # end of the current smooth segment
        seg_end = t_final
        for b in breaks:
            if b > t + 1e-12 * max(1.0, abs(t)):
                if b < seg_end:
                    seg_end = b
                break
        t_side = 0.5 * (t + seg_end)
        rhs(t, y, chain, extra, loads, held, t_side, f)
        stats[0] += 1
        if h <= 0.0:
            h = _initial_step(rhs, chain, extra, loads, held, t_side, t, y, f, seg_end,
                              rtol, atol, stats)
        rejected = False
        while t < seg_end:
            h = min(h, max_step)
            min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
            if h < min_step:
                return y, t, h, STATUS_STEP_UNDERFLOW
            t_new = t + h
            if t_new >= seg_end - 1e-14 * max(1.0, abs(seg_end)):
                t_new = seg_end
            hs = t_new - t
            # stages
            K[0, :] = f
            for s in range(1, N_STAGES):
                for i in range(n):
                    acc = 0.0
                    for r in range(s):
                        acc += A_DOP[s, r] * K[r, i]
                    yy[i] = y[i] + hs * acc
                rhs(t + C_DOP[s] * hs, yy, chain, extra, loads, held, t_side, K[s])
            for i in range(n):
                acc = 0.0
                for r in range(N_STAGES):
                    acc += B_DOP[r] * K[r, i]
                y_new[i] = y[i] + hs * acc
            rhs(t_new, y_new, chain, extra, loads, held, t_side, f_new)
            K[N_STAGES, :] = f_new
            stats[0] += N_STAGES
            if not _all_finite(y_new) or not _all_finite(f_new):
                err_norm = np.inf
            else:
                e5 = 0.0
                e3 = 0.0
                for i in range(n):
                    sc = atol + max(abs(y[i]), abs(y_new[i])) * rtol
                    a5 = 0.0
                    a3 = 0.0
                    for r in range(N_STAGES + 1):
                        a5 += E5_DOP[r] * K[r, i]
                        a3 += E3_DOP[r] * K[r, i]
                    a5 /= sc
                    a3 /= sc
                    e5 += a5 * a5
                    e3 += a3 * a3
                if e5 == 0.0 and e3 == 0.0:
                    err_norm = 0.0
                else:
                    err_norm = hs * e5 / np.sqrt((e5 + 0.01 * e3) * n)
            if not err_norm < 1.0:
                stats[2] += 1
                if np.isfinite(err_norm):
                    h = hs * max(min_factor, safety * err_norm ** exponent)
                else:
                    h = hs * min_factor
                rejected = True
                continue
            # accepted
            stats[1] += 1
            n_steps += 1
            if err_norm == 0.0:
                factor = max_factor
            else:
                factor = min(max_factor, safety * err_norm ** exponent)
            if rejected:
                factor = min(1.0, factor)
            rejected = False
            h_next = hs * factor
            # dense output for the output times inside (t, t_new]
            if i_out < n_out and t_out[i_out] <= t_new:
                if t_out[i_out] < t_new:
                    for s in range(N_STAGES + 1, 16):
                        for i in range(n):
                            acc = 0.0
                            for r in range(s):
                                acc += A_DOP[s, r] * K[r, i]
                            yy[i] = y[i] + hs * acc
                        rhs(t + C_DOP[s] * hs, yy, chain, extra, loads, held, t_side, K[s])
                    stats[0] += 16 - N_STAGES - 1
                    for i in range(n):
                        dy = y_new[i] - y[i]
                        F[0, i] = dy
                        F[1, i] = hs * K[0, i] - dy
                        F[2, i] = 2.0 * dy - hs * (f_new[i] + K[0, i])
                        for d in range(4):
                            acc = 0.0
                            for r in range(16):
                                acc += D_DOP[d, r] * K[r, i]
                            F[3 + d, i] = hs * acc
                while i_out < n_out and t_out[i_out] <= t_new:
                    if t_out[i_out] == t_new:
                        Y_out[i_out, :] = y_new
                    else:
                        x = (t_out[i_out] - t) / hs
                        for i in range(n):
                            v = 0.0
                            for j in range(7):
                                v += F[6 - j, i]
                                if j % 2 == 0:
                                    v *= x
                                else:
                                    v *= 1.0 - x
                            Y_out[i_out, i] = v + y[i]
                    i_out += 1
            t = t_new
            y[:] = y_new
            f[:] = f_new
            h = h_next
            if not _all_finite(y):
                return y, t, h, STATUS_NONFINITE
            if n_steps >= max_steps:
                return y, t, h, STATUS_MAX_STEPS
    return y, t, h, STATUS_OK


@njit
def fixed_run(rhs, chain, extra, loads, held, y0, t0, t_out, breaks, h_max, A, b, c,
              Y_out, stats):
    """Fixed-step explicit Runge-Kutta with tableau (A, b, c).

    Every interval between consecutive output times and breakpoints is split into
    ceil(length / h_max) equal steps, so outputs and breakpoints are hit exactly.
    Returns (y_end, t_end, status)."""
    n = y0.shape[0]
    ns = b.shape[0]
    K = np.empty((ns, n))
    yy = np.empty(n)
    y = y0.copy()
    t = t0
    n_out = t_out.shape[0]
    i_out = 0
    while i_out < n_out and t_out[i_out] <= t0:
        Y_out[i_out, :] = y0
        i_out += 1
    while i_out < n_out:
        target = t_out[i_out]
        for bk in breaks:
            if bk > t + 1e-12 * max(1.0, abs(t)) and bk < target:
                target = bk
                break
        t_side = 0.5 * (t + target)
        n_sub = int(np.ceil((target - t) / h_max - 1e-9))
        if n_sub < 1:
            n_sub = 1
        hs = (target - t) / n_sub
        t_start = t
        for step in range(n_sub):
            ts = t_start + step * hs
            for s in range(ns):
                for i in range(n):
                    acc = 0.0
                    for r in range(s):
                        acc += A[s, r] * K[r, i]
                    yy[i] = y[i] + hs * acc
                rhs(ts + c[s] * hs, yy, chain, extra, loads, held, t_side, K[s])
            stats[0] += ns
            for i in range(n):
                acc = 0.0
                for r in range(ns):
                    acc += b[r] * K[r, i]
                y[i] += hs * acc
            stats[1] += 1
            if not _all_finite(y):
                return y, ts + hs, STATUS_NONFINITE
        t = target
        while i_out < n_out and t_out[i_out] <= t:
            Y_out[i_out, :] = y
            i_out += 1
    return y, t, STATUS_OK


# Module-level entry points, one per model kernel. Passing a kernel as an argument from
# Python would make numba compile (and never cache) a new specialisation in every process;
# these wrappers take only arrays, so their machine code is cached on disk.
from . import kernels as _k  # noqa: E402


@njit
def _dop853_rigid(chain, extra, loads, held, y0, t0, t_out, breaks, rtol, atol, h_init,
                  max_step, max_steps, Y_out, stats):
    return dop853_run(_k.rigid_rhs, chain, extra, loads, held, y0, t0, t_out, breaks, rtol,
                      atol, h_init, max_step, max_steps, Y_out, stats)


@njit
def _dop853_reduced(chain, extra, loads, held, y0, t0, t_out, breaks, rtol, atol, h_init,
                    max_step, max_steps, Y_out, stats):
    return dop853_run(_k.reduced_rhs, chain, extra, loads, held, y0, t0, t_out, breaks, rtol,
                      atol, h_init, max_step, max_steps, Y_out, stats)


@njit
def _dop853_full(chain, extra, loads, held, y0, t0, t_out, breaks, rtol, atol, h_init,
                 max_step, max_steps, Y_out, stats):
    return dop853_run(_k.full_rhs, chain, extra, loads, held, y0, t0, t_out, breaks, rtol,
                      atol, h_init, max_step, max_steps, Y_out, stats)


@njit
def _fixed_rigid(chain, extra, loads, held, y0, t0, t_out, breaks, h_max, A, b, c, Y_out, stats):
    return fixed_run(_k.rigid_rhs, chain, extra, loads, held, y0, t0, t_out, breaks, h_max,
                     A, b, c, Y_out, stats)


@njit
def _fixed_reduced(chain, extra, loads, held, y0, t0, t_out, breaks, h_max, A, b, c, Y_out,
                   stats):
    return fixed_run(_k.reduced_rhs, chain, extra, loads, held, y0, t0, t_out, breaks, h_max,
                     A, b, c, Y_out, stats)


@njit
def _fixed_full(chain, extra, loads, held, y0, t0, t_out, breaks, h_max, A, b, c, Y_out, stats):
    return fixed_run(_k.full_rhs, chain, extra, loads, held, y0, t0, t_out, breaks, h_max,
                     A, b, c, Y_out, stats)


DOP853 = {"rigid": _dop853_rigid, "reduced": _dop853_reduced, "full": _dop853_full}
FIXED = {"rigid": _fixed_rigid, "reduced": _fixed_reduced, "full": _fixed_full}
