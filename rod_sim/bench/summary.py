"""The figures of one ``rod-sim bench`` run as data: the speed targets met (:func:`targets`),
the environment, and the whole run as the JSON of ``--json`` and ``bench.json``
(:func:`as_json`).
"""
from __future__ import annotations

import math
import os
import platform
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from rod_sim.version import __version__
from .config import (BENCH_CHECK_RTOL, BENCH_REFERENCE_RTOL, HINGE_COST_LIMIT, MODELS, RATE_HZ,
                     REFERENCE_GAP, SCENE_T_END, T_END, TARGET_ERROR, BenchConfig)


def best_at(rows, model, max_error=TARGET_ERROR, scene="paper_example", ours=True,
            key="rtf_cpu", error="max_phi_error"):
    """Fastest ok row (by ``key``: "rtf_cpu" or "rtf") of ``model`` on ``scene`` with
    ``error`` <= max_error, or None (``ours``: rod_sim's integrators, not the peer)."""
    ok = [r for r in rows if r.model == model and r.scene == scene and r.status == "ok"
          and getattr(r, error) <= max_error and math.isfinite(getattr(r, key))
          and (not ours or not r.integrator.startswith("mujoco"))]
    return max(ok, key=lambda r: getattr(r, key)) if ok else None


def _brief(row, key):
    if row is None:
        return None
    return {"rtf": getattr(row, key), "integrator": row.integrator, "setting": row.setting,
            "max_phi_error": row.max_phi_error, "max_hinge_error": row.max_hinge_error,
            "wall_s": row.wall_s, "cpu_s": row.cpu_s}


def targets(rows, max_error=TARGET_ERROR, key="rtf_cpu", hinge_cost=None) -> dict:
    """The issue's speed targets, measured in this run, at max phi error <= max_error.
    ``key`` = "rtf_cpu" (simulated s per CPU s of the process: one core, insensitive to other
    processes on a shared machine) or "rtf" (per wall s); ``hinge_cost``: the result of
    :func:`hinge_rhs_cost` (adds its <= HINGE_COST_LIMIT check)."""
    out = {"max_phi_error": max_error, "measure": key}
    for model in MODELS:
        out[f"paper_example_{model}"] = _brief(best_at(rows, model, max_error, key=key), key)
    red, full = out.get("paper_example_reduced"), out.get("paper_example_full")
    out["reduced_over_full_speedup"] = red["rtf"] / full["rtf"] if red and full else None
    out["chain_n128_reduced"] = _brief(best_at(rows, "reduced", max_error, "chain_n128",
                                               key=key), key)
    peer = [r for r in rows if r.integrator.startswith("mujoco") and r.scene == "paper_example"
            and r.status == "ok" and r.max_phi_error <= max_error]
    out["paper_example_mujoco_rigid"] = _brief(
        max(peer, key=lambda r: getattr(r, key)) if peer else None, key)
    rig, mj = out["paper_example_rigid"], out["paper_example_mujoco_rigid"]
    out["rigid_over_mujoco_speedup"] = rig["rtf"] / mj["rtf"] if rig and mj else None
    ran = {(r.scene, r.model) for r in rows}
    checks = {}
    if ("paper_example", "reduced") in ran:
        checks["reduced >= 1000x"] = (red or {}).get("rtf", 0) >= 1000
    if ("paper_example", "full") in ran:
        checks["full >= 5x"] = (full or {}).get("rtf", 0) >= 5
        checks["full >= 120x"] = (full or {}).get("rtf", 0) >= 120
    if {("paper_example", "reduced"), ("paper_example", "full")} <= ran:
        checks["reduced/full >= 100x"] = (out["reduced_over_full_speedup"] or 0) >= 100
    if ("chain_n128", "reduced") in ran:
        checks["n=128 reduced >= 5x"] = (out["chain_n128_reduced"] or {}).get("rtf", 0) >= 5
    if ("paper_example", "reduced") in ran:
        checks["reduced >= 1300x"] = (red or {}).get("rtf", 0) >= 1300
    for model, need in (("reduced", 1000), ("full", 20)):     # issue 12: hinge-angle error
        if ("deployment", model) in ran:
            best = _brief(best_at(rows, model, max_error, "deployment", key=key,
                                  error="max_hinge_error"), key)
            out[f"deployment_{model}"] = best
            checks[f"deployment {model} >= {need}x"] = (best or {}).get("rtf", 0) >= need
    if hinge_cost:
        checks[f"hinge rhs cost <= {HINGE_COST_LIMIT:g}x plain"] = all(
            c["ratio"] <= HINGE_COST_LIMIT for c in hinge_cost.values())
    out["met"] = checks
    return out


def environment(cfg: BenchConfig | None = None) -> dict:
    import numba
    import scipy

    env = {"rod_sim": __version__, "python": platform.python_version(),
           "numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__,
           "machine": platform.machine(), "processor": platform.processor() or "",
           "cpu": _cpu_name(), "cpu_count": os.cpu_count(),
           "load_average_1_5_15": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
           "numba_threads": numba.config.NUMBA_NUM_THREADS,
           "t_end_s": T_END, "scene_t_end_s": SCENE_T_END, "sample_rate_hz": RATE_HZ,
           "reference_rtol": BENCH_REFERENCE_RTOL,
           "reference_check_rtol": BENCH_CHECK_RTOL, "reference_max_gap_rad": REFERENCE_GAP,
           "atol": "= rtol", "timing": "integration alone (Simulator.run at 100 Hz output), "
                                      "median of the repeats, after a JIT warm-up",
           "date_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())}
    try:
        import mujoco
        env["mujoco"] = mujoco.__version__
    except ImportError:
        env["mujoco"] = "not installed"
    if cfg is not None:
        env.update({"quick": cfg.quick, "repeats": cfg.repeats, "cap_s": cfg.cap_s,
                    "scenes": list(cfg.scenes), **cfg.extra})
    return env


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def _finite(x):
    return x if isinstance(x, (int, str, list, type(None), bool)) or math.isfinite(x) else None


def as_json(rows, refs=None, cfg=None, scaling=None, hinge_cost=None, bound=None) -> dict:
    """Everything of one run: environment, references, rows, targets (per CPU and per wall
    second), scaling, ``hinge_rhs_cost`` and ``full_model_bound`` (None: not measured)."""
    out_rows = [{k: _finite(v) for k, v in asdict(r).items()} for r in rows]
    return {"environment": environment(cfg), "references": refs or {}, "rows": out_rows,
            "targets": targets(rows, key="rtf_cpu", hinge_cost=hinge_cost),
            "targets_wall": targets(rows, key="rtf", hinge_cost=hinge_cost),
            "scaling": scaling, "hinge_rhs_cost": hinge_cost, "full_model_bound": bound}
