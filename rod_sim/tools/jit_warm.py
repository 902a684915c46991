"""Compile every compiled driver into numba's on-disk cache: ``python -m rod_sim.tools.jit_warm``.

``make`` runs it after installing (and again whenever a module of ``rod_sim/core`` changes,
which invalidates the cache), so that the first ``rod-sim`` command or node start does not
spend ~20 s compiling. It iterates over whatever the registries hold: every model of
``MODEL_NAMES`` with every integrator of ``INTEGRATOR_NAMES`` (rod_sim.core.names), on a
plain chain and on a chain with hinge features (stops, latches, a locked hinge), so that a
newly registered model, integrator or hinge driver is covered without editing this file.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

CONFIG = Path(__file__).resolve().parents[2] / "config"
SCENES = ("paper_example.yaml", "deployment.yaml")     # plain chain; hinge features


def drivers() -> list[tuple[str, str, str]]:
    """(scene file, model, integrator) for every registered model and integrator."""
    from ..core.names import INTEGRATOR_NAMES, MODEL_NAMES

    return [(scene, model, integrator) for scene in SCENES for model in MODEL_NAMES
            for integrator in INTEGRATOR_NAMES]


def progress_line(done: int, total: int, what: str, took: float, elapsed: float,
                  skipped: bool = False) -> str:
    """One progress line: ``[done/total] what: took s (elapsed s, ~left s left)``; the estimate
    of the time left is the mean time per driver so far times the drivers left [s]."""
    left = elapsed / done * (total - done) if done else 0.0
    status = "skipped (not supported)" if skipped else f"{took:.1f} s"
    return (f"rod_sim: [{done}/{total}] {what}: {status} ({elapsed:.0f} s so far, "
            f"~{left:.0f} s left)")


def warm(log=print) -> int:
    """Run every driver for 1 ms of simulated time, logging one progress line per driver with
    an estimate of the time left; returns how many ran. A combination the library refuses
    (e.g. a fixed-step integrator on a scene with hinge events) is skipped."""
    from ..core.integrators import make_integrator
    from ..core.models import make_model
    from ..core.simulator import Simulator
    from ..io.scene_yaml import load_scene

    scenes = {name: load_scene(CONFIG / name) for name in SCENES}
    ran = 0
    started = time.perf_counter()
    todo = drivers()
    log(f"rod_sim: compiling {len(todo)} drivers into numba's cache (a few minutes cold, "
        "longer on a loaded machine; ~1 s when already cached)")
    for done, (scene, model, integrator) in enumerate(todo, 1):
        t0 = time.perf_counter()
        skipped = False
        try:
            Simulator(make_model(model, scenes[scene]), make_integrator(integrator)).advance(1e-3)
            ran += 1
        except ValueError:
            skipped = True
        now = time.perf_counter()
        log(progress_line(done, len(todo), f"{model} x {integrator} on {scene}", now - t0,
                          now - started, skipped))
    log(f"rod_sim: {ran} compiled drivers ready in numba's cache "
        f"({time.perf_counter() - started:.1f} s)")
    return ran


if __name__ == "__main__":
    sys.exit(0 if warm(lambda line: print(line, flush=True)) else 1)
