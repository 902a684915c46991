"""Compiled implicit Runge-Kutta: Radau IIA of order 5 (3 stages) for stiff scenes.

The method, its constants and its control follow Hairer & Wanner's RADAU5 as transcribed in
scipy's ``scipy/integrate/_ivp/radau.py``: simplified Newton iterations on the collocation
system in the transformed variables (one real and one complex linear system per iteration),
Jacobian reuse (recomputed only when Newton converges slowly or fails), Gustafsson's
predictive step-size controller, the error estimate filtered through (mu_real/h I - J)^-1,
and the cubic collocation polynomial as dense output and as Newton's starting guess.

Every model of :mod:`rod_sim.core.kernels` is second order: the state is y = [q, v]
(size N = 2m) with dq/dt = v exactly, so the Jacobian is [[0, I], [K, D]] with
K = da/dq, D = da/dv (m, m each). Only the lower half J = [K, D] (m, 2m) is formed, by
compiled forward differences of the rhs kernel (2m kernel calls), and every linear system
(gamma I - J_full) z = r is reduced to the m x m system
(gamma^2 I - gamma D - K) x = r_v + gamma r_q - D r_q,  z = [x, gamma x - r_q],
which makes each LU factorisation 8x cheaper than on the N x N matrix.

Interfaces:

- :func:`advance_step`: one accepted step (the building block for drivers with event
  location; :func:`radau_step` takes its parts loose); :func:`radau_dense` evaluates its
  dense output. The workspace is a :class:`RadauWork`, the functions a :class:`RadauFns`.
- :func:`radau_run`: the whole output grid in one call, with exactly the arguments and the
  return of :func:`rod_sim.core.erk.dop853_run` (status codes of :mod:`rod_sim.core.erk`),
  hinge events included: after every accepted step the event functions are compared at the
  step's ends and a crossing is located on the step's cubic collocation polynomial, written
  into DOP853's nested dense form so that erk's bracketing and Illinois search are reused
  (:func:`_nested_form`).
- ``radau_rigid``, ``radau_reduced``, ``radau_full``: per-model cached wrappers, like
  ``erk.dop853_rigid`` (the models' ``compiled`` drivers).

``stats`` = [rhs evaluations (Jacobian columns included), accepted steps, rejected steps];
when it has 6 entries, also [Jacobian evaluations, LU factorisation pairs, Newton iterations].
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .erk import (STATUS_BUDGET, STATUS_EVENT, STATUS_EVENTS_FULL, STATUS_NEWTON_FAILED,
                  STATUS_NONFINITE, STATUS_MAX_STEPS,
                  STATUS_OK, STATUS_STEP_UNDERFLOW, _all_finite, _event_start, _event_values,
                  _initial_step, _locate, _may_cross, _segment_end)
from . import kernels as _k
from . import newton as _nw
from .jit import njit
from .dense_lu import lu_inplace, lu_solve

# ----------------------------------------------------------------- constants (scipy's radau.py)
S6 = 6.0 ** 0.5
C = np.array([(4.0 - S6) / 10.0, (4.0 + S6) / 10.0, 1.0])
E = np.array([-13.0 - 7.0 * S6, -13.0 + 7.0 * S6, -1.0]) / 3.0
MU_REAL = 3.0 + 3.0 ** (2.0 / 3.0) - 3.0 ** (1.0 / 3.0)
MU_C_RE = 3.0 + 0.5 * (3.0 ** (1.0 / 3.0) - 3.0 ** (2.0 / 3.0))
MU_C_IM = -0.5 * (3.0 ** (5.0 / 6.0) + 3.0 ** (7.0 / 6.0))
T = np.array([[0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
              [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
              [1.0, 1.0, 0.0]])
TI = np.array([[4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
               [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
               [0.50287263494578682, -2.57192694985560522, 0.59603920482822492]])
P = np.array([[13.0 / 3.0 + 7.0 * S6 / 3.0, -23.0 / 3.0 - 22.0 * S6 / 3.0, 10.0 / 3.0 + 5.0 * S6],
              [13.0 / 3.0 - 7.0 * S6 / 3.0, -23.0 / 3.0 + 22.0 * S6 / 3.0, 10.0 / 3.0 - 5.0 * S6],
              [1.0 / 3.0, -8.0 / 3.0, 10.0 / 3.0]])
NEWTON_MAXITER = 6
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
EPS = np.finfo(float).eps

# controller memory ``ctl`` (float64 array) of the workspace
H_OLD, ERR_OLD, HAVE_JAC, CURRENT_JAC, LU_H, HAVE_DENSE, H_DENSE, FACCON = 0, 1, 2, 3, 4, 5, 6, 7
RESUME_T = 8        # time [s] a call stopped at on its work budget (NaN: none): resume there
N_CTL = 9
NEWTON_FAILURES = 30
"""Newton non-convergences in a row (each halving the step) after which a step gives up
(STATUS_NEWTON_FAILED) instead of shrinking further."""
JAC_RATE = 0.1      # recompute the Jacobian after a step whose Newton rate exceeded this
# rows of RadauWork.V (real scratch (8, N)) and RadauWork.CV (complex scratch (2, N))
V_YY, V_FD, V_FR, V_XR, V_SCALE, V_RHS_ERR, V_ERR = 0, 1, 2, 3, 4, 5, 6
CV_FC, CV_XC = 0, 1


class RadauWork(NamedTuple):
    """Radau's workspace, kept between steps and calls (allocated once per run, nothing per
    step). The Newton systems' part depends on the algebra (:func:`radau_workspace`: dense;
    :func:`rod_sim.core.newton.chain_workspace`: the chains' O(n) solve), read only by its
    own ``jac``, ``factor`` and ``solve`` functions (:class:`RadauFns`):

    - ``jac``: what the Jacobian update keeps (dense: J = [da/dq, da/dv] (m, 2m); chain: the
      angles phi_J and psi_J (n + 1,) [rad] the inertia is taken at and the tension
      stiffness K_T (n,) [N m/rad] there);
    - ``real``, ``real_aux``: the system at the real shift (dense: LU (m, m) and pivots
      (m,); chain: the Newton Extra and Chain), ``cplx``, ``cplx_aux`` the same at the
      complex shift;

    then the step's arrays: ``Z`` (3, N) stage increments, ``W`` (3, N) transformed
    increments, ``F`` (3, N) stage derivatives, ``Q`` (N, 3) dense-output coefficients,
    ``V`` (8, N) real scratch (rows ``V_*``), ``CV`` (2, N) complex scratch (rows ``CV_*``),
    ``ctl`` (N_CTL,) the controller memory (indices H_OLD ... RESUME_T). Q is ``work[8]``
    for readers by position."""

    jac: object
    real: object
    real_aux: object
    cplx: object
    cplx_aux: object
    Z: np.ndarray
    W: np.ndarray
    F: np.ndarray
    Q: np.ndarray
    V: np.ndarray
    CV: np.ndarray
    ctl: np.ndarray


class RadauFns(NamedTuple):
    """The functions a Radau run is built from: ``rhs`` (the kernels' calling convention,
    :mod:`rod_sim.core.kernels`) and the Newton systems' ``jac`` (rhs, problem, t_side, t,
    y, f, work, stats), ``factor`` (chain, extra, work, g_real, g_cplx, stats) -> ok and
    ``solve`` (chain, extra, jac, sys, sys_aux, gamma, r, out): dense (:func:`dense_jac`,
    :func:`dense_factor`, :func:`dense_solve`) or the chains' O(n) ones
    (:mod:`rod_sim.core.newton`)."""

    rhs: object
    jac: object
    factor: object
    solve: object


# ----------------------------------------------------------------- dense linear algebra
@njit
def _form(J, gamma, M):
    """M = gamma^2 I - gamma D - K (m, m) from J = [K, D] (m, 2m)."""
    m = M.shape[0]
    g2 = gamma * gamma
    for i in range(m):
        for j in range(m):
            M[i, j] = -gamma * J[i, m + j] - J[i, j]
        M[i, i] += g2


@njit
def _solve_reduced(LU, piv, J, gamma, r, out):
    """out (N,) = (gamma I - [[0, I], [K, D]])^-1 r (N,) through the m x m factors LU of
    gamma^2 I - gamma D - K. ``out`` must not alias ``r``."""
    m = LU.shape[0]
    for i in range(m):
        acc = r[m + i] + gamma * r[i]
        for j in range(m):
            acc -= J[i, m + j] * r[j]
        out[i] = acc
    lu_solve(LU, piv, out[:m])
    for i in range(m):
        out[m + i] = gamma * out[i] - r[i]


@njit
def dense_factor(chain, extra, work, g_real, g_cplx, stats):
    """Dense Newton matrices: LU of gamma^2 I - gamma D - K at the real and complex shifts."""
    _form(work.jac, g_real, work.real)
    _form(work.jac, g_cplx, work.cplx)
    return lu_inplace(work.real, work.real_aux) and lu_inplace(work.cplx, work.cplx_aux)


@njit
def dense_solve(chain, extra, J, LU, piv, gamma, r, out):
    """(gamma I - J)^-1 r through the dense factors (:func:`_solve_reduced`)."""
    _solve_reduced(LU, piv, J, gamma, r, out)


@njit(inline="always")
def _factor(fns, problem, work, h, stats):
    """Set up the real and complex iteration matrices for step h [s]; False if singular."""
    ctl = work.ctl
    if stats.shape[0] > 4:
        stats[4] += 1
    ok = fns.factor(problem.chain, problem.extra, work, MU_REAL / h,
                    complex(MU_C_RE, MU_C_IM) / h, stats)
    ctl[LU_H] = h if ok else 0.0
    return ok


@njit
def dense_jac(rhs, problem, t_side, t, y, f, work, stats):
    """J = [da/dq, da/dv] (m, 2m) at (t, y) by forward differences (f = rhs(t, y)) of
    ``rhs`` on ``problem`` (:class:`~rod_sim.core.kernels.Problem`)."""
    chain, extra, loads, held = problem
    J = work.jac
    yy = work.V[V_YY]
    fd = work.V[V_FD]
    N = y.shape[0]
    m = N // 2
    yy[:] = y
    for j in range(N):
        delta = math.sqrt(EPS * max(1e-5, abs(y[j])))
        yy[j] = y[j] + delta
        delta = yy[j] - y[j]
        rhs(t, yy, chain, extra, loads, held, t_side, fd)
        for i in range(m):
            J[i, j] = (fd[m + i] - f[m + i]) / delta
        yy[j] = y[j]
    stats[0] += N
    if stats.shape[0] > 3:
        stats[3] += 1


@njit(inline="always")
def _jacobian(fns, problem, t_side, t, y, f, work, stats):
    """Renew the Newton matrices' Jacobian at (t, y) and mark the factors stale."""
    fns.jac(fns.rhs, problem, t_side, t, y, f, work, stats)
    ctl = work.ctl
    ctl[HAVE_JAC] = 1.0
    ctl[CURRENT_JAC] = 1.0
    ctl[LU_H] = 0.0


# ----------------------------------------------------------------- workspace
@njit
def make_work(jac, real, real_aux, cplx, cplx_aux, size):
    """:class:`RadauWork` from the Newton systems' part and fresh step arrays for a state of
    ``size``."""
    ctl = np.zeros(N_CTL)
    ctl[FACCON] = 1.0
    ctl[RESUME_T] = np.nan
    return RadauWork(jac, real, real_aux, cplx, cplx_aux, np.zeros((3, size)),
                     np.zeros((3, size)), np.zeros((3, size)), np.zeros((size, 3)),
                     np.zeros((8, size)), np.zeros((2, size), dtype=np.complex128), ctl)


@njit
def radau_workspace(size):
    """:class:`RadauWork` of the stepper with dense Newton algebra for a state of ``size`` =
    2m: jac J (m, 2m), real LU (m, m) and pivots (m,), cplx LU (m, m) complex and pivots
    (m,)."""
    m = size // 2
    return make_work(np.zeros((m, 2 * m)), np.zeros((m, m)), np.zeros(m, dtype=np.int64),
                     np.zeros((m, m), dtype=np.complex128), np.zeros(m, dtype=np.int64), size)


@njit
def radau_restart(work):
    """Forget the step history (after a jump of the forcing or of the state: event, latch):
    no predictor from the last polynomial, no controller memory. The Jacobian is kept but
    marked stale, so that slow Newton convergence recomputes it."""
    ctl = work.ctl
    ctl[H_OLD] = 0.0
    ctl[ERR_OLD] = 0.0
    ctl[HAVE_DENSE] = 0.0
    ctl[CURRENT_JAC] = 0.0
    ctl[RESUME_T] = np.nan


# ----------------------------------------------------------------- one step
@njit
def _newton(fns, problem, t_side, t, y, h, scale, tol, work, stats):
    """Simplified Newton on the collocation system (scipy's solve_collocation_system, with
    RADAU5's convergence test: |dW| rate / (1 - rate) < tol, the rate of the previous step
    standing in until one is measured, so that one iteration can suffice).

    ``work.Z`` (3, N) holds the starting guess on entry and the stage increments on exit.
    Returns (converged, iterations, convergence rate; -1 when unknown)."""
    chain, extra, loads, held = problem
    rhs, solve_fn = fns.rhs, fns.solve
    Z, W, F = work.Z, work.W, work.F
    V = work.V
    CV = work.CV
    N = y.shape[0]
    yy = V[V_YY]
    fr = V[V_FR]
    xr = V[V_XR]
    fc = CV[CV_FC]
    xc = CV[CV_XC]
    m_real = MU_REAL / h
    m_cplx = complex(MU_C_RE, MU_C_IM) / h
    for i in range(3):
        for j in range(N):
            W[i, j] = TI[i, 0] * Z[0, j] + TI[i, 1] * Z[1, j] + TI[i, 2] * Z[2, j]
    ctl = work.ctl
    faccon = max(ctl[FACCON], EPS) ** 0.8
    dw_old = -1.0
    rate = -1.0
    converged = False
    k = 0
    for k in range(NEWTON_MAXITER):
        for i in range(3):
            for j in range(N):
                yy[j] = y[j] + Z[i, j]
            rhs(t + C[i] * h, yy, chain, extra, loads, held, t_side, F[i])
        stats[0] += 3
        if stats.shape[0] > 5:
            stats[5] += 1
        if not (_all_finite(F[0]) and _all_finite(F[1]) and _all_finite(F[2])):
            break
        for j in range(N):
            f0 = F[0, j]
            f1 = F[1, j]
            f2 = F[2, j]
            fr[j] = TI[0, 0] * f0 + TI[0, 1] * f1 + TI[0, 2] * f2 - m_real * W[0, j]
            fc[j] = (complex(TI[1, 0] * f0 + TI[1, 1] * f1 + TI[1, 2] * f2,
                             TI[2, 0] * f0 + TI[2, 1] * f1 + TI[2, 2] * f2)
                     - m_cplx * complex(W[1, j], W[2, j]))
        solve_fn(chain, extra, work.jac, work.real, work.real_aux, m_real, fr, xr)
        solve_fn(chain, extra, work.jac, work.cplx, work.cplx_aux, m_cplx, fc, xc)
        acc = 0.0
        for j in range(N):
            a = xr[j] / scale[j]
            b = xc[j].real / scale[j]
            c = xc[j].imag / scale[j]
            acc += a * a + b * b + c * c
        dw = math.sqrt(acc / (3 * N))
        if not math.isfinite(dw):
            break
        if dw_old >= 0.0:
            rate = dw / dw_old
            if rate >= 1.0 or rate ** (NEWTON_MAXITER - k) / (1.0 - rate) * dw > tol:
                break
            faccon = rate / (1.0 - rate)
        for j in range(N):
            W[0, j] += xr[j]
            W[1, j] += xc[j].real
            W[2, j] += xc[j].imag
        for i in range(3):
            for j in range(N):
                Z[i, j] = T[i, 0] * W[0, j] + T[i, 1] * W[1, j] + T[i, 2] * W[2, j]
        if dw == 0.0 or faccon * dw < tol:
            converged = True
            break
        dw_old = dw
    ctl[FACCON] = faccon
    return converged, k + 1, rate


@njit
def _predict_factor(h, h_old, err, err_old):
    """Gustafsson's predictive controller (scipy's predict_factor); 0 = no history."""
    if err_old <= 0.0 or h_old <= 0.0 or err == 0.0:
        multiplier = 1.0
    else:
        multiplier = h / h_old * (err_old / err) ** 0.25
    if err == 0.0:
        return np.inf
    return min(1.0, multiplier) * err ** -0.25


@njit
def _rms_scaled(x, y, y_new, rtol, atol):
    acc = 0.0
    for j in range(x.shape[0]):
        v = x[j] / (atol + max(abs(y[j]), abs(y_new[j])) * rtol)
        acc += v * v
    return math.sqrt(acc / x.shape[0])


@njit
def radau_step(rhs, jac_fn, factor_fn, solve_fn, chain, extra, loads, held, t_side, t, y, f, h,
               t_bound, rtol, atol, work, y_new, f_new, stats):
    """:func:`advance_step` with its parts spelled out (the functions, the problem, the
    tolerances) for callers that have them loose; returns as advance_step."""
    return advance_step(RadauFns(rhs, jac_fn, factor_fn, solve_fn),
                        _k.Problem(chain, extra, loads, held), t_side, t, y, f, h, t_bound,
                        _k.Control(rtol, atol, 0.0, np.inf, 0, 0), work, y_new, f_new, stats)


@njit
def advance_step(fns, problem, t_side, t, y, f, h, t_bound, control, work, y_new, f_new,
                 stats):
    """One accepted Radau IIA step of ``fns.rhs`` on ``problem``
    (:class:`~rod_sim.core.kernels.Problem`) from time t [s], state y (N,), f = rhs(t, y)
    (N,), with the tolerances ``control.rtol``, ``control.atol``.

    ``h`` [s] > 0 is the proposed step; the step ends at ``t_bound`` if it would reach it
    (within 1e-14 relative). ``work`` (:class:`RadauWork`) is kept between steps: it carries
    the Jacobian, the factorisations, the controller memory and the predictor.
    ``t_side`` is passed to the kernel (a time inside the current smooth segment).

    On success writes y_new = y(t_new) (N,), f_new = rhs(t_new, y_new) (N,) and the dense
    output coefficients ``work.Q`` (N, 3): for x in [0, 1],
    y(t + x (t_new - t)) = y + Q[:, 0] x + Q[:, 1] x^2 + Q[:, 2] x^3 (:func:`radau_dense`).
    Returns (status, t_new, h_next): STATUS_OK, or STATUS_STEP_UNDERFLOW (t_new = t) when
    the step fell below 10 ulp of t, STATUS_NEWTON_FAILED (t_new = t) after
    :data:`NEWTON_FAILURES` Newton failures in a row, or STATUS_NONFINITE when y_new is not
    finite."""
    chain, extra, loads, held = problem
    rhs, solve_fn = fns.rhs, fns.solve
    rtol, atol = control.rtol, control.atol
    Z, Q, V, ctl = work.Z, work.Q, work.V, work.ctl
    N = y.shape[0]
    scale = V[V_SCALE]
    rhs_err = V[V_RHS_ERR]
    err = V[V_ERR]
    yy = V[V_YY]
    newton_tol = max(10.0 * EPS / rtol, min(0.03, math.sqrt(rtol)))
    min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
    if ctl[HAVE_JAC] == 0.0:
        _jacobian(fns, problem, t_side, t, y, f, work, stats)
    h_abs = h
    h_old = ctl[H_OLD]
    err_old = ctl[ERR_OLD]
    rejected = False
    n_iter = 0
    rate = -1.0
    error_norm = 0.0
    safety = 0.9
    t_new = t
    hs = h
    n_fail = 0
    while True:
        if not h_abs >= min_step:
            return STATUS_STEP_UNDERFLOW, t, h_abs
        t_new = t + h_abs
        if t_new >= t_bound - 1e-14 * max(1.0, abs(t_bound)):
            t_new = t_bound
        hs = t_new - t
        # starting guess: the previous step's collocation polynomial, extrapolated
        if ctl[HAVE_DENSE] != 0.0:
            for i in range(3):
                x = 1.0 + C[i] * hs / ctl[H_DENSE]
                for j in range(N):
                    Z[i, j] = Q[j, 0] * (x - 1.0) + Q[j, 1] * (x * x - 1.0) \
                        + Q[j, 2] * (x * x * x - 1.0)
        else:
            Z[:, :] = 0.0
        for j in range(N):
            scale[j] = atol + abs(y[j]) * rtol
        converged = False
        while True:
            ok = True
            if abs(ctl[LU_H] - hs) > 1e-9 * hs:
                ok = _factor(fns, problem, work, hs, stats)
            if ok:
                converged, n_iter, rate = _newton(fns, problem, t_side, t, y, hs, scale,
                                                  newton_tol, work, stats)
            if converged or ctl[CURRENT_JAC] != 0.0:
                break
            _jacobian(fns, problem, t_side, t, y, f, work, stats)
        if not converged:
            h_abs = 0.5 * hs
            stats[2] += 1
            rejected = True
            n_fail += 1
            if n_fail >= NEWTON_FAILURES:
                return STATUS_NEWTON_FAILED, t, h_abs
            continue
        hl = ctl[LU_H]
        for j in range(N):
            y_new[j] = y[j] + Z[2, j]
            rhs_err[j] = f[j] + (Z[0, j] * E[0] + Z[1, j] * E[1] + Z[2, j] * E[2]) / hs
        solve_fn(chain, extra, work.jac, work.real, work.real_aux, MU_REAL / hl, rhs_err, err)
        error_norm = _rms_scaled(err, y, y_new, rtol, atol)
        safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
        if rejected and error_norm > 1.0:
            for j in range(N):
                yy[j] = y[j] + err[j]
            rhs(t, yy, chain, extra, loads, held, t_side, err)
            stats[0] += 1
            for j in range(N):
                rhs_err[j] += err[j] - f[j]
            solve_fn(chain, extra, work.jac, work.real, work.real_aux, MU_REAL / hl, rhs_err, err)
            error_norm = _rms_scaled(err, y, y_new, rtol, atol)
        if not error_norm <= 1.0:
            if math.isfinite(error_norm):
                factor = _predict_factor(hs, h_old, error_norm, err_old)
                h_abs = hs * max(MIN_FACTOR, safety * factor)
            else:
                h_abs = hs * MIN_FACTOR
            stats[2] += 1
            rejected = True
            continue
        break
    stats[1] += 1
    if not _all_finite(y_new):
        return STATUS_NONFINITE, t, hs
    recompute_jac = n_iter > 1 and rate > JAC_RATE
    factor = min(MAX_FACTOR, safety * _predict_factor(hs, h_old, error_norm, err_old))
    if not recompute_jac and factor < 1.2:
        factor = 1.0                      # keep h, and with it the factorisations
    else:
        ctl[LU_H] = 0.0
    rhs(t_new, y_new, chain, extra, loads, held, t_side, f_new)
    stats[0] += 1
    if recompute_jac:
        _jacobian(fns, problem, t_side, t_new, y_new, f_new, work, stats)
    else:
        ctl[CURRENT_JAC] = 0.0
    for j in range(N):
        for k in range(3):
            Q[j, k] = Z[0, j] * P[0, k] + Z[1, j] * P[1, k] + Z[2, j] * P[2, k]
    ctl[HAVE_DENSE] = 1.0
    ctl[H_DENSE] = hs
    ctl[H_OLD] = hs
    ctl[ERR_OLD] = error_norm
    return STATUS_OK, t_new, hs * factor


@njit
def radau_dense(y_old, Q, x, out):
    """Dense output of the last step at x = (t - t_old) / (t_new - t_old) in [0, 1]:
    out (N,) = y_old + Q[:, 0] x + Q[:, 1] x^2 + Q[:, 2] x^3."""
    for j in range(y_old.shape[0]):
        out[j] = y_old[j] + x * (Q[j, 0] + x * (Q[j, 1] + x * Q[j, 2]))


# ----------------------------------------------------------------- the driver
@njit
def radau_run(rhs, problem, span, control, output):
    """Integrate from (t0, y0) through every time of ``t_out`` (sorted, >= t0): the same
    arguments, return and status codes as :func:`rod_sim.core.erk.dop853_run`.

    Steps end exactly at ``breaks`` (sorted times where the forcing jumps), where the step
    history is forgotten (:func:`radau_restart`). Writes y(t_out[i]) into Y_out[i] by dense
    output. ``events``: see :mod:`rod_sim.core.erk` (located on the collocation polynomial).
    Returns (y_end, t_end, h_next, status, number of outputs written)."""
    return radau_run_work(RadauFns(rhs, dense_jac, dense_factor, dense_solve), problem, span,
                          control, output, radau_workspace(span.y0.shape[0]))


@njit
def _nested_form(Q, F):
    """Write the step's cubic a x + b x^2 + c x^3 (Q (N, 3) = [a, b, c]) into DOP853's nested
    dense form F (7, N) read by erk's event location: x (F0 + (1 - x) (F1 + x F2)) with
    F0 = a + b + c, F1 = -(b + c), F2 = -c, F3..F6 = 0."""
    for i in range(Q.shape[0]):
        a, b, c = Q[i, 0], Q[i, 1], Q[i, 2]
        F[0, i] = a + b + c
        F[1, i] = -(b + c)
        F[2, i] = -c
        for k in range(3, 7):
            F[k, i] = 0.0


@njit
def radau_run_work(fns, problem, span, control, output, work):
    """:func:`radau_run` of ``fns`` (:class:`RadauFns`: the rhs and the Newton systems'
    functions) with the workspace ``work`` (:class:`RadauWork`) given, so that
    a caller stepping one model period by period keeps its Jacobian between calls (it is
    kept stale: slow Newton convergence still renews it). At an event the history is
    forgotten and the Jacobian dropped (the caller changes the mode: a latch jumps the
    velocity, a stop contact switches the rhs), so the next call starts afresh. After
    ``budget`` right-hand side evaluations (Jacobian columns included) it returns
    STATUS_BUDGET after an accepted step, keeping the step history in ``work``: a call from
    the returned (y_end, t_end, h_next) with the same ``work`` continues the same integration."""
    chain, extra, loads, held = problem
    rhs = fns.rhs
    y0, t0, t_out, breaks = span
    h_init, max_step, max_steps, budget = (control.h_init, control.max_step,
                                           control.max_steps, control.budget)
    Y_out, stats, events = output
    n = y0.shape[0]
    n_out = t_out.shape[0]
    t_final = t_out[n_out - 1]
    y = y0.copy()
    t = t0
    i_out = 0
    while i_out < n_out and t_out[i_out] <= t0:
        Y_out[i_out, :] = y0
        i_out += 1
    if i_out == n_out:
        return y, t, h_init, STATUS_OK, i_out
    m_ev, g0, g1, cap = _event_start(t, y, events)
    F = np.zeros((7, n))
    Q = work.Q
    f = np.empty(n)
    y_new = np.empty(n)
    f_new = np.empty(n)
    h = h_init
    n_steps = 0
    nfev0 = stats[0]
    ctl = work.ctl
    resume = ctl[RESUME_T] == t0 and h > 0.0
    ctl[RESUME_T] = np.nan
    while t < t_final:
        seg_end = _segment_end(breaks, t, t_final)
        t_side = 0.5 * (t + seg_end)
        rhs(t, y, chain, extra, loads, held, t_side, f)
        stats[0] += 1
        if h <= 0.0:
            h = _initial_step(rhs, problem, t_side, t, y, f, seg_end, control, stats)
        if not resume:
            radau_restart(work)
        resume = False
        while t < seg_end:
            if m_ev > 0 and events.count[0] + m_ev > cap:
                return y, t, h, STATUS_EVENTS_FULL, i_out
            h = min(h, max_step)
            status, t_new, h_next = advance_step(fns, problem, t_side, t, y, f, h, seg_end,
                                                 control, work, y_new, f_new, stats)
            if status != STATUS_OK:
                return y, t, h_next, status, i_out
            hs = t_new - t
            x_stop = -1.0
            if m_ev > 0:
                _event_values(t_new, y_new, events, g1)
                if _may_cross(g0, g1, events):
                    _nested_form(Q, F)
                    x_stop = _locate(F, y, t, hs, g0, g1, events)
            t_last = t_new if x_stop < 0.0 else t + x_stop * hs
            while i_out < n_out and t_out[i_out] <= t_last:
                if t_out[i_out] == t_new:
                    Y_out[i_out, :] = y_new
                else:
                    radau_dense(y, Q, (t_out[i_out] - t) / hs, Y_out[i_out])
                i_out += 1
            if x_stop >= 0.0:
                if x_stop < 1.0:
                    radau_dense(y, Q, x_stop, y_new)
                radau_restart(work)
                ctl[HAVE_JAC] = 0.0
                return y_new.copy(), t_last, h_next, STATUS_EVENT, i_out
            g0[:] = g1
            t = t_new
            y[:] = y_new
            f[:] = f_new
            h = h_next
            n_steps += 1
            if n_steps >= max_steps:
                return y, t, h, STATUS_MAX_STEPS, i_out
            if stats[0] - nfev0 >= budget and t < t_final:
                ctl[RESUME_T] = t
                return y, t, h, STATUS_BUDGET, i_out
    return y, t, h, STATUS_OK, i_out


def chain_radau_workspace(model):
    """The :class:`RadauWork` of a chain model: the O(n) Newton part
    (:func:`rod_sim.core.newton.chain_workspace`) and the step's arrays."""
    return make_work(*_nw.chain_workspace(model.chain, model.extra, model.state_size),
                     model.state_size)


# Module-level entry points, one per model kernel (see erk.py: cached on disk).


@njit
def radau_rigid(problem, span, control, output, work):
    return radau_run_work(RadauFns(_k.rigid_rhs, _nw.chain_jac, _nw.chain_factor,
                                   _nw.chain_solve), problem, span, control, output, work)


@njit
def radau_reduced(problem, span, control, output, work):
    return radau_run_work(RadauFns(_k.reduced_rhs, _nw.chain_jac, _nw.chain_factor,
                                   _nw.chain_solve), problem, span, control, output, work)


@njit
def radau_full(problem, span, control, output, work):
    return radau_run_work(RadauFns(_k.full_rhs, _nw.chain_jac, _nw.chain_factor,
                                   _nw.chain_solve), problem, span, control, output, work)
