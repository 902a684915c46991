"""What numba is compiling, why and for how long: one notice per compile, then progress.

A compiled driver that is not in numba's on-disk cache (the first use after an install or a
change of ``rod_sim/core``; ``make warm`` compiles only what ``make demo`` needs) compiles on
first use, which takes from a few seconds to a minute or more of CPU time. numba fires a
``numba:compile`` event only on a cache miss (loading from the cache fires none), so the
:class:`CompileWatch` listening to it says something only when a compile really happens:

- after :data:`NOTICE_AFTER_S` of a compile, one notice: what compiles, why, and how long it
  takes (the CPU seconds measured for it, :data:`COMPILE_CPU_S`, scaled to wall seconds by
  the machine's load);
- every :data:`TICK_S` after that, a progress line: elapsed and an estimate of the time left
  (the CPU seconds still to go at the CPU rate the compile has had so far);
- at the end (only if the notice was printed), how long it took.

Only the outermost compile of a thread is reported (a driver compiles its kernels inside it).
Every line contains :data:`COMPILE_NOTICE` (tests drop these timed lines by it).
"""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

COMPILE_NOTICE = "compiling"
"""Contained in every line the watch prints."""
NOTICE_AFTER_S = 2.0
"""[s] of wall time a compile runs before the notice (a cache load takes ~0.3 s: never)."""
TICK_S = 8.0
"""[s] between progress lines (the issue asks for one at least every 10 s)."""

COMPILE_CPU_S = {
    "dop853_full": 80.0, "dop853_reduced": 80.0, "dop853_rigid": 80.0,
    "radau_full": 140.0, "radau_reduced": 135.0, "radau_rigid": 135.0,
    "fixed_full": 66.0, "fixed_reduced": 66.0, "fixed_rigid": 66.0,
    "full_rhs": 66.0, "reduced_rhs": 66.0, "rigid_rhs": 66.0,
    "mass_times": 2.0, "load_forces": 1.0, "solve_with": 70.0,
}
"""Process CPU seconds to compile each compiled entry point from a cold cache, its model's
kernel included, on the 2-core development machine (numba 0.68, NUMBA_OPT 3). Measured
2026-11-27 on an idle machine, each entry point alone in a copy of the warm cache without its
files (`rod-sim simulate config/paper_example.yaml`, the model and integrator named): the
reduced dop853-jit driver with its kernel 79 s; with the kernel already cached (its
:data:`KERNEL_CPU_S` less) dop853-jit 29-31 s (reduced), 32 s (full), 27 s (rigid), the
fixed-step drivers 16 s (reduced), radau-jit 84 s (reduced) and 91 s (full); the figures
here are those plus :data:`KERNEL_CPU_S`. Earlier, not measured again: a kernel alone ~66 s
(scipy's Radau compiling it again for a strided state); the helpers a node's checks call
~1 s (mass_times: 1 s CPU, 3 s wall at load 7); the velocity projection of a scene with
locked hinges or latches (solve_with) ~70 s (~450 s wall at load 9)."""
KERNEL_CPU_S = 50.0
"""CPU seconds of an entry point's estimate that a later entry point of the same model in
the same process does not pay again (typing the model's kernel; measured: the reduced
dop853-jit driver 79 s cold, 29 s with its kernel cached)."""
UNKNOWN_CPU_S = 5.0
"""[s] CPU assumed for a function not in the table."""

_KINDS = {"dop853": "dop853-jit integrator", "radau": "radau-jit integrator",
          "fixed": "fixed-step integrators (rk4, rk2, euler)"}
_MODELS = ("full", "reduced", "rigid")


def describe(name: str) -> str:
    """What the compiled function ``name`` (a dispatcher's qualified name) is, in words."""
    kind, _, model = name.partition("_")
    if kind in _KINDS and model in _MODELS:
        return f"the {model} model's {_KINDS[kind]}"
    model, _, tail = name.partition("_")
    if tail == "rhs" and model in _MODELS:
        return f"the {model} model's right-hand side for scipy's solvers"
    if name == "solve_with":
        return "the velocity projection for locked hinges and latches"
    return f"the compiled function {name}"


def kernel_cached(name: str) -> bool:
    """True when the compiled entry point ``name`` (e.g. 'fixed_reduced') is a driver whose
    model kernel is compiled already, in this process or in numba's cache (then the driver
    does not type it again: :data:`KERNEL_CPU_S` less). Uses numba's cache internals; False
    when they are missing."""
    kind, _, model = name.partition("_")
    if kind not in _KINDS or model not in _MODELS:
        return False
    try:
        from rod_sim.core import kernels

        disp = getattr(kernels, f"{model}_rhs")
        return bool(disp.overloads) or bool(disp._cache._impl and
                                            disp._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 -- an estimate, never a failure
        return False


def _load_and_cores(load: float | None, cores: int | None) -> tuple[float, int]:
    if load is None:
        try:
            load = os.getloadavg()[0]
        except OSError:
            load = 0.0
    return load, cores or os.cpu_count() or 1


def cpu_inflation(load: float | None = None, cores: int | None = None) -> float:
    """How much more CPU time a compile takes on a busy machine than the idle figures of
    :data:`COMPILE_CPU_S` (shared caches and cores): 1 + 0.1 per unit of 1-minute load above
    the core count. Fitted to this session's runs at load 6-9 on 2 cores: rk4 15 s of CPU
    against 8 idle, the demo's 2 drivers 214 s against ~170, the full warm-up 1094 s
    against ~830."""
    load, cores = _load_and_cores(load, cores)
    return 1.0 + 0.1 * max(0.0, load - cores)


def load_slowdown(load: float | None = None, cores: int | None = None) -> float:
    """Wall seconds per CPU second of one single-threaded job at the 1-minute load average
    ``load`` (default: the machine's) on ``cores`` cores: max(1, (load + 1) / cores)."""
    load, cores = _load_and_cores(load, cores)
    return max(1.0, (load + 1.0) / cores)


@dataclass
class _Compile:
    """One outermost compile being watched."""

    name: str
    wall0: float
    cpu0: float
    estimate_cpu: float
    announced: bool = False
    last_line: float = 0.0
    depth: int = 1
    cached: bool = True
    extra: dict = field(default_factory=dict)


class CompileWatch:
    """Turns numba's compile events into notices passed to ``sink`` (one line each).
    ``clock`` (wall), ``cpu`` (process CPU), ``slowdown`` (wall per CPU second now) and
    ``table`` are injectable for tests; :meth:`poll` does the timed part and is called by
    the ticker thread :meth:`install` starts (or directly by a test)."""

    def __init__(self, sink: Callable[[str], None], *, after: float = NOTICE_AFTER_S,
                 every: float = TICK_S, clock=time.monotonic, cpu=time.process_time,
                 slowdown=load_slowdown, table: dict | None = None,
                 kernel_ready=kernel_cached, inflation=cpu_inflation):
        self.sink = sink
        self.after, self.every = after, every
        self.clock, self.cpu, self.slowdown = clock, cpu, slowdown
        self.table = COMPILE_CPU_S if table is None else table
        self.kernel_ready = kernel_ready
        self.inflation = inflation
        self._active: dict[int, _Compile] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None

    # -- the compile thread's side (numba's events) ------------------------------------
    def begin(self, name: str, cached: bool = True) -> None:
        """A compile of ``name`` starts in the calling thread (nested ones are counted).
        ``cached`` False: the signature takes a compiled function, which numba's disk cache
        does not keep (:func:`rod_sim.core.jit.names_a_function_object`)."""
        key = threading.get_ident()
        with self._lock:
            cur = self._active.get(key)
            if cur is not None:
                cur.depth += 1
                return
            cpu = self.table.get(name, UNKNOWN_CPU_S)
            if name in self.table and self.kernel_ready(name):
                cpu = max(cpu - KERNEL_CPU_S, 5.0)
            cpu *= self.inflation()
            self._active[key] = _Compile(name, self.clock(), self.cpu(), cpu, cached=cached)
        self._wake.set()

    def end(self) -> None:
        """The calling thread's innermost compile ended; after the outermost, a closing line
        if the notice was printed."""
        key = threading.get_ident()
        with self._lock:
            cur = self._active.get(key)
            if cur is None:
                return
            cur.depth -= 1
            if cur.depth:
                return
            del self._active[key]
        if cur.announced:
            self.sink(f"{COMPILE_NOTICE} {describe(cur.name)}: done in "
                      f"{self.clock() - cur.wall0:.0f} s ({self.cpu() - cur.cpu0:.0f} s CPU); "
                      + ("cached for later runs" if cur.cached else
                         "not cached (it takes a compiled function): compiled again by every "
                         "process"))

    # -- the ticker's side -------------------------------------------------------------
    def poll(self) -> list[str]:
        """Print (and return) the notice or progress lines that are due now."""
        now = self.clock()
        lines = []
        with self._lock:
            due = [c for c in self._active.values()
                   if (not c.announced and now - c.wall0 >= self.after)
                   or (c.announced and now - c.last_line >= self.every)]
            for c in due:
                lines.append(self._progress(c, now) if c.announced else self._notice(c, now))
                c.announced, c.last_line = True, now
        for line in lines:
            self.sink(line)
        return lines

    def _notice(self, c: _Compile, now: float) -> str:
        wall = max(c.estimate_cpu * self.slowdown(), now - c.wall0)
        measured = (f"Measured ~{c.estimate_cpu:.0f} s of CPU at this load" if c.name in
                    self.table else
                    f"Not measured (helpers take ~{c.estimate_cpu:.0f} s of CPU)")
        why = ("it is not in numba's cache yet (first use since an install or a change of "
               "rod_sim/core; compiled once, then cached)" if c.cached else
               "it takes a compiled function as an argument, which numba's disk cache does "
               "not keep (compiled once per process)")
        return (f"{COMPILE_NOTICE} {describe(c.name)} ({c.name}): {why}. {measured}; "
                f"expect ~{wall:.0f} s at this machine's load")

    def _progress(self, c: _Compile, now: float) -> str:
        elapsed, used = now - c.wall0, self.cpu() - c.cpu0
        head = f"{COMPILE_NOTICE} {describe(c.name)}: {elapsed:.0f} s so far"
        if used >= c.estimate_cpu:
            return (f"{head}, past its measured {c.estimate_cpu:.0f} s of CPU "
                    f"({used:.0f} s CPU used); should end soon")
        rate = max(used / elapsed, 0.02) if elapsed > 0 else 1.0
        return f"{head}, ~{(c.estimate_cpu - used) / rate:.0f} s left"

    def _tick(self) -> None:
        """Poll four times a second while a compile runs; sleep while none does (no wake-ups
        in a running node)."""
        while not self._stop.is_set():
            if not self._active:
                self._wake.wait()
                self._wake.clear()
                continue
            if self._stop.wait(0.25):
                break
            try:
                self.poll()
            except Exception:   # a notice must never break the run
                pass

    # -- installation --------------------------------------------------------------------
    def install(self) -> "CompileWatch":
        """Listen to numba's compile events and start the ticker (a daemon thread)."""
        from numba.core import event

        watch = self

        class _Listener(event.Listener):
            def on_start(self, ev):
                disp = ev.data.get("dispatcher")
                watch.begin(getattr(getattr(disp, "py_func", None), "__qualname__", "?"),
                            cached=not _takes_function(ev.data.get("args")))

            def on_end(self, ev):
                watch.end()

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self.start_ticker()

    def start_ticker(self) -> "CompileWatch":
        """Start the daemon thread that calls :meth:`poll` four times a second."""
        self._thread = threading.Thread(target=self._tick, name="rod-sim-compile-watch",
                                        daemon=True)
        self._thread.start()
        return self

    def uninstall(self) -> None:
        """Stop listening and stop the ticker."""
        from numba.core import event

        self._stop.set()
        self._wake.set()
        if getattr(self, "_listener", None) is not None:
            event.unregister("numba:compile", self._listener)
            self._listener = None


def _takes_function(args) -> bool:
    """Whether a compile's argument types include a compiled function (False if unknown)."""
    try:
        from rod_sim.core.jit import names_a_function_object

        return names_a_function_object(tuple(args or ()))
    except Exception:  # noqa: BLE001 -- a notice's wording, never a failure
        return False


_installed: CompileWatch | None = None


def watch_compiles(sink: Callable[[str], None]) -> CompileWatch | None:
    """Install one process-wide :class:`CompileWatch` printing to ``sink`` (later calls
    return the first); None when numba is not in use (``ROD_SIM_NO_JIT``)."""
    global _installed
    if _installed is None:
        from rod_sim.core.jit import HAVE_NUMBA

        if not HAVE_NUMBA:
            return None
        _installed = CompileWatch(sink).install()
    return _installed
