"""Time steppers behind one protocol, chosen by name.

Every integrator maps (model, y0, t0, output times, held forces) to the states at the output
times, restarting at the scene's load breakpoints:

- ``dop853-jit`` (default): compiled adaptive Dormand-Prince 8(5,3) with dense output.
- ``radau-jit``: compiled implicit Radau IIA of order 5 (stiff scenes: the full model,
  stiff rods, stops), finite-difference Jacobian, collocation dense output.
- ``rk4``, ``rk2``, ``euler``: compiled fixed-step explicit Runge-Kutta (order 4, 2, 1);
  the step is ``step`` [s] at most, intervals are split into equal substeps.
- ``RK45``, ``DOP853``, ``Radau``, ``BDF``, ``LSODA``: scipy's ``solve_ivp`` methods.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from . import erk, radau

DEFAULT_RTOL = 1e-8
DEFAULT_STEP = 1e-3
MIN_STEP = 1e-9         # [s]: smallest fixed step (the step count of an interval stays exact)
from .names import INTEGRATOR_NAMES as INTEGRATORS
from .names import SCIPY_METHODS

_TABLEAUX = {
    "euler": (np.zeros((1, 1)), np.array([1.0]), np.array([0.0]), 1),
    "rk2": (np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.5, 0.5]), np.array([0.0, 1.0]), 2),
    "rk4": (np.array([[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0],
                      [0.0, 0.0, 1.0, 0.0]]),
            np.array([1.0, 2.0, 2.0, 1.0]) / 6.0, np.array([0.0, 0.5, 0.5, 1.0]), 4),
}


class IntegrationError(RuntimeError):
    """The integration could not go on (divergence, non-finite state, step underflow).

    ``t`` is the simulated time [s] reached, ``reason`` a one-line cause (it names the
    quantity and rod that went non-finite or grew fastest when the integrator knows them)."""

    def __init__(self, reason: str, t: float):
        self.reason = reason
        self.t = t
        super().__init__(f"integration stopped at t = {t:.6g} s: {reason}")


_GROUPS = {1: (("phi", "rad"), ("phi_rate", "rad/s")),
           3: (("phi", "rad"), ("alpha", "rad"), ("beta", "rad"), ("phi_rate", "rad/s"),
               ("alpha_rate", "rad/s"), ("beta_rate", "rad/s"))}


def state_component(model, i: int) -> tuple[str, int, str]:
    """(quantity, rod 1..n, unit) of component ``i`` of the model's state vector."""
    name, unit = _GROUPS[model.dof_per_rod][i // model.n]
    return name, i % model.n + 1, unit


def explain_state(model, t: float, y, held=None) -> str:
    """Why the state ``y`` at ``t`` [s] stops an integration, in words: the first non-finite
    component, else the first non-finite derivative, else the largest rate (the likely
    divergence). Never raises."""
    try:
        y = np.asarray(y, dtype=float)
        bad = np.flatnonzero(~np.isfinite(y))
        if bad.size:
            name, rod, _ = state_component(model, int(bad[0]))
            return f"{name} of rod {rod} is {y[bad[0]]} ({bad.size} non-finite components)"
        dy = model.rhs(t, y, held)
        bad = np.flatnonzero(~np.isfinite(dy))
        if bad.size:
            name, rod, _ = state_component(model, int(bad[0]))
            return f"the time derivative of {name} of rod {rod} is {dy[bad[0]]}"
        half = y.size // 2
        i = half + int(np.argmax(np.abs(y[half:])))
        j = half + int(np.argmax(np.abs(dy[half:])))
        name, rod, unit = state_component(model, i)
        acc_name, acc_rod, _ = state_component(model, j)
        f = np.abs(model.forces(t, held))
        k = np.unravel_index(int(np.argmax(f)), f.shape)
        return (f"largest rate: {name} of rod {rod} = {y[i]:.3g} {unit}; largest "
                f"acceleration: d({acc_name})/dt of rod {acc_rod} = {dy[j]:.3g} {unit}/s; "
                f"largest applied force: {'xy'[k[1]]} at node {k[0] + 1} = {f[k]:.3g} N")
    except Exception as exc:  # the explanation must never hide the original failure
        return f"state not inspectable ({type(exc).__name__})"


def _failure(model, status_text: str, t: float, y, held) -> IntegrationError:
    return IntegrationError(f"{status_text}; {explain_state(model, t, y, held)}", float(t))


@dataclass
class Stats:
    """Work counters: right-hand side evaluations, accepted and rejected steps; implicit
    integrators also count Jacobians, LU factorisations and Newton iterations."""

    nfev: int = 0
    steps: int = 0
    rejected: int = 0
    njev: int = 0
    nlu: int = 0
    newton_iters: int = 0

    def add(self, arr) -> None:
        self.nfev += int(arr[0])
        self.steps += int(arr[1])
        self.rejected += int(arr[2])
        if len(arr) > 5:
            self.njev += int(arr[3])
            self.nlu += int(arr[4])
            self.newton_iters += int(arr[5])


@dataclass
class Integrator:
    """Base class: ``integrate(model, y0, t0, t_out, held)`` -> states (len(t_out), size)."""

    name: str = ""
    rtol: float = DEFAULT_RTOL
    atol: float | None = None
    step: float = DEFAULT_STEP
    stats: Stats = field(default_factory=Stats)
    order: int = 0
    adaptive: bool = True

    @property
    def abs_tol(self) -> float:
        return self.rtol if self.atol is None else self.atol

    def describe(self) -> str:
        """A short settings string for logs and reports."""
        if self.adaptive:
            return f"{self.name} rtol={self.rtol:g} atol={self.abs_tol:g}"
        return f"{self.name} step={self.step:g}"

    def integrate(self, model, y0, t0, t_out, held=None):
        raise NotImplementedError

    @staticmethod
    def _breaks(model, t0, t_end) -> np.ndarray:
        b = [x for x in model.scene.load_breakpoints() if t0 < x < t_end]
        return np.array(sorted(b), dtype=float)

    @staticmethod
    def _prepare(model, y0, t_out, held):
        t_out = np.atleast_1d(np.asarray(t_out, dtype=float))
        if t_out.size == 0:
            raise ValueError("t_out: at least one output time is needed")
        if np.any(np.diff(t_out) < 0):
            raise ValueError("t_out: output times must be sorted")
        held = model._held(held)
        return np.ascontiguousarray(y0, dtype=float), t_out, held


@dataclass
class JitDop853(Integrator):
    """Compiled adaptive DOP853; carries its step size from one call to the next."""

    name: str = "dop853-jit"
    order: int = 8
    max_step: float = np.inf
    max_steps: int = 10_000_000
    _h: float = 0.0

    def _driver(self, model):
        return erk.DOP853[model.name]

    def integrate(self, model, y0, t0, t_out, held=None):
        y0, t_out, held = self._prepare(model, y0, t_out, held)
        Y = np.empty((t_out.size, y0.size))
        stats = np.zeros(6, dtype=np.int64)
        y, t, h, status = self._driver(model)(
            model.chain, model.extra, model.loads, held, y0, float(t0), t_out,
            self._breaks(model, t0, t_out[-1]), self.rtol, self.abs_tol, self._h,
            self.max_step, self.max_steps, Y, stats)
        self.stats.add(stats)
        if status != erk.STATUS_OK:
            raise _failure(model, erk.STATUS_TEXT[status], t, y, held)
        self._h = h
        return Y

    def reset(self) -> None:
        self._h = 0.0


@dataclass
class JitRadau(JitDop853):
    """Compiled implicit Radau IIA (order 5) for stiff problems (:mod:`rod_sim.core.radau`);
    carries its step size and, for the same model, its workspace (Jacobian) from one call to
    the next, so that stepping period by period does not rebuild the Jacobian every period."""

    name: str = "radau-jit"
    order: int = 5
    _work: tuple | None = field(default=None, repr=False)
    _work_model: object = field(default=None, repr=False)

    def _driver(self, model):
        if self._work is None or self._work_model is not model:
            self._work = radau.radau_workspace(model.state_size)
            self._work_model = model
        work, run = self._work, radau.RADAU_WORK[model.name]
        return lambda *args: run(*args, work)

    def integrate(self, model, y0, t0, t_out, held=None):
        try:
            return super().integrate(model, y0, t0, t_out, held)
        except BaseException:
            self._work = self._work_model = None        # no half-updated history kept
            raise

    def reset(self) -> None:
        super().reset()
        self._work = self._work_model = None


@dataclass
class JitFixedStep(Integrator):
    """Compiled fixed-step explicit Runge-Kutta (euler, rk2 = Heun, rk4)."""

    adaptive: bool = False

    def __post_init__(self):
        A, b, c, order = _TABLEAUX[self.name]
        self._tableau = (np.ascontiguousarray(A), b, c)
        self.order = order
        if not self.step > 0:
            raise ValueError(f"step: must be > 0 (got {self.step!r})")

    def integrate(self, model, y0, t0, t_out, held=None):
        y0, t_out, held = self._prepare(model, y0, t_out, held)
        Y = np.empty((t_out.size, y0.size))
        stats = np.zeros(3, dtype=np.int64)
        A, b, c = self._tableau
        y, t, status = erk.FIXED[model.name](model.chain, model.extra, model.loads, held,
                                     y0, float(t0), t_out, self._breaks(model, t0, t_out[-1]),
                                     float(self.step), A, b, c, Y, stats)
        self.stats.add(stats)
        if status != erk.STATUS_OK:
            raise _failure(model, erk.STATUS_TEXT[status], t, y, held)
        return Y


STALL_CALLS = 20_000
"""scipy paths: right-hand side calls without progress in time before giving up."""


class _NonFinite(Exception):
    """Raised inside a scipy right-hand side call that meets a non-finite state/derivative
    (or makes no progress in time)."""

    def __init__(self, t, y, reason):
        super().__init__(reason)
        self.t, self.y, self.reason = float(t), y, reason


@dataclass
class ScipyIntegrator(Integrator):
    """scipy.integrate.solve_ivp with one of its methods, restarted at load breakpoints.
    ``max_nfev`` (0 = no limit) bounds the right-hand side evaluations of one call."""

    max_nfev: int = 0

    def __post_init__(self):
        self.order = {"RK45": 5, "DOP853": 8, "Radau": 5, "BDF": 5, "LSODA": 12}[self.name]

    def integrate(self, model, y0, t0, t_out, held=None):
        y0, t_out, held = self._prepare(model, y0, t_out, held)
        Y = np.empty((t_out.size, y0.size))
        edges = [float(t0), *self._breaks(model, t0, t_out[-1]), float(t_out[-1])]
        kernel, chain, extra, loads = model.kernel, model.chain, model.extra, model.loads
        y = y0
        done = 0
        calls = [0]                              # right-hand side evaluations of this call
        while done < t_out.size and t_out[done] <= t0:
            Y[done] = y0
            done += 1
        for a, b in zip(edges[:-1], edges[1:]):
            if b <= a:
                continue
            side = 0.5 * (a + b)

            progress = [a, 0]                    # latest time seen, calls since it grew

            def fun(t, yy, side=side, progress=progress):
                calls[0] += 1
                if self.max_nfev and calls[0] > self.max_nfev:
                    raise _NonFinite(t, np.array(yy), erk.STATUS_TEXT[erk.STATUS_MAX_STEPS]
                                     + f" (more than {self.max_nfev} derivative evaluations)")
                out = np.empty(yy.shape[0])
                kernel(t, yy, chain, extra, loads, held, side, out)
                if not (np.all(np.isfinite(yy)) and np.all(np.isfinite(out))):
                    raise _NonFinite(t, np.array(yy), erk.STATUS_TEXT[erk.STATUS_NONFINITE])
                if t > progress[0]:
                    progress[0], progress[1] = t, 0
                else:
                    progress[1] += 1
                    if progress[1] > STALL_CALLS:    # e.g. LSODA looping at one time
                        raise _NonFinite(t, np.array(yy), f"no progress in time after "
                                         f"{STALL_CALLS} derivative evaluations (it diverges)")
                return out

            stop = done
            while stop < t_out.size and t_out[stop] <= b:
                stop += 1
            try:
                with np.errstate(all="ignore"):
                    sol = solve_ivp(fun, (a, b), y, method=self.name, rtol=self.rtol,
                                    atol=self.abs_tol, dense_output=stop > done)
            except _NonFinite as exc:
                raise _failure(model, exc.reason, exc.t, exc.y, held) from None
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                raise _failure(model, f"{self.name} failed ({type(exc).__name__}: {exc})",
                               a, y, held) from None
            self.stats.nfev += sol.nfev
            self.stats.steps += max(sol.t.size - 1, 0)
            if sol.status != 0 or not np.all(np.isfinite(sol.y)):
                t_fail = float(sol.t[-1]) if sol.t.size else a
                y_fail = sol.y[:, -1] if sol.t.size else y
                raise _failure(model, sol.message if sol.status != 0 else
                               erk.STATUS_TEXT[erk.STATUS_NONFINITE], t_fail, y_fail, held)
            if stop > done:
                Y[done:stop] = sol.sol(t_out[done:stop]).T
            y = sol.y[:, -1]
            done = stop
        return Y




def make_integrator(name: str = "dop853-jit", *, rtol: float | None = None,
                    atol: float | None = None, step: float | None = None) -> Integrator:
    """The integrator called ``name`` with the given tolerances or fixed step [s]."""
    rtol = DEFAULT_RTOL if rtol is None else float(rtol)
    if not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol: must be a positive number (got {rtol!r})")
    if atol is not None and not (np.isfinite(atol) and atol > 0):
        raise ValueError(f"atol: must be a positive number (got {atol!r})")
    if name == "dop853-jit":
        return JitDop853(rtol=rtol, atol=atol)
    if step is not None and not (np.isfinite(step) and step >= MIN_STEP):
        raise ValueError(f"step: must be a number >= {MIN_STEP:g} s (got {step!r})")
    if name == "radau-jit":
        return JitRadau(rtol=rtol, atol=atol)
    if name in _TABLEAUX:
        return JitFixedStep(name=name, step=DEFAULT_STEP if step is None else float(step))
    if name in SCIPY_METHODS:
        return ScipyIntegrator(name=name, rtol=rtol, atol=atol)
    raise ValueError(f"integrator: unknown integrator {name!r} (choose from {', '.join(INTEGRATORS)})")
