"""Linear stability of a model and of the explicit integrators: why a run takes the steps it
takes.

- :func:`jacobian`: d(dy/dt)/dy (m, m) of a model's right-hand side at one state, by central
  differences of the compiled kernel (m = state size).
- :func:`spectral_radius`: the largest |lambda| [rad/s] of that Jacobian (the fastest mode of
  the linearised model: the full model's bending vibrations).
- :func:`stability_limit`: the largest x such that an explicit Runge-Kutta method with the
  given tableau is stable for h lambda on the ray from 0 through ``direction`` up to x, i.e.
  |R(h lambda)| <= 1 with R the method's stability polynomial (dimensionless h |lambda|).

An explicit method on a model whose fastest mode is lambda needs h <= stability_limit /
|lambda|, whatever the tolerance: the run is then *stability-bound*.
"""
from __future__ import annotations

import numpy as np


def jacobian(model, t: float, y: np.ndarray, held=None, mode=None,
             rel_step: float = 1e-7) -> np.ndarray:
    """J (m, m) = d rhs / d y at (t, y) [1/s] by central differences (step rel_step
    max(1, |y_i|) per component); ``held`` (n, 2) [N] and ``mode`` as for ``model.rhs``."""
    y = np.asarray(y, dtype=float)
    m = y.size
    contact = model.contact_state(y, t)
    J = np.empty((m, m))
    for i in range(m):
        h = rel_step * max(1.0, abs(y[i]))
        e = np.zeros(m)
        e[i] = h
        J[:, i] = (model.rhs(t, y + e, held, mode, contact)
                   - model.rhs(t, y - e, held, mode, contact)) / (2.0 * h)
    return J


def spectral_radius(model, t: float, y: np.ndarray, held=None, mode=None) -> tuple[float, complex]:
    """(max |lambda| [rad/s], that lambda) of the Jacobian at (t, y)."""
    lam = np.linalg.eigvals(jacobian(model, t, y, held, mode))
    i = int(np.argmax(np.abs(lam)))
    return float(abs(lam[i])), complex(lam[i])


def stability_polynomial(A: np.ndarray, b: np.ndarray):
    """R(z) of the explicit Runge-Kutta method (A (s, s) strictly lower, b (s,)), as a
    function of complex z (a scalar or an array): y_{k+1} = R(h lambda) y_k for
    y' = lambda y."""
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    s = b.shape[0]

    def R(z):
        z = np.asarray(z, dtype=complex)
        k = np.zeros((s,) + z.shape, dtype=complex)
        for j in range(s):
            k[j] = z * (1.0 + np.tensordot(A[j, :j], k[:j], axes=1))
        return 1.0 + np.tensordot(b, k, axes=1)

    return R


def stability_limit(A: np.ndarray, b: np.ndarray, direction: complex = 1j,
                    x_max: float = 20.0, resolution: float = 1e-4) -> float:
    """Largest x (dimensionless h |lambda|) with |R(x d)| <= 1 + 1e-12 for every point of the
    ray from 0 to x d, d = direction / |direction|; scanned at ``resolution``, then refined by
    bisection to 1e-10. Returns x_max when the whole scanned ray is stable."""
    R = stability_polynomial(A, b)
    d = complex(direction) / abs(direction)
    xs = np.arange(1, int(round(x_max / resolution)) + 1) * resolution
    unstable = np.flatnonzero(np.abs(R(xs * d)) > 1.0 + 1e-12)
    if unstable.size == 0:
        return float(x_max)
    hi = float(xs[unstable[0]])
    lo = hi - resolution
    while hi - lo > 1e-10:
        mid = 0.5 * (lo + hi)
        if abs(R(mid * d)) > 1.0 + 1e-12:
            hi = mid
        else:
            lo = mid
    return float(lo)
