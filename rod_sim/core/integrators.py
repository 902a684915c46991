"""Time steppers behind one protocol, registered by name (:data:`INTEGRATORS`), and the one
integration driver. An integrator is immutable settings; what it carries between calls (step
size, radau's workspace, work counters) is a :class:`Carry` owned by the ``Simulator``.

:func:`drive` is the only integration path (``Simulator``, and through it simulate, the node,
compare, bench, advise and sweep): it asks an integrator to ``advance`` the model in the
current mode through the output times until a terminal hinge event (a latch), applies the
latch (mode change + impulsive velocity projection, :mod:`rod_sim.core.hinges`) and goes on.
Every integrator restarts at the scene's load breakpoints (computed once, in :func:`drive`)
and locates hinge events (latches, stop contact begin/end):

- ``dop853-jit`` (default): compiled adaptive Dormand-Prince 8(5,3) with dense output.
- ``radau-jit``: compiled implicit Radau IIA of order 5 (stiff scenes: the full model,
  stiff rods, stops), Newton systems solved in O(n) (:mod:`rod_sim.core.newton`),
  collocation dense output.
- ``rk4``, ``rk2``, ``euler``: compiled fixed-step explicit Runge-Kutta (order 4, 2, 1);
  the step is ``step`` [s] at most, intervals are split into equal substeps.
- ``RK45``, ``DOP853``, ``Radau``, ``BDF``, ``LSODA``: scipy's ``solve_ivp`` methods.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .scipy_tables import light_dop853_tables

with light_dop853_tables():     # erk's tables without scipy.integrate's import
    from . import erk, hinges, radau
from .kernels import Control, Events, Output, Problem, Span, ground_angle



def _solve_ivp():
    """scipy's ``solve_ivp``, imported when a scipy method first runs (importing
    ``scipy.integrate`` costs ~1 s, which a start with the compiled integrators never needs)."""
    from scipy.integrate import solve_ivp

    return solve_ivp


DEFAULT_RTOL = 1e-8
DEFAULT_STEP = 1e-3
MIN_STEP = 1e-9         # [s]: smallest fixed step (the step count of an interval stays exact)
CALL_WORK = 1_000_000
"""Work budget of one compiled driver call, in state components times right-hand side
evaluations: a call returns to Python (``drive`` calls it again) after CALL_WORK / state size
evaluations (at least :data:`MIN_CALL_RHS`), every ~0.05 s (DOP853) to ~0.15 s (Radau) for the
stiff deployment scene, so that Ctrl-C and SIGTERM are seen within that time in every
integrator. Scenes that need fewer evaluations per call than that never notice it."""
MIN_CALL_RHS = 200
COLLAPSE_STEP = 1e-12
"""[s] (times max(1, |t|)): a compiled call that uses its whole work budget with a mean
accepted step below this has a collapsed step size (10^12 steps per simulated second):
``drive`` stops with IntegrationError instead of spinning."""
from .names import INTEGRATOR_NAMES, SCIPY_METHODS

_TABLEAUX = {
    "euler": (np.zeros((1, 1)), np.array([1.0]), np.array([0.0]), 1),
    "rk2": (np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.5, 0.5]), np.array([0.0, 1.0]), 2),
    "rk4": (np.array([[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0],
                      [0.0, 0.0, 1.0, 0.0]]),
            np.array([1.0, 2.0, 2.0, 1.0]) / 6.0, np.array([0.0, 0.5, 0.5, 1.0]), 4),
}

_SCIPY_ORDERS = {"RK45": 5, "DOP853": 8, "Radau": 5, "BDF": 5, "LSODA": 12}


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


_BASE = (("base x", "m"), ("base y", "m"), ("base psi", "rad"), ("wheel angle", "rad"))


def state_component(model, i: int) -> tuple[str, int, str]:
    """(quantity, rod 1..n, unit) of component ``i`` of the model's state vector (a free
    base's coordinates: rod 0)."""
    dof, chains = model.dof, model.dof_per_rod * model.n
    j = i % dof
    if j >= chains:
        name, unit = _BASE[j - chains]
        return (name, 0, unit) if i < dof else (name + " rate", 0, unit + "/s")
    group = j // model.n + (model.dof_per_rod if i >= dof else 0)
    name, unit = _GROUPS[model.dof_per_rod][group]
    return name, j % model.n + 1, unit


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
    """Work counters: right-hand side evaluations, accepted and rejected steps; dop853-jit
    also counts its stability-limited accepted steps (``stiff_steps``, Hairer's test,
    :data:`rod_sim.core.erk.STIFF_H_LAMBDA`), implicit integrators their Jacobians, LU
    factorisations and Newton iterations."""

    nfev: int = 0
    steps: int = 0
    rejected: int = 0
    njev: int = 0
    nlu: int = 0
    newton_iters: int = 0
    stiff_steps: int = 0

    def add(self, arr) -> None:
        """Add a compiled driver's counters: [nfev, steps, rejected], then [stiff_steps]
        (dop853-jit, 4 entries) or [njev, nlu, newton_iters] (radau-jit, 6 entries)."""
        self.nfev += int(arr[0])
        self.steps += int(arr[1])
        self.rejected += int(arr[2])
        if len(arr) == 4:
            self.stiff_steps += int(arr[3])
        if len(arr) > 5:
            self.njev += int(arr[3])
            self.nlu += int(arr[4])
            self.newton_iters += int(arr[5])

    def stiff_share(self) -> float:
        """Share of the accepted steps that were stability-limited (dop853-jit's count; 0
        before the first step and for the other integrators)."""
        return self.stiff_steps / self.steps if self.steps else 0.0


@dataclass
class Stretch:
    """What one ``Integrator.advance`` call did: states ``Y`` at the first ``written`` output
    times, the state ``y`` reached at ``t`` [s], the event it stopped at (``event``: its
    index in the plan's table, None: none) and the located crossing (t (k,), code (k,) =
    2 e + rising for event e, states (k, size); k = 1 at an event, else 0)."""

    Y: np.ndarray
    written: int
    y: np.ndarray
    t: float
    event: int | None
    crossings: tuple
    exhausted: bool = False     # the call's work budget ran out (call again from (t, y))


def _event_buffers(plan, size: int):
    cap = 64 + 2 * plan.events.hinge.size
    return Events(*plan.events, np.empty(cap), np.empty(cap, dtype=np.int64),
                  np.empty((cap, size)), np.zeros(1, dtype=np.int64))


def _no_crossings() -> tuple:
    """The ``crossings`` of a :class:`Stretch` that located none."""
    return (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 0)))


def _stretch(model, plan, Y, written, y, t, status, ev) -> Stretch:
    k = int(ev.count[0])
    crossings = (ev.t[:k].copy(), ev.code[:k].copy(), ev.y[:k].copy())
    event = int(ev.code[k - 1]) // 2 if status == erk.STATUS_EVENT else None
    return Stretch(Y, int(written), np.array(y), float(t), event, crossings,
                   status == erk.STATUS_BUDGET)


def _compiled(fn, *args):
    """Call a compiled driver. A signal handler that raises (Ctrl-C: KeyboardInterrupt) while
    numba's machine code runs a Python helper (it unpickles constants on entry) surfaces as
    SystemError "returned a result with an exception set" caused by the handler's exception:
    re-raise that exception, so that an interrupt is an interrupt."""
    try:
        return fn(*args)
    except SystemError as err:
        if err.__cause__ is not None and "exception set" in str(err):
            raise err.__cause__ from None
        raise


_RESUMABLE = (erk.STATUS_OK, erk.STATUS_EVENT, erk.STATUS_EVENTS_FULL, erk.STATUS_BUDGET)


def call_budget(size: int) -> int:
    """Right-hand side evaluations one compiled driver call may spend (:data:`CALL_WORK`)."""
    return max(MIN_CALL_RHS, CALL_WORK // max(1, int(size)))


@dataclass
class Carry:
    """What an integrator carries from one call to the next for one simulator (the
    init/step pattern: the settings are the :class:`Integrator`, this is its state, owned by
    the ``Simulator``): work counters ``stats``, the step size ``h`` [s] to try next (0:
    choose one), radau's workspace ``work`` (its Jacobian and Newton matrices; None: build it)
    and ``steps0``, ``stats.steps`` when the current drive began."""

    stats: Stats = field(default_factory=Stats)
    h: float = 0.0
    work: tuple | None = field(default=None, repr=False)
    steps0: int = 0

    def restart(self) -> None:
        """Forget the carried step size and workspace (a new run); the counters stay."""
        self.h, self.work = 0.0, None


@dataclass(frozen=True)
class Integrator:
    """Base class of the integrators' *settings* (immutable; change one with
    ``dataclasses.replace``). ``init(model)`` -> :class:`Carry`;
    ``advance(carry, model, plan, y0, t0, t_out, held, breaks)`` -> :class:`Stretch`."""

    name: str = ""
    rtol: float = DEFAULT_RTOL
    atol: float | None = None
    step: float = DEFAULT_STEP
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

    def init(self, model) -> Carry:
        """A fresh carried state for stepping ``model``."""
        return Carry()

    def advance(self, carry: Carry, model, plan, y0, t0, t_out, held, breaks) -> Stretch:
        """Integrate from (t0, y0) in the mode of ``plan`` (with the caller's scratch bound
        in: ``ModelData.plan``) through the sorted ``t_out`` until the end, a terminal event
        or the call's work budget, updating ``carry``. Raises IntegrationError."""
        raise NotImplementedError

    def integrate(self, model, y0, t0, t_out, held=None, mode=None, events=None,
                  carry: Carry | None = None):
        """States (len(t_out), state_size) at the sorted times t_out [s] from (t0, y0) in
        ``mode`` (see :func:`drive`; events go to ``events`` if given, work to ``carry``)."""
        return drive(model, self, y0, t0, t_out, held, mode,
                     [] if events is None else events, carry=carry).Y

    def _steps_left(self, carry: Carry) -> int:
        """Accepted steps the current drive may still take (``max_steps`` bounds a drive)."""
        return max(1, int(getattr(self, "max_steps", 1 << 62))
                   - (carry.stats.steps - carry.steps0))


@dataclass(frozen=True)
class JitDop853(Integrator):
    """Compiled adaptive DOP853 (:func:`rod_sim.core.erk.dop853_run`); the step size is
    carried from one call to the next. ``max_step`` [s] bounds a step, ``max_steps`` the
    accepted steps of one drive."""

    name: str = "dop853-jit"
    order: int = 8
    max_step: float = np.inf
    max_steps: int = 10_000_000

    def advance(self, carry, model, plan, y0, t0, t_out, held, breaks) -> Stretch:
        Y = np.empty((t_out.size, y0.size))
        stats = np.zeros(4, dtype=np.int64)
        ev = _event_buffers(plan, y0.size)
        y, t, h, status, written = _compiled(
            model.compiled.dop853, Problem(model.chain, plan.extra, model.loads, held),
            Span(y0, float(t0), t_out, breaks), self._control(carry, y0.size),
            Output(Y, stats, ev))
        return self._finish(carry, model, plan, held, Y, stats, ev, y, t, h, status, written)

    def _control(self, carry: Carry, size: int) -> Control:
        return Control(float(self.rtol), float(self.abs_tol), float(carry.h),
                       float(self.max_step), int(self._steps_left(carry)), call_budget(size))

    @staticmethod
    def _finish(carry, model, plan, held, Y, stats, ev, y, t, h, status, written) -> Stretch:
        """Account a compiled run's stats, raise on failure, carry the step size (a fresh
        start after a latch's impact) and wrap the result as a :class:`Stretch`."""
        carry.stats.add(stats)
        if status not in _RESUMABLE:
            raise _failure(model, erk.STATUS_TEXT[status] + f" (t = {t:.9g} s, step {h:.3g} s)",
                           t, y, held)
        latch = status == erk.STATUS_EVENT and \
            plan.events.kind[int(ev.code[0]) // 2] == hinges.EV_LATCH
        carry.h = 0.0 if latch else h          # a fresh start after an impact
        return _stretch(model, plan, Y, written, y, t, status, ev)


@dataclass(frozen=True)
class JitRadau(JitDop853):
    """Compiled implicit Radau IIA (order 5) for stiff problems (:mod:`rod_sim.core.radau`);
    the step size and the workspace (Jacobian, Newton matrices) are carried from one call to
    the next, so that stepping period by period does not rebuild the Jacobian every period."""

    name: str = "radau-jit"
    order: int = 5

    def advance(self, carry, model, plan, y0, t0, t_out, held, breaks) -> Stretch:
        Y = np.empty((t_out.size, y0.size))
        stats = np.zeros(6, dtype=np.int64)
        ev = _event_buffers(plan, y0.size)
        if carry.work is None:
            carry.work = radau.chain_radau_workspace(model)
        try:
            y, t, h, status, written = _compiled(
                model.compiled.radau, Problem(model.chain, plan.extra, model.loads, held),
                Span(y0, float(t0), t_out, breaks), self._control(carry, y0.size),
                Output(Y, stats, ev), carry.work)
        except BaseException:
            carry.work = None                    # no half-updated history kept
            raise
        if status not in _RESUMABLE:
            carry.work = None
        return self._finish(carry, model, plan, held, Y, stats, ev, y, t, h, status, written)


@dataclass(frozen=True)
class JitFixedStep(Integrator):
    """Compiled fixed-step explicit Runge-Kutta (euler, rk2 = Heun, rk4); hinge events are
    located on each step's cubic Hermite interpolant (erk.fixed_run)."""

    adaptive: bool = False

    def __post_init__(self):
        if self.name not in _TABLEAUX:
            raise ValueError(f"integrator: {self.name!r} is not a fixed-step method")
        object.__setattr__(self, "order", _TABLEAUX[self.name][3])
        if not self.step > 0:
            raise ValueError(f"step: must be > 0 (got {self.step!r})")

    def advance(self, carry, model, plan, y0, t0, t_out, held, breaks) -> Stretch:
        Y = np.empty((t_out.size, y0.size))
        stats = np.zeros(3, dtype=np.int64)
        A, b, c, _ = _TABLEAUX[self.name]
        ev = _event_buffers(plan, y0.size)
        control = Control(0.0, 0.0, 0.0, float(self.step), 0, call_budget(y0.size))
        y, t, status, written = _compiled(
            model.compiled.fixed, Problem(model.chain, plan.extra, model.loads, held),
            Span(y0, float(t0), t_out, breaks), control, (A, b, c), Output(Y, stats, ev))
        carry.stats.add(stats)
        if status not in _RESUMABLE:
            raise _failure(model, erk.STATUS_TEXT[status], t, y, held)
        return _stretch(model, plan, Y, written, y, t, status, ev)


STALL_CALLS = 20_000
"""scipy paths: right-hand side calls without progress in time before giving up."""


class _NonFinite(Exception):
    """Raised inside a scipy right-hand side call that meets a non-finite state/derivative
    (or makes no progress in time)."""

    def __init__(self, t, y, reason):
        super().__init__(reason)
        self.t, self.y, self.reason = float(t), y, reason


def _scipy_events(plan):
    """solve_ivp event functions (terminal) for the plan's table: latches only (stops are
    refused, see ScipyIntegrator); at a hinge 0 on a prescribed base less p(t) of its psi
    (the table's ``ground``, by the kernels' :func:`~rod_sim.core.kernels.ground_angle`)."""
    fns = []
    ground = plan.events.ground
    moving = ground[0] != 0.0
    for h, angle, o in zip(plan.events.hinge, plan.events.angle, plan.events.other):
        h, o = int(h), int(o)
        if o < 0 and moving:
            f = (lambda t, y, h=h, a=angle: y[h] - ground_angle(ground, t) - a)
        elif o < 0:
            f = (lambda t, y, h=h, a=angle: y[h] - a)
        else:
            f = (lambda t, y, h=h, o=o, a=angle: y[h] - y[o] - a)
        f.terminal = True
        fns.append(f)
    return fns


@dataclass(frozen=True)
class ScipyIntegrator(Integrator):
    """scipy.integrate.solve_ivp with one of its methods on the compiled right-hand side,
    restarted at load breakpoints; latches through solve_ivp's event location. Scenes with
    stops are refused (ValueError): after a contact ends, solve_ivp's first step from the
    root can leave the stop and come back unseen, and the hinge then passes through it
    (measured: scipy DOP853 missed 11 of 25 contact events of a 2 s test and let the hinge
    reach 1.23 rad past a 0.2 rad stop). ``max_nfev`` (0 = no limit) bounds the right-hand
    side evaluations of one call."""

    max_nfev: int = 0

    def __post_init__(self):
        object.__setattr__(self, "order", _SCIPY_ORDERS[self.name])

    def advance(self, carry, model, plan, y0, t0, t_out, held, breaks) -> Stretch:
        Y = np.empty((t_out.size, y0.size))
        edges = [float(t0), *[b for b in breaks if t0 < b < t_out[-1]], float(t_out[-1])]
        kernel, chain, extra, loads = model.kernel, model.chain, plan.extra, model.loads
        if np.any(plan.events.kind != hinges.EV_LATCH):
            raise ValueError(f"integrator: {self.name} cannot follow hinge stop contacts "
                             "(hinges.stop); use dop853-jit, radau-jit, rk4, rk2 or euler")
        fns = _scipy_events(plan) or None
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
                # scipy's finite-difference Jacobian (Radau, BDF) passes columns of a 2-D
                # array: a contiguous copy keeps one compiled specialisation of the kernel
                # (a strided one compiled the whole kernel again, 66 s of CPU per model)
                yy = np.ascontiguousarray(yy)
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

            try:
                with np.errstate(all="ignore"):
                    sol = _solve_ivp()(fun, (a, b), y, method=self.name, rtol=self.rtol,
                                    atol=self.abs_tol, dense_output=True, events=fns)
            except _NonFinite as exc:
                raise _failure(model, exc.reason, exc.t, exc.y, held) from None
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                raise _failure(model, f"{self.name} failed ({type(exc).__name__}: {exc})",
                               a, y, held) from None
            carry.stats.nfev += sol.nfev
            carry.stats.steps += max(sol.t.size - 1, 0)
            if sol.status == -1 or not np.all(np.isfinite(sol.y)):
                t_fail = float(sol.t[-1]) if sol.t.size else a
                y_fail = sol.y[:, -1] if sol.t.size else y
                raise _failure(model, sol.message if sol.status == -1 else
                               erk.STATUS_TEXT[erk.STATUS_NONFINITE], t_fail, y_fail, held)
            t_end = float(sol.t[-1])
            stop = done
            while stop < t_out.size and t_out[stop] <= t_end:
                stop += 1
            if stop > done:
                Y[done:stop] = sol.sol(t_out[done:stop]).T
            done = stop
            y = sol.y[:, -1].copy()
            if sol.status == 1:
                first = None
                for e, ts in enumerate(sol.t_events):
                    if ts.size and ts[-1] == t_end and (
                            first is None or plan.events.kind[e] == hinges.EV_LATCH):
                        first = e
                h = int(plan.events.hinge[first])
                rising = model.hinge_rates(y, t_end)[h] > 0.0
                crossing = (np.array([t_end]), np.array([2 * first + int(rising)]), y[None, :])
                return Stretch(Y, done, y, t_end, first, crossing)
        return Stretch(Y, done, y, float(t_out[-1]), None, self._found())

    @staticmethod
    def _found():
        return _no_crossings()


@dataclass(frozen=True, eq=False)
class DriveResult:
    """What :func:`drive` returns: states ``Y`` (N, size) and fired latches ``modes`` (N, n)
    at the output times; at the end, the latches ``mode`` (n,), the state ``y`` (size,)
    (after the impact when a latch fell on the last time) and the stop contacts ``contact``
    (n,) int8."""

    Y: np.ndarray
    modes: np.ndarray
    mode: np.ndarray
    y: np.ndarray
    contact: np.ndarray


def drive(model, integrator: Integrator, y0, t0: float, t_out, held=None, mode=None,
          events: list | None = None, contact=None, carry: Carry | None = None,
          data=None) -> DriveResult:
    """The integration driver: states at the sorted times ``t_out`` [s] from (t0, y0) with
    held nodal forces (n, 2) [N], the latches ``mode`` (n,) bool already fired (None: none)
    and the stop contacts ``contact`` (n,) int (None: as implied by y0), appending
    :class:`~rod_sim.core.hinges.HingeEvent` s to ``events`` at their simulated times.
    Every located event ends the integrator's stretch: a latch locks the hinge and projects
    the velocity (outputs at exactly that time are the state before the impact), a stop
    crossing switches the hinge's contact law; then the integration restarts there. A
    compiled integrator returns after a bounded amount of work (:data:`CALL_WORK`) and is
    called again, so that signals (Ctrl-C) are handled within a fraction of a second; a call
    that spent its whole budget with a mean step below :data:`COLLAPSE_STEP` raises
    IntegrationError (the step size collapsed). ``carry`` is the integrator's state from
    the previous call (step size, workspace, counters; None: a fresh one) and is updated;
    ``data`` the caller's scratch for the model's kernels (``model.new_data()``; None: a
    fresh one). Raises IntegrationError, ValueError (bad output times)."""
    t_out = np.atleast_1d(np.asarray(t_out, dtype=float))
    if t_out.size == 0:
        raise ValueError("t_out: at least one output time is needed")
    if t_out.size > 1 and (t_out[1:] < t_out[:-1]).any():
        raise ValueError("t_out: output times must be sorted")
    held = model._held(held)
    events = [] if events is None else events
    mode = np.zeros(model.n, dtype=bool) if mode is None else np.array(mode, dtype=bool)
    y = np.ascontiguousarray(y0, dtype=float).copy()
    contact = model.contact_state(y, t0) if contact is None else \
        np.array(contact, dtype=np.int8)
    t = float(t0)
    Y = np.empty((t_out.size, y.size))
    modes = np.empty((t_out.size, model.n), dtype=bool)
    done = 0
    while done < t_out.size and t_out[done] <= t:
        Y[done], modes[done] = y, mode
        done += 1
    mode, y = _latch(model, mode, t, y, None, events)
    breaks = np.array([b for b in model.scene.breakpoints() if t < b < t_out[-1]], dtype=float)
    carry = integrator.init(model) if carry is None else carry
    data = model.new_data() if data is None else data
    carry.steps0 = carry.stats.steps
    while done < t_out.size:
        plan = data.plan(mode, contact)
        steps0, t0_call = carry.stats.steps, t
        s = integrator.advance(carry, model, plan, y, t, t_out[done:], held, breaks)
        Y[done:done + s.written] = s.Y[:s.written]
        modes[done:done + s.written] = mode
        done += s.written
        y, t = np.ascontiguousarray(s.y, dtype=float), s.t
        carry.t = t
        if s.exhausted:
            steps = carry.stats.steps - steps0
            mean = (t - t0_call) / steps if steps else 0.0
            if mean < COLLAPSE_STEP * max(1.0, abs(t)):
                raise IntegrationError(
                    f"the step size collapsed: {steps} steps of mean {mean:.3g} s (< "
                    f"{COLLAPSE_STEP:g} s) up to t = {t:.9g} s; the scene is too stiff or not "
                    f"smooth for {integrator.describe()}", t)
        if s.event is None:
            continue
        h, kind = int(plan.events.hinge[s.event]), int(plan.events.kind[s.event])
        if kind == hinges.EV_LATCH:
            mode, y = _latch(model, mode, t, y, h, events)
            contact[h] = 0
            continue
        rising = bool(s.crossings[1][-1] % 2)
        name, stop = hinges.crossing_kind(kind, rising)
        contact[h] = (1 if stop == "upper" else -1) if name == "stop_contact_begin" else 0
        events.append(hinges.HingeEvent(t, name, h, {
            "stop": stop, "angle": float(model.hinge_angles(y, t)[h]),
            "rate": float(model.hinge_rates(y, t)[h])}))
    return DriveResult(Y, modes, mode, y, contact)


def _latch(model, mode, t: float, y, located: int | None, events: list):
    """Lock the unlocked hinges whose latch angle is reached at (t, y): the located one
    (``located``) and any other within 1e-9 rad; at the start of a drive (``located``
    None) only exact hits. Returns (mode, y with the velocity projected)."""
    if not model.has_latches:
        return mode, y
    s = model.scene
    theta = model.hinge_angles(y, t)
    gap = np.abs(theta - s.latch_angle)
    free = ~hinges.locked_hinges(s, mode) & np.isfinite(s.latch_angle)
    if located is None:
        hit = free & (gap == 0.0)
    else:
        hit = free & (gap <= max(1e-9, 1e-9 * float(np.max(np.abs(theta)))))
        hit[located] = free[located]
    if not hit.any():
        return mode, y
    rate = model.hinge_rates(y, t)
    new_mode = mode | hit
    y1 = model.project_velocity(y, new_mode, t)
    loss = model.kinetic_energy(t, y) - model.kinetic_energy(t, y1)
    # one impact latches every hinge of ``hit`` at once (the two wings of a symmetric bus):
    # its loss is shared out so that the events' losses sum to the impact's
    together = [int(h) for h in np.flatnonzero(hit)]
    for h in together:
        events.append(hinges.HingeEvent(t, "latch", h, {
            "angle": float(theta[h]), "rate": float(rate[h]),
            "kinetic_energy_loss": float(loss) / len(together),
            "impact_kinetic_energy_loss": float(loss), "impact_hinges": together}))
    return new_mode, y1


def _adaptive(cls):
    """Factory of an adaptive integrator class (no fixed step)."""
    def make(name, rtol, atol, step):
        return cls(name=name, rtol=rtol, atol=atol)
    return make


def _fixed(name, rtol, atol, step):
    return JitFixedStep(name=name, step=DEFAULT_STEP if step is None else float(step))


INTEGRATORS = {"dop853-jit": _adaptive(JitDop853), "radau-jit": _adaptive(JitRadau),
               **{name: _fixed for name in _TABLEAUX},
               **{name: _adaptive(ScipyIntegrator) for name in SCIPY_METHODS}}
"""The integrator registry: name -> factory (name, rtol, atol, step) -> Integrator. Its keys
are :data:`rod_sim.core.names.INTEGRATOR_NAMES` (a test checks), which the command line and
the node's parameters read without importing numba."""


def make_integrator(name: str = "dop853-jit", *, rtol: float | None = None,
                    atol: float | None = None, step: float | None = None) -> Integrator:
    """The integrator called ``name`` with the given tolerances or fixed step [s] (a fixed
    step applies to the fixed-step methods only)."""
    rtol = DEFAULT_RTOL if rtol is None else float(rtol)
    if not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol: must be a positive number (got {rtol!r})")
    if atol is not None and not (np.isfinite(atol) and atol > 0):
        raise ValueError(f"atol: must be a positive number (got {atol!r})")
    if step is not None and not (np.isfinite(step) and step >= MIN_STEP):
        raise ValueError(f"step: must be a number >= {MIN_STEP:g} s (got {step!r})")
    try:
        factory = INTEGRATORS[name]
    except (KeyError, TypeError):
        raise ValueError(f"integrator: unknown integrator {name!r} "
                         f"(choose from {', '.join(INTEGRATOR_NAMES)})") from None
    return factory(name, rtol, atol, step)
