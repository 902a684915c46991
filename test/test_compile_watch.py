"""The compile notice (issue 29): one notice per compile that outlasts 2 s (what, why, how
long), a progress line every tick with an estimate of the time left, a closing line; nothing
for a quick compile or a cache load. Clocks are injected: nothing here depends on the
machine's speed or load."""
from __future__ import annotations

import re
import threading

import pytest

from rod_sim.core import jit, models, names
from rod_sim.core import compile_watch
from rod_sim.tools import jit_warm
from rod_sim.core.compile_watch import COMPILE_NOTICE, CompileWatch


class Clocks:
    """A wall clock and a process-CPU clock the test moves: the compile gets ``share`` of a
    CPU per wall second."""

    def __init__(self, share: float = 1.0):
        self.wall = self.cpu = 0.0
        self.share = share

    def advance(self, seconds: float) -> None:
        self.wall += seconds
        self.cpu += seconds * self.share


def make_watch(clocks, lines, slowdown=1.0, table=None):
    return CompileWatch(lines.append, clock=lambda: clocks.wall, cpu=lambda: clocks.cpu,
                        slowdown=lambda: slowdown,
                        table={"dop853_full": 40.0} if table is None else table,
                        kernel_ready=lambda name: False, inflation=lambda: 1.0)


def test_a_long_compile_gets_one_notice_then_progress_then_a_closing_line():
    clocks, lines = Clocks(), []
    watch = make_watch(clocks, lines)
    watch.begin("dop853_full")
    clocks.advance(1.9)
    assert watch.poll() == []                         # not yet 2 s
    clocks.advance(0.2)
    (notice,) = watch.poll()
    assert "the full model's dop853-jit integrator" in notice
    assert "not in numba's cache" in notice and "~40 s of CPU" in notice and "~40 s" in notice
    clocks.advance(5.0)
    assert watch.poll() == []                         # the next line one tick later
    clocks.advance(compile_watch.TICK_S)
    (progress,) = watch.poll()
    assert re.search(r": 15 s so far, ~25 s left$", progress), progress
    clocks.advance(25.0)
    watch.end()
    assert lines[-1].endswith("done in 40 s (40 s CPU); cached for later runs")
    assert len(lines) == 3 and all(COMPILE_NOTICE in line for line in lines)
    assert watch.poll() == [] and watch._active == {}


def test_a_quick_compile_or_a_cache_load_says_nothing():
    clocks, lines = Clocks(), []
    watch = make_watch(clocks, lines)
    watch.begin("dop853_full")
    clocks.advance(1.5)
    watch.poll()
    watch.end()
    clocks.advance(60.0)
    assert watch.poll() == [] and lines == []


def test_only_the_outermost_compile_is_reported():
    clocks, lines = Clocks(), []
    watch = make_watch(clocks, lines)
    watch.begin("dop853_full")
    watch.begin("full_rhs")                           # a kernel compiled inside the driver
    clocks.advance(3.0)
    watch.poll()
    watch.end()
    assert len(lines) == 1 and "dop853_full" in lines[0] and "full_rhs" not in lines[0]
    watch.end()
    assert len(lines) == 2 and "done in 3 s" in lines[1]


@pytest.mark.parametrize("share", [1.0, 0.5, 0.2])
def test_estimates_are_within_2x_when_the_table_is_right(share):
    """At a load that gives the compile ``share`` of a CPU (and a slowdown that says so), the
    notice's and every progress line's estimate of the time left is within 2x of the
    truth."""
    clocks, lines = Clocks(share), []
    cpu_needed = 40.0
    watch = make_watch(clocks, lines, slowdown=1.0 / share)
    watch.begin("dop853_full")
    total = cpu_needed / share
    while clocks.wall + 0.25 < total:
        clocks.advance(0.25)
        for line in watch.poll():
            left = total - clocks.wall
            said = float(re.findall(r"~(\d+) s", line)[-1])    # the time, not the CPU
            if "so far" in line:
                assert left / 2 <= said <= 2 * left + 1, (line, left)
            else:                                     # the notice: the whole duration
                assert total / 2 <= said <= 2 * total, (line, total)
    assert len(lines) >= total / compile_watch.TICK_S - 1


def test_a_compile_past_its_estimate_says_so_instead_of_a_negative_time():
    clocks, lines = Clocks(), []
    watch = make_watch(clocks, lines, table={"dop853_full": 5.0})
    watch.begin("dop853_full")
    clocks.advance(12.0)
    watch.poll()
    clocks.advance(compile_watch.TICK_S)
    (line,) = watch.poll()
    assert "past its measured 5 s of CPU" in line and "left" not in line


def test_the_ticker_thread_prints_while_a_fake_compile_runs():
    """The real thread with short periods; waited for (not slept for), so a loaded machine
    only makes it slower."""
    lines = []
    got = threading.Event()

    def sink(line):
        lines.append(line)
        if len(lines) >= 2:
            got.set()

    watch = CompileWatch(sink, after=0.05, every=0.05, table={}).start_ticker()
    try:
        watch.begin("some_function")                  # a compile that sleeps until seen
        assert got.wait(60.0)
        watch.end()
    finally:
        watch.uninstall()
    assert "the compiled function some_function" in lines[0] and "Not measured" in lines[0]
    assert "so far" in lines[1] and lines[-1].endswith("cached for later runs")


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba not installed")
def test_numba_compile_events_reach_the_watch():
    """Each compile is seen once, with whether its signature takes a compiled function (then
    numba's disk cache does not keep it: reported as not cached)."""
    import numba

    seen = []
    watch = CompileWatch(lambda line: None)
    watch.begin = lambda name, cached=True: seen.append((name.rpartition(".")[2], cached))
    watch.end = lambda: seen.append("end")
    watch.install()
    try:
        @numba.njit(cache=False)
        def tiny_compiled_function(x):
            return x + 1

        @numba.njit(cache=False)
        def apply(f, x):
            return f(x)

        assert tiny_compiled_function(1) == 2
        assert tiny_compiled_function(2) == 3         # compiled once
        assert apply(tiny_compiled_function, 3) == 4
    finally:
        watch.uninstall()
    assert seen == [("tiny_compiled_function", True), "end", ("apply", False), "end"]


def test_every_driver_has_a_measured_estimate_and_a_name_in_words():
    for model in names.MODEL_NAMES:
        cls = models.MODELS[model]
        for integrator in names.INTEGRATOR_NAMES:
            key = jit_warm.entry_point(model, integrator)
            assert key in compile_watch.COMPILE_CPU_S, key
            assert "compiled function" not in compile_watch.describe(key)
        if jit.HAVE_NUMBA:
            for family, disp in zip(("dop853", "fixed", "radau"), cls.compiled):
                assert disp.py_func.__name__ == f"{family}_{model}"
            assert cls.kernel.py_func.__name__ == f"{model}_rhs"


def test_a_driver_whose_kernel_is_compiled_already_is_estimated_without_it():
    clocks, lines = Clocks(), []
    watch = make_watch(clocks, lines, table={"fixed_full": 60.0})
    watch.kernel_ready = lambda name: name == "fixed_full"
    watch.begin("fixed_full")
    clocks.advance(2.0)
    (notice,) = watch.poll()
    assert f"Measured ~{60 - compile_watch.KERNEL_CPU_S:.0f} s of CPU" in notice
    assert not compile_watch.kernel_cached("mass_times")     # not a driver


def test_the_slowdown_and_the_cpu_estimate_grow_with_the_load():
    assert compile_watch.load_slowdown(0.0, 2) == 1.0
    assert compile_watch.load_slowdown(5.0, 2) == 3.0
    assert compile_watch.cpu_inflation(1.0, 2) == 1.0
    assert compile_watch.cpu_inflation(8.0, 2) == pytest.approx(1.6)


def test_warming_prunes_shared_cache_directories_unused_for_a_month(tmp_path):
    import os

    from rod_sim.tools.jit_warm import prune_shared_cache

    now = 1_800_000_000.0
    current, fresh, stale = (tmp_path / name for name in ("cur", "fresh", "stale"))
    for d in (current, fresh, stale):
        d.mkdir()
        (d / "x.nbi").write_bytes(b"x")
    os.utime(current, (now - 90 * 86400, now - 90 * 86400))   # old, but in use: stays
    os.utime(fresh, (now - 29 * 86400, now - 29 * 86400))
    os.utime(stale, (now - 31 * 86400, now - 31 * 86400))
    assert prune_shared_cache(current, now=now) == [stale]
    assert current.is_dir() and fresh.is_dir() and not stale.exists()
    assert current.stat().st_mtime == now
    assert prune_shared_cache(None) == [] and prune_shared_cache(tmp_path / "nope") == []


def test_a_compile_taking_a_compiled_function_says_it_is_not_cached():
    clocks, lines = Clocks(), []
    watch = make_watch(clocks, lines)
    watch.begin("radau_run", cached=False)
    clocks.advance(2.5)
    (notice,) = watch.poll()
    assert "takes a compiled function" in notice and "not in numba's cache yet" not in notice
    watch.end()
    assert lines[-1].endswith("not cached (it takes a compiled function): compiled again by "
                              "every process")

