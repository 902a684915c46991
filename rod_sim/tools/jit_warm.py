"""Compile drivers into numba's on-disk cache ahead of use: ``python -m rod_sim.tools.jit_warm``.

``make demo`` runs it with ``--demo`` (only what the demo needs: the reduced and the full
model's dop853-jit drivers and the helpers the node's messages use), ``make test`` without
(every driver), each again whenever a module of ``rod_sim/core`` changes (which invalidates
the cache). Anything not compiled here compiles on first use with a notice saying what, why
and how long (:mod:`rod_sim.core.compile_watch`).

The full set iterates over whatever the registries hold: every model of ``MODEL_NAMES`` with
every integrator of ``INTEGRATOR_NAMES`` (rod_sim.core.names), on a plain chain and on a
chain with hinge features (stops, latches, a locked hinge), so that a newly registered model,
integrator or hinge driver is covered without editing this file. The drivers are grouped by
model (one group runs in one process, in order, so that the model's kernel is compiled once)
and the groups run in ``--jobs`` processes, the most expensive first. Processes compiling side
by side may save different signatures of one shared helper at once: rod_sim.core.jit locks
numba's cache index for that. A line at least every :data:`TICK_S` seconds says what is
compiling, how long it has taken and how long the rest should take.
"""
from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

CONFIG = Path(__file__).resolve().parents[2] / "config"
SCENES = ("paper_example.yaml", "deployment.yaml")     # plain chain; hinge features
ON_A_BASE = "spin_up_beam.yaml"
"""A chain on a prescribed base: one sample of it per model (with the hinge scene's drivers,
so not for ``--demo``) compiles the base's helpers of a sample (its reaction, the momentum,
the balance's pair on a prescribed base, the momentum ledger)."""
DEMO = (("paper_example.yaml", "full", "dop853-jit"),
        ("paper_example.yaml", "reduced", "dop853-jit"))
"""What ``make demo`` runs: table1 (both models), the node (reduced), compare (full)."""
TICK_S = 8.0
"""[s] between progress lines while nothing finishes."""
START = "spawn"
"""How the compiling processes start. Not forked: two forked workers compiling side by side
spent up to ~70 % of their time in the kernel (~60 000 page faults a second each; the demo's
two drivers: 142 s of system CPU in 326 s, 233-369 s of wall time at load ~3-4), two spawned
ones 16 s in 187 s (194 s wall at the same load); one forked worker alone did not (5 s). The
cause is not established."""


def drivers() -> list[tuple[str, str, str]]:
    """(scene file, model, integrator) for every registered model and integrator."""
    from ..core.names import INTEGRATOR_NAMES, MODEL_NAMES

    return [(scene, model, integrator) for scene in SCENES for model in MODEL_NAMES
            for integrator in INTEGRATOR_NAMES]


def entry_point(model: str, integrator: str) -> str:
    """The name of the compiled function a (model, integrator) pair compiles (scipy's
    methods share the model's right-hand side; the fixed-step methods one driver)."""
    from ..core.names import SCIPY_METHODS

    if integrator in SCIPY_METHODS:
        return f"{model}_rhs"
    family = {"dop853-jit": "dop853", "radau-jit": "radau"}.get(integrator, "fixed")
    return f"{family}_{model}"


def groups(todo) -> list[list[tuple[str, str, str]]]:
    """``todo`` grouped by model (its drivers share the model's kernel, compiled once by the
    group's process), the groups the most expensive first. The first group runs the hinge
    scene first, the others run it last: a scene with locked hinges or latches compiles the
    velocity projection (kernels.solve_with, ~70 s of CPU, one for every model) from Python,
    and two processes reaching it together compiled it twice."""
    by_model: dict[str, list] = {}
    for item in todo:
        by_model.setdefault(item[1], []).append(item)
    plan = sorted(by_model.values(), key=lambda g: -estimate(g))
    hinge = SCENES[-1]
    return [sorted(g, key=lambda item: (item[0] == hinge) == (k > 0)) for k, g in
            enumerate(plan)]


def estimate(group) -> float:
    """CPU seconds measured for compiling a group's entry points in one process (the
    model's kernel once: :data:`compile_watch.KERNEL_CPU_S`)."""
    from rod_sim.core.compile_watch import COMPILE_CPU_S, KERNEL_CPU_S, UNKNOWN_CPU_S

    points = {entry_point(m, i) for _, m, i in group}
    return sum(COMPILE_CPU_S.get(p, UNKNOWN_CPU_S) for p in points) \
        - KERNEL_CPU_S * (len(points) - 1)


def progress_line(done: int, total: int, what: str, took: float, elapsed: float,
                  left: float, skipped: bool = False) -> str:
    """One progress line: ``[done/total] what: took s (elapsed s so far, ~left s left)``."""
    status = "skipped (not supported)" if skipped else f"{took:.1f} s"
    return (f"rod_sim: [{done}/{total}] {what}: {status} ({elapsed:.0f} s so far, "
            f"~{left:.0f} s left)")


def run_group(group) -> list[tuple[str, float, float, bool]]:
    """Run each (scene, model, integrator) of ``group`` for 1 ms, then what every sample of a
    node or a log and every run's start call from Python: one snapshot, one energy balance
    sample (the energies, the powers and the balance's central difference) and the validity
    monitor (the chain's lowest bending mode: the mass and stiffness operators, and the
    velocity projection of locked hinges); with the hinge scene's first driver of a model, one
    sample of the model on a base (:data:`ON_A_BASE`): per item (label, wall s, CPU s,
    skipped). A combination the library refuses (ValueError) is skipped."""
    from ..core.integrators import make_integrator
    from ..core.ledger import SpacecraftLedger
    from ..core.models import make_model
    from ..core.simulator import Simulator
    from ..core.validity import ValidityMonitor, balance_sample
    from ..io.scene_yaml import load_scene

    def sample_on_a_base(model_name: str) -> None:
        model = make_model(model_name, load_scene(CONFIG / ON_A_BASE))
        t, y = 0.5, model.initial_state()       # spinning up: the base moves
        s = model.state(t, y)
        model.snapshot(t, y, state=s)
        balance_sample(model, t, y, state=s)
        SpacecraftLedger(model).add(t, y, None, None, state=s)

    out = []
    on_a_base = set()
    for scene, model_name, integrator in group:
        w0, c0 = time.perf_counter(), time.process_time()
        skipped = False
        try:
            model = make_model(model_name, load_scene(CONFIG / scene))
            sim = Simulator(model, make_integrator(integrator))
            sim.advance(1e-3)
            model.snapshot(sim.t, sim.y, sim.held, sim.mode)
            balance_sample(model, sim.t, sim.y, sim.held, sim.mode)
            ValidityMonitor(model)
            if scene == SCENES[-1] and model_name not in on_a_base:
                on_a_base.add(model_name)
                sample_on_a_base(model_name)
        except ValueError:
            skipped = True
        out.append((f"{model_name} x {integrator} on {scene}", time.perf_counter() - w0,
                    time.process_time() - c0, skipped))
    return out


def warm(log=print, todo=None, jobs: int = 1, clock=time.perf_counter) -> int:
    """Compile the drivers of ``todo`` (default: :func:`drivers`) in ``jobs`` processes (1:
    in this one), logging one line per driver and, while none finishes, one every
    :data:`TICK_S`; returns how many ran (not skipped)."""
    from rod_sim.core.compile_watch import cpu_inflation, load_slowdown

    todo = drivers() if todo is None else list(todo)
    plan = groups(todo)
    total = len(todo)
    jobs = max(1, min(jobs, len(plan)))
    cpu_left = sum(estimate(g) for g in plan)
    pace = load_slowdown() * cpu_inflation() * max(1.0, jobs / (os.cpu_count() or 1)) / jobs
    log(f"rod_sim: compiling {total} drivers ({len(plan)} compiled entry points) into "
        f"numba's cache in {jobs} process(es): ~{cpu_left * pace:.0f} s at this load "
        f"(measured {cpu_left:.0f} s of CPU cold; ~1 s when already cached)")
    started = clock()
    expected_end = started + cpu_left * pace
    done = ran = 0
    spent_cpu = spent_est = 0.0

    def report(group, results):
        nonlocal done, ran, cpu_left, spent_cpu, spent_est, expected_end
        cpu_left -= estimate(group)
        spent_est += estimate(group)
        spent_cpu += sum(r[2] for r in results)
        now = clock()
        # the rest at the pace seen so far (wall per estimated CPU second)
        expected_end = now + max(cpu_left, 0.0) * (now - started) / spent_est
        for label, took, _cpu, skipped in results:
            done += 1
            ran += not skipped
            log(progress_line(done, total, label, took, now - started, expected_end - now,
                              skipped))

    if jobs == 1:
        for group in plan:
            report(group, run_group(group))
    else:
        queue = list(plan)
        with ProcessPoolExecutor(max_workers=jobs,
                                 mp_context=multiprocessing.get_context(START)) as pool:
            pending = {}
            while queue or pending:
                while queue and len(pending) < jobs:   # submitted = running: the ticks say
                    group = queue.pop(0)               # what really compiles
                    pending[pool.submit(run_group, group)] = group
                finished, _ = wait(pending, timeout=TICK_S, return_when=FIRST_COMPLETED)
                for f in finished:
                    report(pending.pop(f), f.result())
                if not finished:
                    now = clock()
                    busy = [f"the {g[0][1]} model's drivers" for g in pending.values()]
                    left = (f"~{expected_end - now:.0f} s left" if expected_end > now else
                            "past the estimate, should end soon")
                    log(f"rod_sim: [{done}/{total}] compiling {', '.join(busy) or '...'} "
                        f"({now - started:.0f} s so far, {left})")
    log(f"rod_sim: {ran} compiled drivers ready in numba's cache "
        f"({clock() - started:.1f} s, {spent_cpu:.0f} s CPU in the compiling processes)")
    return ran


PRUNE_AFTER_DAYS = 30.0
"""A directory of the shared compile cache not warmed for this many days is removed."""


def prune_shared_cache(current: Path | None, now: float | None = None,
                       max_age_days: float = PRUNE_AFTER_DAYS) -> list[Path]:
    """Mark ``current`` (this checkout's directory of the shared compile cache,
    rod_sim.core.jit.shared_cache_dir) as used now and remove its siblings not warmed for
    ``max_age_days`` (sources edited since, other numba versions); returns those removed."""
    import shutil

    if current is None or not current.is_dir():
        return []
    now = time.time() if now is None else now
    os.utime(current, (now, now))
    removed = []
    for other in current.parent.iterdir():
        if other == current or not other.is_dir():
            continue
        if now - other.stat().st_mtime > max_age_days * 86400.0:
            shutil.rmtree(other, ignore_errors=True)
            removed.append(other)
    return removed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rod_sim.tools.jit_warm",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--demo", action="store_true",
                        help="only what `make demo` needs (default: every driver)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                        help="compiling processes (default: 2, or 1 on one core)")
    args = parser.parse_args(argv)
    ran = warm(lambda line: print(line, flush=True), DEMO if args.demo else None,
               max(1, args.jobs))
    from ..core.jit import shared_cache_dir, sources_stamp

    current = shared_cache_dir(sources_stamp())
    for gone in prune_shared_cache(current):
        print(f"rod_sim: removed {gone} (a compile cache unused for "
              f"{PRUNE_AFTER_DAYS:.0f} days)", flush=True)
    return 0 if ran else 1


if __name__ == "__main__":
    sys.exit(main())
