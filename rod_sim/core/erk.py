"""Compiled explicit Runge-Kutta drivers: adaptive DOP853 with dense output, and fixed-step
methods given by a Butcher tableau.

Both integrate a whole output grid in one compiled call, restarting at load breakpoints
(where a scripted force or its derivatives jump), so their accuracy is not spoiled by the
forcing. ``rhs`` is any kernel of :mod:`rod_sim.core.kernels`.

Event location (hinge latches and stop contacts, :mod:`rod_sim.core.hinges`): ``events`` =
(hinge (m,), angle (m,), kind (m,), other (m,), ground (N_MOTION,), t_buf (cap,), code_buf
(cap,), y_buf (cap, size), count (1,)), :class:`~rod_sim.core.kernels.Events`. After every
accepted step the event functions g_e = theta_{hinge_e}(t, y) - angle_e are compared at the
step's ends (theta = y[hinge] - y[other]; at a hinge 0 on the base, other = -1, y[hinge]
less the prescribed part p(t) of a prescribed base's angle, :func:`kernels.ground_angle`,
so that the function depends on time too; p = 0 for a fixed base); a sign change is
bracketed on the step and its root found on the step's interpolant (DOP853: its 7th-order
dense output; fixed-step methods: the cubic Hermite interpolant of the step's end values
and slopes) by the Illinois method to |dt| <= 4 eps max(1, |t|) (a few 1e-16 s). Every
event changes the mode (a latch locks the hinge, a stop crossing switches its contact law on
or off, so that no step straddles the contact's jump in acceleration): the driver stops
exactly at the earliest root (a latch first among equal roots), records it (t, code = 2 e +
rising, interpolated state) and returns STATUS_EVENT; the caller changes the mode and
restarts. A function that crosses twice within one step is not seen (as in scipy's
solve_ivp), except in the step that starts on the root of the crossing just handled: there
the interpolant is also sampled at x = 1/8 ... 7/8, so a hinge that leaves a stop and comes
back within that step is caught.

Status codes returned: 0 success, 1 step size underflow, 2 too many steps, 3 non-finite state,
4 a terminal event (stopped at it), 5 the event buffer is full (stopped after a step; drain it
and call again), 6 the call's work budget is used up (``budget`` right-hand side evaluations:
stopped after an accepted step, nothing lost; call again from the returned state, so that the
caller gets control back, e.g. for Ctrl-C, at bounded intervals), 7 the Newton iteration of an
implicit method failed too many times in a row (:mod:`rod_sim.core.radau`).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop

from .jit import njit
from .kernels import ground_angle

STATUS_OK, STATUS_STEP_UNDERFLOW, STATUS_MAX_STEPS, STATUS_NONFINITE = 0, 1, 2, 3
STATUS_EVENT, STATUS_EVENTS_FULL = 4, 5
STATUS_BUDGET, STATUS_NEWTON_FAILED = 6, 7
EV_LATCH = 0
STATUS_TEXT = {
    STATUS_OK: "ok",
    STATUS_STEP_UNDERFLOW: "step size fell below the minimum (the solution is not smooth "
                           "enough or it diverges)",
    STATUS_MAX_STEPS: "too many steps",
    STATUS_NONFINITE: "the state became non-finite (NaN/Inf)",
    STATUS_NEWTON_FAILED: "the Newton iteration failed to converge too many times in a row "
                          "(the scene is too stiff or not smooth for this integrator)",
}

# Dormand-Prince 8(5,3) coefficients, Hairer's DOP853, as shipped by scipy.
N_STAGES = _dop.N_STAGES
A_DOP = np.ascontiguousarray(_dop.A)
B_DOP = np.ascontiguousarray(_dop.B)
C_DOP = np.ascontiguousarray(_dop.C)
E3_DOP = np.ascontiguousarray(_dop.E3)
E5_DOP = np.ascontiguousarray(_dop.E5)
D_DOP = np.ascontiguousarray(_dop.D)
STIFF_H_LAMBDA = 6.1
"""Hairer's bound on DOP853's h |lambda| estimate (DOP853's stiffness detection, Hairer,
Norsett & Wanner, Solving ODEs I, section II.10): an accepted step above it was as long as the
method's stability allowed, not as its accuracy did."""


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


@njit(inline="always")
def _dense(F, y, x, i):
    """Component i of the step's interpolant at x = (t - t_step) / h in [0, 1]: F (7, size)
    in DOP853's nested form (a cubic Hermite when F[3:] = 0)."""
    v = 0.0
    for j in range(7):
        v += F[6 - j, i]
        if j % 2 == 0:
            v *= x
        else:
            v *= 1.0 - x
    return v + y[i]


@njit(inline="always")
def _theta(y, h, o, t, ground):
    """Rigid hinge angle theta_h of state y (phi first in every model's layout) at time t [s]
    [rad]: y[h] less the angle y[o] on the hinge's other side (o = -1: the ground, whose
    angle is p(t) of the profile ``ground`` (N_MOTION,): a prescribed base's psi less its
    psi_0, which the event's angle holds; 0 for a fixed base)."""
    return y[h] - y[o] if o >= 0 else y[h] - ground_angle(ground, t)


@njit(inline="always")
def _theta_dense(F, y, x, h, o, t, ground):
    """:func:`_theta` on the step's interpolant at x, t [s] the time there."""
    if o < 0:
        return _dense(F, y, x, h) - ground_angle(ground, t)
    return _dense(F, y, x, h) - _dense(F, y, x, o)


@njit
def _event_values(t, y, events, g):
    """g (m,) = the event functions at (t [s], y)."""
    ev_h = events.hinge
    ev_o = events.other
    ev_a = events.angle
    for e in range(ev_h.shape[0]):
        g[e] = _theta(y, ev_h[e], ev_o[e], t, events.ground) - ev_a[e]


@njit
def _illinois(F, y, h, o, a, x_lo, g_lo, g_hi, tol_x, t, hs, ground):
    """Root x in (x_lo, 1] of theta_h(x) - a on the interpolant of the step (t, t + hs] [s]
    (``ground``: see :func:`_theta`), g_lo = g(x_lo) and g_hi = g(1) of opposite signs (or
    g_hi = 0): the Illinois variant of regula falsi. Returns the end of the final bracket on
    the side of g_hi (the state there has crossed)."""
    if g_hi == 0.0:
        return 1.0
    x_hi = 1.0
    kept = 0
    x = 1.0
    for _ in range(200):
        x = (x_lo * g_hi - x_hi * g_lo) / (g_hi - g_lo)
        if not (x_lo < x < x_hi):
            x = 0.5 * (x_lo + x_hi)
        gx = _theta_dense(F, y, x, h, o, t + x * hs, ground) - a
        if gx == 0.0:
            return x
        if (gx > 0.0) == (g_hi > 0.0):
            x_hi, g_hi = x, gx
            if kept == -1:
                g_lo *= 0.5
            kept = -1
        else:
            x_lo, g_lo = x, gx
            if kept == 1:
                g_hi *= 0.5
            kept = 1
        if x_hi - x_lo <= tol_x:
            return x_hi
    return x_hi


@njit
def _on_root(g0, a):
    """The step starts on the event function's root (the crossing just handled)."""
    return abs(g0) <= 1e-12 * (1.0 + abs(a))


@njit
def _bracket(F, y, e, g0, g1, events, t, hs):
    """(x_lo, g(x_lo)) of a crossing of event e in the step (t, t + hs] [s], or (-1, 0): a
    sign change between the step's ends, or, for a step that starts on the function's root, a
    return across it seen at x = 1/8 ... 7/8 on the interpolant (leaving and coming back
    within the step)."""
    ev_h, ev_a = events.hinge, events.angle
    if (g0[e] < 0.0 and g1[e] >= 0.0) or (g0[e] > 0.0 and g1[e] <= 0.0):
        return 0.0, g0[e]
    if g1[e] == 0.0 or not _on_root(g0[e], ev_a[e]):
        return -1.0, 0.0
    x_lo, g_lo = -1.0, 0.0
    for k in range(1, 8):
        x = k / 8.0
        gk = _theta_dense(F, y, x, ev_h[e], events.other[e], t + x * hs, events.ground) \
            - ev_a[e]
        if gk * g1[e] < 0.0:
            x_lo, g_lo = x, gk
    return x_lo, g_lo


@njit
def _event_start(t, y, events):
    """(number of event functions m, their values at (t [s], y) (m,), scratch for the step's
    end (m,), capacity of the event buffer) at the start of a driver call."""
    m_ev = events.hinge.shape[0]
    g0 = np.empty(m_ev)
    _event_values(t, y, events, g0)
    return m_ev, g0, np.empty(m_ev), events.t.shape[0]


@njit
def _may_cross(g0, g1, events):
    """Whether a step with event values g0 -> g1 needs its interpolant for event location."""
    for e in range(g0.shape[0]):
        if (g0[e] < 0.0 and g1[e] >= 0.0) or (g0[e] > 0.0 and g1[e] <= 0.0):
            return True
        if _on_root(g0[e], events.angle[e]):
            return True
    return False


@njit
def _locate(F, y, t, hs, g0, g1, events):
    """Locate the earliest crossing of the event functions in the step (t, t + hs] with
    interpolant F (a latch first among equal roots; see :func:`_bracket`) and record it;
    returns its x in (0, 1], or -1 when nothing crossed."""
    ev_h, ev_a, ev_k, ev_o, ground, ev_t, ev_i, ev_y, ev_n = events
    tol_x = 4.0 * 2.220446049250313e-16 * max(1.0, abs(t) + abs(hs)) / hs
    x_stop = 2.0
    first = -1
    rising = 0
    for latch_pass in (True, False):
        for e in range(ev_h.shape[0]):
            if (ev_k[e] == EV_LATCH) != latch_pass:
                continue
            x_lo, g_lo = _bracket(F, y, e, g0, g1, events, t, hs)
            if x_lo < 0.0:
                continue
            x = _illinois(F, y, ev_h[e], ev_o[e], ev_a[e], x_lo, g_lo, g1[e], tol_x, t, hs,
                          ground)
            if x < x_stop:
                x_stop = x
                first = e
                rising = 1 if g1[e] > g_lo else 0
    if first < 0:
        return -1.0
    k = ev_n[0]
    ev_t[k] = t + x_stop * hs
    ev_i[k] = 2 * first + rising
    for i in range(y.shape[0]):
        ev_y[k, i] = _dense(F, y, x_stop, i)
    ev_n[0] = k + 1
    return x_stop


@njit
def _segment_end(breaks, t, t_end):
    """End [s] of the smooth segment from t [s]: the first of ``breaks`` (sorted times [s] where
    the forcing jumps) later than t by more than 1e-12 max(1, |t|), or ``t_end`` [s] if that
    comes first."""
    for b in breaks:
        if b > t + 1e-12 * max(1.0, abs(t)):
            return min(b, t_end)
    return t_end


@njit(inline="always")
def _combine(w, K, y, h, out):
    """out (size,) = y + h sum_r w[r] K[r] over the weights w (s,) and the first s stage
    derivatives of K (>= s, size); ``out`` may be ``y``."""
    for i in range(y.shape[0]):
        acc = 0.0
        for r in range(w.shape[0]):
            acc += w[r] * K[r, i]
        out[i] = y[i] + h * acc


@njit(inline="always")
def _hermite_form(y, y_new, f, f_new, h, F):
    """The cubic Hermite interpolant of a step of h [s] from (y, f) to (y_new, f_new) (size,)
    each, in DOP853's nested form: F[0:3] (of F (7, size)) as :func:`_dense` reads them."""
    for i in range(y.shape[0]):
        dy = y_new[i] - y[i]
        F[0, i] = dy
        F[1, i] = h * f[i] - dy
        F[2, i] = 2.0 * dy - h * (f_new[i] + f[i])


@njit
def _initial_step(rhs, problem, t_side, t0, y0, f0, t_bound, control, stats):
    """Hairer's starting step (Solving ODEs I, II.4), as scipy's select_initial_step, for
    ``rhs`` on ``problem`` from (t0, y0) with f0 = rhs(t0, y0), at most to ``t_bound`` [s],
    with the tolerances of ``control``."""
    chain, extra, loads, held = problem
    rtol, atol = control.rtol, control.atol
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
def dop853_run(rhs, problem, span, control, output):
    """Integrate ``rhs(t, y, chain, extra, loads, held, t_side, out)`` of ``problem``
    (:class:`~rod_sim.core.kernels.Problem`) over ``span`` (:class:`~rod_sim.core.kernels.Span`:
    from (t0, y0) through every time of ``t_out``, sorted, > t0 or == t0) with ``control``
    (:class:`~rod_sim.core.kernels.Control`) into ``output``
    (:class:`~rod_sim.core.kernels.Output`: Y_out, stats, events).

    ``breaks`` (sorted) are times where the forcing jumps: steps end exactly there.
    Writes y(t_out[i]) into Y_out[i]. ``stats`` = [rhs evaluations, accepted steps,
    rejected steps, stability-limited accepted steps (:data:`STIFF_H_LAMBDA`)] is accumulated.
    ``h_init`` <= 0 selects the first step automatically.
    After ``budget`` right-hand side evaluations (counted from the call's start) it returns
    STATUS_BUDGET after an accepted step: calling again from (y_end, t_end, h_next) continues
    the same integration. ``events``: see the module docstring. Returns (y_end, t_end,
    h_next, status, number of outputs written).
    """
    chain, extra, loads, held = problem
    y0, t0, t_out, breaks = span
    rtol, atol, h_init, max_step, max_steps, budget = control
    Y_out, stats, events = output
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
        return y, t, h_init, STATUS_OK, i_out
    m_ev, g0, g1, cap = _event_start(t, y, events)
    h = h_init
    n_steps = 0
    nfev0 = stats[0]
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
        seg_end = _segment_end(breaks, t, t_final)
        t_side = 0.5 * (t + seg_end)
        rhs(t, y, chain, extra, loads, held, t_side, f)
        stats[0] += 1
        if h <= 0.0:
            h = _initial_step(rhs, problem, t_side, t, y, f, seg_end, control, stats)
        rejected = False
        while t < seg_end:
            if m_ev > 0 and events.count[0] + m_ev > cap:
                return y, t, h, STATUS_EVENTS_FULL, i_out
            h = min(h, max_step)
            min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
            if h < min_step:
                return y, t, h, STATUS_STEP_UNDERFLOW, i_out
            t_new = t + h
            if t_new >= seg_end - 1e-14 * max(1.0, abs(seg_end)):
                t_new = seg_end
            hs = t_new - t
            # stages
            K[0, :] = f
            for s in range(1, N_STAGES):
                _combine(A_DOP[s, :s], K, y, hs, yy)
                rhs(t + C_DOP[s] * hs, yy, chain, extra, loads, held, t_side, K[s])
            _combine(B_DOP, K, y, hs, y_new)
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
            # Hairer's stiffness test (DOP853): h |f(t+h, y_new) - f(t+h, y_12)| / |y_new -
            # y_12| estimates h |lambda| along the step; above 6.1 stability limits the step.
            # Norms weighted as the error's (each component over its tolerance), so that the
            # estimate does not depend on the units of angles, rates and lengths
            num = 0.0
            den = 0.0
            for i in range(n):
                w = 1.0 / (atol + max(abs(y[i]), abs(y_new[i])) * rtol)
                num += (w * (f_new[i] - K[N_STAGES - 1, i])) ** 2
                den += (w * (y_new[i] - yy[i])) ** 2
            if den > 0.0 and hs * hs * num > STIFF_H_LAMBDA ** 2 * den:
                stats[3] += 1
            if err_norm == 0.0:
                factor = max_factor
            else:
                factor = min(max_factor, safety * err_norm ** exponent)
            if rejected:
                factor = min(1.0, factor)
            rejected = False
            h_next = hs * factor
            # dense output: for the output times inside (t, t_new] and for event location
            x_stop = -1.0
            crossed = False
            if m_ev > 0:
                _event_values(t_new, y_new, events, g1)
                crossed = _may_cross(g0, g1, events)
            need_out = i_out < n_out and t_out[i_out] < t_new
            if crossed or need_out:
                for s in range(N_STAGES + 1, 16):
                    _combine(A_DOP[s, :s], K, y, hs, yy)
                    rhs(t + C_DOP[s] * hs, yy, chain, extra, loads, held, t_side, K[s])
                stats[0] += 16 - N_STAGES - 1
                _hermite_form(y, y_new, K[0], f_new, hs, F)
                for i in range(n):
                    for d in range(4):
                        acc = 0.0
                        for r in range(16):
                            acc += D_DOP[d, r] * K[r, i]
                        F[3 + d, i] = hs * acc
            if crossed:
                x_stop = _locate(F, y, t, hs, g0, g1, events)
            t_last = t_new if x_stop < 0.0 else t + x_stop * hs
            while i_out < n_out and t_out[i_out] <= t_last:
                if t_out[i_out] == t_new:
                    Y_out[i_out, :] = y_new
                else:
                    x = (t_out[i_out] - t) / hs
                    for i in range(n):
                        Y_out[i_out, i] = _dense(F, y, x, i)
                i_out += 1
            if x_stop >= 0.0:
                for i in range(n):
                    yy[i] = _dense(F, y, x_stop, i) if x_stop < 1.0 else y_new[i]
                return yy, t_last, h_next, STATUS_EVENT, i_out
            g0[:] = g1
            t = t_new
            y[:] = y_new
            f[:] = f_new
            h = h_next
            if not _all_finite(y):
                return y, t, h, STATUS_NONFINITE, i_out
            if n_steps >= max_steps:
                return y, t, h, STATUS_MAX_STEPS, i_out
            if stats[0] - nfev0 >= budget and t < t_final:
                return y, t, h, STATUS_BUDGET, i_out
    return y, t, h, STATUS_OK, i_out


@njit
def fixed_run(rhs, problem, span, control, tableau, output):
    """Fixed-step explicit Runge-Kutta with ``tableau`` (A, b, c) (c[0] = 0); arguments as
    :func:`dop853_run`, of ``control`` only ``max_step`` (the step h_max [s]) and
    ``budget``.

    Every interval between consecutive output times and breakpoints is split into
    ceil(length / h_max) equal steps, so outputs and breakpoints are hit exactly. Events are
    located on each step's cubic Hermite interpolant (one extra rhs at a sign change).
    After ``budget`` right-hand side evaluations it returns STATUS_BUDGET at the start of a
    step (calling again from (y_end, t_end) continues with the same steps).
    Returns (y_end, t_end, status, number of outputs written)."""
    chain, extra, loads, held = problem
    y0, t0, t_out, breaks = span
    h_max, budget = control.max_step, control.budget
    A, b, c = tableau
    Y_out, stats, events = output
    n = y0.shape[0]
    nfev0 = stats[0]
    ns = b.shape[0]
    K = np.empty((ns, n))
    F = np.zeros((7, n))
    yy = np.empty(n)
    y_prev = np.empty(n)
    f_new = np.empty(n)
    y = y0.copy()
    t = t0
    n_out = t_out.shape[0]
    i_out = 0
    m_ev, g0, g1, cap = _event_start(t, y, events)
    while i_out < n_out and t_out[i_out] <= t0:
        Y_out[i_out, :] = y0
        i_out += 1
    while i_out < n_out:
        target = _segment_end(breaks, t, t_out[i_out])
        t_side = 0.5 * (t + target)
        n_sub = int(np.ceil((target - t) / h_max - 1e-9))
        if n_sub < 1:
            n_sub = 1
        hs = (target - t) / n_sub
        t_start = t
        for step in range(n_sub):
            ts = t_start + step * hs
            if m_ev > 0 and events.count[0] + m_ev > cap:
                return y, ts, STATUS_EVENTS_FULL, i_out
            if stats[0] - nfev0 >= budget and stats[0] > nfev0:
                return y, ts, STATUS_BUDGET, i_out
            y_prev[:] = y
            for s in range(ns):
                _combine(A[s, :s], K, y, hs, yy)
                rhs(ts + c[s] * hs, yy, chain, extra, loads, held, t_side, K[s])
            stats[0] += ns
            _combine(b, K, y, hs, y)
            stats[1] += 1
            if not _all_finite(y):
                return y, ts + hs, STATUS_NONFINITE, i_out
            if m_ev == 0:
                continue
            _event_values(ts + hs, y, events, g1)
            if _may_cross(g0, g1, events):
                rhs(ts + hs, y, chain, extra, loads, held, t_side, f_new)
                stats[0] += 1
                _hermite_form(y_prev, y, K[0], f_new, hs, F)
                x_stop = _locate(F, y_prev, ts, hs, g0, g1, events)
                if x_stop >= 0.0:
                    if x_stop < 1.0:
                        for i in range(n):
                            yy[i] = _dense(F, y_prev, x_stop, i)
                        return yy, ts + x_stop * hs, STATUS_EVENT, i_out
                    if step == n_sub - 1:
                        while i_out < n_out and t_out[i_out] <= target:
                            Y_out[i_out, :] = y
                            i_out += 1
                        return y, target, STATUS_EVENT, i_out
                    return y, ts + hs, STATUS_EVENT, i_out
            g0[:] = g1
        t = target
        while i_out < n_out and t_out[i_out] <= t:
            Y_out[i_out, :] = y
            i_out += 1
    return y, t, STATUS_OK, i_out


# Module-level entry points, one per model kernel. Passing a kernel as an argument from
# Python would make numba compile (and never cache) a new specialisation in every process;
# these wrappers take only arrays, so their machine code is cached on disk.
from . import kernels as _k  # noqa: E402


@njit
def dop853_rigid(problem, span, control, output):
    return dop853_run(_k.rigid_rhs, problem, span, control, output)


@njit
def dop853_reduced(problem, span, control, output):
    return dop853_run(_k.reduced_rhs, problem, span, control, output)


@njit
def dop853_full(problem, span, control, output):
    return dop853_run(_k.full_rhs, problem, span, control, output)


@njit
def fixed_rigid(problem, span, control, tableau, output):
    return fixed_run(_k.rigid_rhs, problem, span, control, tableau, output)


@njit
def fixed_reduced(problem, span, control, tableau, output):
    return fixed_run(_k.reduced_rhs, problem, span, control, tableau, output)


@njit
def fixed_full(problem, span, control, tableau, output):
    return fixed_run(_k.full_rhs, problem, span, control, tableau, output)
