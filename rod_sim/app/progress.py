"""A long command says what it is doing: :class:`Progress` prints a progress line on stderr
from a daemon thread, the first after ``first_s`` seconds of wall time, then every ``every_s``,
until its ``with`` block ends; :class:`Pace` estimates the wall time left from how fast a
simulated time advanced over the last interval. ``rod-sim simulate``, ``compare`` and ``advise``
and the node's start-up (:mod:`rod_sim.ros.startup`) use them (their integrators return after
bounded work, so the thread gets to run during a long step).
"""
from __future__ import annotations

import math
import sys
import threading
import time
from typing import Callable

from rod_sim.app.signals import write_line


class Progress:
    """Calls ``line(elapsed_s)`` (-> the text, or None for no line this time) after
    ``first_s`` [s] of wall time and then every ``every_s`` [s], and writes each text as one
    line on ``stream`` (stderr by default), while the ``with`` block runs."""

    def __init__(self, line: Callable[[float], str | None], first_s: float, every_s: float,
                 name: str = "rod-sim-progress", stream=None):
        self.line, self.first_s, self.every_s = line, float(first_s), float(every_s)
        self.stream = stream
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name=name)

    def __enter__(self) -> "Progress":
        self._begun = time.perf_counter()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._done.set()

    def _run(self) -> None:
        wait = self.first_s
        while not self._done.wait(wait):
            text = self.line(time.perf_counter() - self._begun)
            if text is not None and not self._done.is_set():
                write_line(text, self.stream if self.stream is not None else sys.stderr)
            wait = self.every_s


class Pace:
    """Wall time left to reach ``t_end`` [s] of simulated time, at the pace of the interval
    since the last :meth:`left` call (the first interval starts at construction): the pace of
    the simulated time when it advanced, else (inside one long stretch of integration, whose
    time is set only at its end) the accepted steps' pace at the current step size. ``wall``:
    the ``time.perf_counter()`` reading at which the run was at ``t_now`` (default: now)."""

    def __init__(self, t_end: float, t_now: float = 0.0, steps: int = 0,
                 wall: float | None = None):
        self.t_end = float(t_end)
        self._last = (time.perf_counter() if wall is None else float(wall), float(t_now),
                      int(steps))

    def left(self, t_now: float, steps: int = 0, h: float = 0.0) -> float:
        """[s] of wall time left; ``steps``: accepted steps so far, ``h`` [s] the current step
        size (0: unknown); inf when there is no estimate yet."""
        now = time.perf_counter()
        wall0, t0, steps0 = self._last
        self._last = (now, float(t_now), int(steps))
        togo = max(0.0, self.t_end - t_now)
        if t_now > t0:
            return (now - wall0) * togo / (t_now - t0)
        rate = (steps - steps0) / (now - wall0) if now > wall0 else 0.0
        if h > 0 and rate > 0:
            return togo / h / rate
        return math.inf


def run_state(sim) -> tuple[float, int, float]:
    """(simulated time [s], accepted steps, current step size [s], 0 before the first) of a
    :class:`~rod_sim.core.simulator.Simulator`: what :meth:`Pace.left` takes. The time is the
    integration's (its last call's end), which runs ahead of ``sim.t`` inside one long
    ``run`` or ``advance``."""
    return (max(sim.t, getattr(sim.carry, "t", -math.inf)), sim.stats.steps,
            getattr(sim.carry, "h", 0.0))


STIFF_SHARE = 0.2
"""dop853-jit calls a run stiff when at least this share of its accepted steps ... (measured:
0.96-1.0 on hanging cables of 1 cm rods and a heavily damped hinge, 0.33 on the spin-up beam's
full model, where radau-jit takes 50x fewer right-hand sides; 0.00-0.01 on the paper example
and the two-wing deployment, where dop853-jit is the cheaper)"""
STIFF_MIN_STEPS = 1000
"""... of at least this many were limited by its stability (a short run is cheap anyway)."""


def stiffness_hint(integrator, stats) -> str | None:
    """One sentence when a dop853-jit run was stiff (:data:`STIFF_SHARE` of at least
    :data:`STIFF_MIN_STEPS` accepted steps limited by its stability, Hairer's test: the step
    size was set by the method's stability, not by the tolerance), pointing to radau-jit;
    else None. ``integrator``: the run's settings; ``stats``: its work counters."""
    if integrator.name != "dop853-jit" or stats.steps < STIFF_MIN_STEPS:
        return None
    share = stats.stiff_share()
    if share < STIFF_SHARE:
        return None
    return (f"the scene is stiff for dop853-jit: {100 * share:.0f} % of its {stats.steps} "
            "steps were as short as its stability allowed, not as the tolerance asked; "
            "--integrator radau-jit (implicit) may take far fewer (docs/hard_cases.md)")


def steps_text(steps: int, h: float) -> str:
    """'1234 steps of ~0.00037 s' (the step size when known)."""
    return f"{steps} steps" + (f" of ~{h:.2g} s" if h > 0 else "")


def left_text(seconds: float, tail: str = "more at this pace") -> str:
    """'~8 s more at this pace' (``tail`` after the time), or 'no estimate yet' for inf."""
    return f"~{duration(seconds)} {tail}" if math.isfinite(seconds) else "no estimate yet"


def duration(seconds: float) -> str:
    """``seconds`` in words for a progress line: 42 s, 7 min, 1.5 h."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.3g} h"


CHECK_FIRST_S = 2.0
"""[s] a log's integrity pass runs before :func:`log_check_progress` says so."""
CHECK_EVERY_S = 10.0
"""[s] between its next lines."""
CHECK_POLL_S = 1.0
"""[s] between looks at :data:`rod_sim.io.log_reader.CHECKING`."""


def log_check_progress(prog: str) -> Progress:
    """A :class:`Progress` for a command that opens logs (``prog``: e.g. 'rod-sim compare'):
    once opening a file has taken :data:`CHECK_FIRST_S` (the integrity pass reads and checks
    every record: ~80 s for a 1.2 GB log), a line says which and how far it is, then every
    :data:`CHECK_EVERY_S`; nothing while no file is being opened."""
    from rod_sim.io.log_reader import CHECKING

    last = {"since": None, "at": 0.0}

    def line(elapsed: float) -> str | None:
        path, since = CHECKING.path, CHECKING.since
        now = time.monotonic()
        if not path or now - since < CHECK_FIRST_S:
            return None
        if last["since"] == since and now - last["at"] < CHECK_EVERY_S:
            return None
        last["since"], last["at"] = since, now
        return (f"{prog}: checking {path} (every record and its CRC): "
                f"{CHECKING.done / 1e6:.0f} of {CHECKING.size / 1e6:.0f} MB after "
                f"{now - since:.0f} s")

    return Progress(line, CHECK_POLL_S, CHECK_POLL_S, "rod-sim-log-check-progress")
