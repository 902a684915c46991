"""Speed against error (docs/bench.md): wall time, work counters and max phi error of each
scene, model and integrator setting, against verified converged references.

``rod-sim bench [--quick] [--json] [--out DIR]``. For each scene the converged reference of
every model (compiled DOP853 at ``REFERENCE_RTOL``) is first checked against a run at
``CHECK_RTOL``; a model whose reference fails the check gets no timed rows (its rows are listed
with the failure). Then every setting is timed: the integration alone (``Simulator.run``
sampling at 100 Hz, as the log does), the median of several repeats after a JIT warm-up.
Errors are max |phi - phi_ref| [rad] over rods and samples, against the reference of the same
model (``max_phi_error``) and against the full model's reference (``error_vs_full``; for the
full model both are the same). Runs that fail, diverge or would exceed the per-run wall-time
cap are listed with their status, not dropped.

``--out DIR`` writes ``bench.json``, ``results.md`` (tables), one work-precision plot per scene
(``wp_<scene>.png``, error against wall time, log-log) and the cost-per-rhs scaling plot
(``scaling.png``, n = 8 ... 512, with the fitted exponents).
"""
from __future__ import annotations

import copy
import json
import math
import os
import platform
import statistics
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.names import INTEGRATOR_NAMES, SCIPY_METHODS
from .common import EXIT_CHECK_FAILED, EXIT_OK, PAPER_EXAMPLE, UsageError

T_END = 2.0                 # simulated time of every run [s]
RATE_HZ = 100.0             # output samples [Hz of simulated time]
REFERENCE_RTOL = 1e-12      # converged reference (atol = rtol)
CHECK_RTOL = 1e-11          # the reference is checked against this looser run
REFERENCE_GAP = 1e-9        # largest allowed |phi(rtol 1e-11) - phi(rtol 1e-12)| [rad]
TARGET_ERROR = 1e-6         # the issue's accuracy for the speed targets [rad]
FAST_BUDGET_S = 0.3         # runs faster than this in total get up to MAX_REPEATS repeats
MAX_REPEATS = 15
PILOT_FRACTION = 0.05       # compiled runs: a pilot over this fraction of T_END predicts the wall
MODELS = ("reduced", "full", "rigid")
CONFIG = PAPER_EXAMPLE.parent
SCENES = {"paper_example": PAPER_EXAMPLE,
          "chain_n32": CONFIG / "bench" / "chain_n32.yaml",
          "chain_n128": CONFIG / "bench" / "chain_n128.yaml",
          "paper_stiff": CONFIG / "bench" / "paper_stiff.yaml",
          "deployment": CONFIG / "deployment.yaml"}
SCENE_T_END = {"deployment": 10.0}
"""Scenes run over another span than T_END [s] (the deployment latches at 1.0 ... 6.8 s)."""
QUICK_SCENES = ("paper_example",)
RADAU_RTOLS = (1e-4, 1e-5, 6e-6, 3e-6, 1e-6, 3e-7, 1e-7, 1e-8)
RADAU_RTOLS_QUICK = (1e-5, 3e-6, 1e-6)


COMMAND = "bench"
HELP = "speed against error of every model and integrator (docs/bench.md)"


def _core():
    """The numerical core, imported on first use (``rod-sim --help`` stays light)."""
    from ..core.integrators import IntegrationError, make_integrator
    from ..core.models import make_model
    from ..core.simulator import Simulator

    return IntegrationError, make_integrator, make_model, Simulator


class RunTimeout(RuntimeError):
    """A run would exceed (or exceeded) the per-run wall-time cap."""


@dataclass
class BenchRow:
    """One timed setting. Errors in rad, times in s; ``simulate_args`` are the ``rod-sim
    simulate`` options (after the scene file ``scene_file``) that reproduce the run."""

    scene: str
    n: int
    model: str
    integrator: str
    setting: str
    simulate_args: list | None
    wall_s: float
    sim_s: float
    rtf: float
    max_phi_error: float
    error_vs_full: float = math.nan
    model_error: float = math.nan
    max_hinge_error: float = math.nan      # max |theta - theta_ref| over hinges and samples
    cpu_s: float = math.nan
    rtf_cpu: float = math.nan
    nfev: int = 0
    steps: int = 0
    rejected: int = 0
    njev: int = 0               # Jacobians (radau-jit; their columns are counted in nfev)
    repeats: int = 0
    scene_file: str = ""
    status: str = "ok"


@dataclass
class Reference:
    """Converged phi (N, n) of one model on one scene and its check."""

    model: str
    phi: np.ndarray | None
    gap: float
    wall_s: float
    ok: bool
    message: str = ""


@dataclass
class BenchConfig:
    quick: bool = False
    repeats: int = 3
    cap_s: float = 45.0          # per-run wall-time cap
    scenes: tuple = ()
    models: tuple = MODELS
    integrators: tuple = ()      # only these integrators ('': all)
    mujoco: bool = True
    log: object = None           # callable(str) for progress lines, or None
    extra: dict = field(default_factory=dict)


# ------------------------------------------------------------------ scenes and settings
def load_bench_scene(key: str):
    from ..io.scene_yaml import load_scene

    return load_scene(str(SCENES[key]))


def settings_grid(model_name: str, quick: bool) -> list[tuple[str, dict]]:
    """(integrator, settings) pairs timed for one model (``quick``: fewer of them)."""
    rtols = (1e-4, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 1e-8, 1e-9, 1e-10)
    grid = [("dop853-jit", {"rtol": r}) for r in rtols]
    grid += [("radau-jit", {"rtol": r}) for r in (RADAU_RTOLS_QUICK if quick else RADAU_RTOLS)]
    if quick:
        grid += [("rk4", {"step": h}) for h in (2e-3, 1e-3, 5e-4)]
        grid += [("rk2", {"step": h}) for h in (2.5e-4, 1e-4)]
        grid += [("euler", {"step": 1e-4})]
        grid += [(m, {"rtol": 1e-7}) for m in SCIPY_METHODS]
        return grid
    grid += [("rk4", {"step": h}) for h in (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)]
    grid += [("rk2", {"step": h}) for h in (1e-3, 2.5e-4, 1e-4)]
    grid += [("euler", {"step": h}) for h in (1e-4, 1e-5)]
    grid += [(m, {"rtol": r}) for m in SCIPY_METHODS for r in (1e-5, 1e-7, 1e-9)]
    return grid


def simulate_args(model_name: str, integrator: str, settings: dict, t_end=T_END) -> list[str]:
    """``rod-sim simulate`` options reproducing one run (the scene file goes first)."""
    args = ["--model", model_name, "--integrator", integrator]
    for key in ("rtol", "atol", "step"):
        if key in settings:
            args += [f"--{key}", repr(float(settings[key]))]
    return args + ["--t-end", repr(float(t_end)), "--rate", repr(RATE_HZ)]


def describe_setting(settings: dict) -> str:
    return " ".join(f"{k}={v:g}" for k, v in settings.items())


# ------------------------------------------------------------------ references
def run_phi(scene, model_name, integrator, t_end=T_END, **settings):
    """phi (N, n) sampled at RATE_HZ on [0, t_end] and the run's work counters."""
    _, make_integrator, make_model, Simulator = _core()
    sim = Simulator(make_model(model_name, scene), make_integrator(integrator, **settings))
    traj = sim.run(t_end, RATE_HZ)
    return traj.phi, sim.stats


def reference(scene, model_name: str, rtol=REFERENCE_RTOL, check_rtol=CHECK_RTOL,
              max_gap=REFERENCE_GAP, t_end=T_END) -> Reference:
    """Reference phi of ``model_name`` at ``rtol``, checked against ``check_rtol``: ``ok`` only
    when the two differ by at most ``max_gap`` rad everywhere."""
    IntegrationError = _core()[0]
    started = time.perf_counter()
    try:
        loose, _ = run_phi(scene, model_name, "dop853-jit", t_end, rtol=check_rtol)
        tight, _ = run_phi(scene, model_name, "dop853-jit", t_end, rtol=rtol)
    except IntegrationError as exc:
        return Reference(model_name, None, math.nan, time.perf_counter() - started, False,
                         f"reference run failed: {exc.reason}")
    wall = time.perf_counter() - started
    gap = float(np.max(np.abs(loose - tight)))
    ok = bool(np.isfinite(gap) and gap <= max_gap)
    msg = "" if ok else (f"reference not converged: rtol {check_rtol:g} and {rtol:g} differ by "
                         f"{gap:.2g} rad > {max_gap:g}")
    return Reference(model_name, tight, gap, wall, ok, msg)


# ------------------------------------------------------------------ timing
def _deadline_model(model, deadline):
    """A copy of ``model`` whose Python-called kernel raises RunTimeout after ``deadline``
    (perf_counter seconds); scipy's integrators call the kernel from Python."""
    proxy = copy.copy(model)
    kernel = model.kernel

    def guarded(*args):
        if time.perf_counter() > deadline:
            raise RunTimeout("wall-time cap reached")
        kernel(*args)

    proxy.kernel = guarded
    return proxy


def time_run(scene, model_name, integrator, settings, repeats, cap_s, t_end=T_END):
    """(median wall [s], median CPU [s], phi (N, n), work counters of the last run, repeats).

    Compiled runs are preceded by a pilot over PILOT_FRACTION of the time span that predicts
    the full wall time; a prediction above ``cap_s`` raises RunTimeout without the long run.
    scipy runs are stopped by a deadline checked at every right-hand side."""
    _, make_integrator, make_model, Simulator = _core()
    model = make_model(model_name, scene)
    compiled = integrator not in SCIPY_METHODS
    if compiled:
        Simulator(model, make_integrator(integrator, **settings)).advance(1e-3)   # JIT warm-up
        started = time.perf_counter()
        Simulator(model, make_integrator(integrator, **settings)).run(t_end * PILOT_FRACTION,
                                                                      RATE_HZ)
        predicted = (time.perf_counter() - started) / PILOT_FRACTION
        if predicted > cap_s:
            raise RunTimeout(f"predicted {predicted:.3g} s > cap {cap_s:g} s (pilot over "
                             f"{t_end * PILOT_FRACTION:g} s)")
    walls, cpus = [], []
    phi = sim = None
    while True:
        run_model = model if compiled else _deadline_model(model, time.perf_counter() + cap_s)
        sim = Simulator(run_model, make_integrator(integrator, **settings))
        cpu0, started = time.process_time(), time.perf_counter()
        traj = sim.run(t_end, RATE_HZ)
        walls.append(time.perf_counter() - started)
        cpus.append(time.process_time() - cpu0)
        phi = traj.phi
        total = sum(walls)
        if len(walls) >= repeats and (total > FAST_BUDGET_S or len(walls) >= MAX_REPEATS):
            break                                       # fast runs: more repeats, same budget
        if total * (len(walls) + 1) / len(walls) > cap_s / 2:
            break                                       # slow runs: fewer repeats
    return statistics.median(walls), statistics.median(cpus), phi, sim.stats, len(walls)


def _max_err(phi, ref):
    if ref is None or phi is None:
        return math.nan
    return float(np.max(np.abs(phi - ref)))


def _hinge_err(phi, ref):
    """max |theta - theta_ref| [rad], theta the hinge angles (phi_1, phi_{k+1} - phi_k)."""
    if ref is None or phi is None:
        return math.nan
    return _max_err(np.diff(phi, prepend=0.0, axis=1), np.diff(ref, prepend=0.0, axis=1))


def bench_scene(key: str, cfg: BenchConfig) -> tuple[list[BenchRow], dict]:
    """Rows of one scene and its references' summary."""
    say = cfg.log or (lambda s: None)
    scene = load_bench_scene(key)
    t_end = SCENE_T_END.get(key, T_END)
    refs = {}
    for model_name in cfg.models:
        say(f"{key}: reference {model_name} ...")
        refs[model_name] = reference(scene, model_name, t_end=t_end)
        say(f"{key}: reference {model_name}: gap {refs[model_name].gap:.2g} rad, "
            f"{refs[model_name].wall_s:.2f} s {refs[model_name].message}")
    full_ref = refs["full"].phi if "full" in refs and refs["full"].ok else None
    rows = []
    for model_name in cfg.models:
        ref = refs[model_name]
        model_error = _max_err(ref.phi, full_ref) if ref.ok else math.nan
        for integrator, settings in settings_grid(model_name, cfg.quick):
            if cfg.integrators and integrator not in cfg.integrators:
                continue
            row = measure_setting(key, scene, model_name, integrator, settings, ref, full_ref,
                                  cfg, model_error)
            rows.append(row)
            say(f"{key}: {model_name:7s} {integrator:10s} {row.setting:12s} "
                f"rtf {row.rtf:9.4g} cpu-rtf {row.rtf_cpu:9.4g} err {row.max_phi_error:9.3g}  "
                f"{row.status}")
    if cfg.mujoco and "rigid" in refs and refs["rigid"].ok and not scene.has_hinge_features:
        rows += mujoco_rows(key, scene, refs, full_ref, cfg)
    summary = {m: {"ok": r.ok, "gap_rad": r.gap, "wall_s": r.wall_s, "message": r.message,
                   "rtol": REFERENCE_RTOL, "check_rtol": CHECK_RTOL}
               for m, r in refs.items()}
    return rows, summary


def measure_setting(key, scene, model_name, integrator, settings, ref: Reference, full_ref,
                    cfg: BenchConfig, model_error=math.nan) -> BenchRow:
    """Time one setting and measure its errors; failures become the row's status."""
    IntegrationError = _core()[0]
    t_end = SCENE_T_END.get(key, T_END)
    row = BenchRow(key, scene.n, model_name, integrator, describe_setting(settings),
                   simulate_args(model_name, integrator, settings, t_end), math.nan, t_end,
                   math.nan, math.nan, math.nan, model_error,
                   scene_file=os.path.relpath(SCENES.get(key, key)))
    if not ref.ok:
        row.status = f"not timed: {ref.message}"
        return row
    reps = 1 if integrator in SCIPY_METHODS and cfg.quick else cfg.repeats
    try:
        wall, cpu, phi, stats, done = time_run(scene, model_name, integrator, settings, reps,
                                               cfg.cap_s, t_end)
        row.wall_s, row.rtf = wall, t_end / wall
        row.cpu_s, row.rtf_cpu = cpu, t_end / max(cpu, 1e-9)
        row.max_phi_error = _max_err(phi, ref.phi)
        row.max_hinge_error = _hinge_err(phi, ref.phi)
        row.error_vs_full = _max_err(phi, full_ref)
        row.nfev, row.steps, row.rejected = stats.nfev, stats.steps, stats.rejected
        row.njev = stats.njev
        row.repeats = done
        if not np.isfinite(row.max_phi_error):
            row.status = "diverged (non-finite phi)"
    except IntegrationError as exc:
        row.status = f"failed at t = {exc.t:.4g} s: {exc.reason}"
    except RunTimeout as exc:
        row.status = f"timed out: {exc}"
    except ValueError as exc:                   # e.g. scipy's methods on a scene with stops
        row.status = f"refused: {exc}"
    return row


def mujoco_rows(key, scene, refs, full_ref, cfg) -> list[BenchRow]:
    """MuJoCo's rigid chain (the peer) at several time steps; listed as not run when the
    ``mujoco`` package is missing."""
    from . import mujoco_peer

    if not mujoco_peer.available():
        return [BenchRow(key, scene.n, "rigid", "mujoco", "-", None, math.nan, T_END, math.nan,
                         math.nan, status="not run: mujoco not installed (pip install "
                                          "'rod_sim[peer]')")]
    rows = []
    for integrator, dt in mujoco_peer.bench_settings(cfg.quick):
        row = BenchRow(key, scene.n, "rigid", f"mujoco-{integrator}", f"step={dt:g}", None,
                       math.nan, T_END, math.nan, math.nan,
                       model_error=_max_err(refs["rigid"].phi, full_ref),
                       scene_file=os.path.relpath(SCENES[key]))
        try:
            res = mujoco_peer.time_run(scene, T_END, RATE_HZ, dt, integrator,
                                       repeats=cfg.repeats, cap_s=cfg.cap_s)
            row.wall_s, row.rtf = res.wall_s, T_END / res.wall_s
            row.cpu_s, row.rtf_cpu = res.cpu_s, T_END / max(res.cpu_s, 1e-9)
            row.max_phi_error = _max_err(res.phi, refs["rigid"].phi)
            row.error_vs_full = _max_err(res.phi, full_ref)
            row.steps, row.repeats = res.steps, res.repeats
            if not np.isfinite(row.max_phi_error):
                row.status = "diverged (non-finite phi)"
        except mujoco_peer.PeerError as exc:
            row.status = f"failed: {exc}"
        rows.append(row)
        (cfg.log or (lambda s: None))(
            f"{key}: mujoco  {integrator:10s} {row.setting:12s} rtf {row.rtf:9.4g} "
            f"cpu-rtf {row.rtf_cpu:9.4g} "
            f"err {row.max_phi_error:9.3g}  {row.status}")
    return rows


# ------------------------------------------------------------------ summaries
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
           "reference_rtol": REFERENCE_RTOL,
           "reference_check_rtol": CHECK_RTOL, "reference_max_gap_rad": REFERENCE_GAP,
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


def format_rows(rows) -> str:
    lines = [f"{'scene':14s} {'model':8s} {'integrator':17s} {'setting':12s} {'wall [s]':>10s} "
             f"{'RTF':>9s} {'phi err':>9s} {'vs full':>9s} {'nfev':>8s} {'steps':>7s} "
             f"{'rej':>5s}  status"]
    for r in rows:
        lines.append(f"{r.scene:14s} {r.model:8s} {r.integrator:17s} {r.setting:12s} "
                     f"{r.wall_s:10.4g} {r.rtf:9.4g} {r.max_phi_error:9.3g} "
                     f"{r.error_vs_full:9.3g} {r.nfev:8d} {r.steps:7d} {r.rejected:5d}  "
                     f"{r.status}")
    return "\n".join(lines)


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


# ------------------------------------------------------------------ scaling of the rhs cost
def rhs_cost(model_name: str, n: int, budget_s: float = 0.05) -> float:
    """Wall time of one right-hand side [s] inside the compiled rk4 loop, chain of n rods
    (the paper's rods, tip pulses at node n, a bent initial state)."""
    from ..core.scene import Scene
    from .bench_long import rhs_cost as cost

    base = load_bench_scene("paper_example")
    d = base.to_dict()
    d["rods"]["count"] = n
    for key in ("length", "mass_per_length", "bending_stiffness"):
        d["rods"][key] = float(base.to_dict()["rods"][key][0])
    d["nodes"]["mass"] = float(d["nodes"]["mass"][0])
    for key in ("stiffness", "damping"):
        d["hinges"][key] = float(d["hinges"][key][0])
    d["initial"] = {"phi": 0.1, "phi_rate": 0.5}
    for ld in d["loads"]:
        ld["node"] = n
    return cost(model_name, Scene.from_dict(d), budget_s)


def hinge_rhs_cost(models=MODELS, rounds: int = 7, span_s: float = 0.2) -> dict:
    """Cost per rhs [s] (compiled rk4 loop, step 1e-5 s, over the first ``span_s`` of the
    deployment scene, before any event) of the deployment scene against the same chain without
    its hinge features (no rest angle, stop, latch or locked hinge), per model, and their
    ratio. The two are timed alternately, ``rounds`` times each, and the minimum of each is
    kept, so that a burst of load from other processes hits both or neither."""
    _, make_integrator, make_model, Simulator = _core()
    scene = load_bench_scene("deployment")
    n = scene.n
    plain = scene.with_changes(hinge_rest_angle=0.0, stop_lower=-math.inf,
                               stop_upper=math.inf, stop_stiffness=0.0, stop_damping=0.0,
                               latch_angle=math.nan, hinge_locked=False)
    out = {}
    for m in models:
        chains = {"hinge": make_model(m, scene), "plain": make_model(m, plain)}
        cost = {"hinge": math.inf, "plain": math.inf}
        for _ in range(rounds):
            for label, model in chains.items():
                sim = Simulator(model, make_integrator("rk4", step=1e-5))
                started = time.perf_counter()
                sim.advance(span_s)
                cost[label] = min(cost[label],
                                  (time.perf_counter() - started) / sim.stats.nfev)
        out[m] = {"hinge_s": cost["hinge"], "plain_s": cost["plain"],
                  "ratio": cost["hinge"] / cost["plain"], "n": n, "rounds": rounds,
                  "span_s": span_s}
    return out


HINGE_COST_LIMIT = 1.5
"""Issue 12: a hinge scene's cost per rhs within this factor of the plain chain's."""


def full_model_bound(rows, scene_key: str = "paper_example", samples: int = 21) -> dict | None:
    """Why the full model runs at the speed it does on ``scene_key``, in numbers of this run.

    The largest |lambda| of the linearised full model (Jacobian by central differences at
    ``samples`` states of a run at rtol 1e-8, the largest over them), the stability limit of
    DOP853 on the ray of that eigenvalue (from its tableau), hence the largest stable step
    h_max = limit / |lambda| [s], the fewest steps and rhs evaluations (12 per step) any
    dop853-jit run over the span can take, and with the CPU time per rhs of this run's best
    dop853-jit row the highest RTF it could reach. radau-jit's best row gives its steps, rhs
    and CPU per step. None when the scene's full-model rows are missing."""
    from ..core import erk
    from ..core.stability import spectral_radius, stability_limit

    best = {integ: best_at([r for r in rows if r.integrator == integ], "full", scene=scene_key)
            for integ in ("dop853-jit", "radau-jit")}
    if best["dop853-jit"] is None:
        return None
    _, make_integrator, make_model, Simulator = _core()
    scene = load_bench_scene(scene_key)
    t_end = SCENE_T_END.get(scene_key, T_END)
    model = make_model("full", scene)
    traj = Simulator(model, make_integrator("dop853-jit", rtol=1e-8)).run(t_end, RATE_HZ)
    picks = np.unique(np.linspace(0, len(traj.t) - 1, samples).round().astype(int))
    radius, lam = 0.0, 0j
    for i in picks:
        mode = None if traj.modes is None else traj.modes[i]
        r, l_ = spectral_radius(model, float(traj.t[i]), traj.y[i], mode=mode)
        if r > radius:
            radius, lam = r, l_
    stages = erk.B_DOP.shape[0]
    limit = stability_limit(erk.A_DOP[:stages, :stages], erk.B_DOP, direction=lam)
    h_max = limit / radius
    steps_min = math.ceil(t_end / h_max)
    d = best["dop853-jit"]
    per_rhs = d.cpu_s / d.nfev
    out = {"scene": scene_key, "t_end_s": t_end, "max_abs_lambda": radius,
           "lambda_real": lam.real, "lambda_imag": lam.imag, "states_sampled": len(picks),
           "dop853_stability_limit": limit, "dop853_stages": stages, "h_max_s": h_max,
           "dop853_min_steps": steps_min, "dop853_min_rhs": steps_min * stages,
           "dop853_best": {"setting": d.setting, "steps": d.steps, "rejected": d.rejected,
                           "rhs": d.nfev, "cpu_s": d.cpu_s, "cpu_per_rhs_s": per_rhs,
                           "rtf": d.rtf_cpu, "max_phi_error": d.max_phi_error},
           "dop853_rtf_bound": t_end / (steps_min * stages * per_rhs),
           "cpu_per_rhs_for_120x_at_min_rhs_s": t_end / (120.0 * steps_min * stages)}
    rd = best["radau-jit"]
    if rd is not None:
        out["radau_best"] = {"setting": rd.setting, "steps": rd.steps, "rejected": rd.rejected,
                             "rhs": rd.nfev, "jacobians": rd.njev, "cpu_s": rd.cpu_s,
                             "cpu_per_step_s": rd.cpu_s / max(1, rd.steps + rd.rejected),
                             "rhs_per_step": rd.nfev / max(1, rd.steps + rd.rejected),
                             "rtf": rd.rtf_cpu, "max_phi_error": rd.max_phi_error}
    return out


def scaling(models=MODELS, ns=(8, 16, 32, 64, 128, 256, 512), log=None) -> dict:
    """Cost per rhs [s] against n for each model and the exponent p of cost ~ n^p fitted
    (least squares in log-log) over n >= 64."""
    out = {"n": list(ns), "per_rhs_s": {}, "exponent_n_ge_64": {}}
    for m in models:
        rhs_cost(m, 8, 0.001)                                        # warm-up / JIT
        costs = []
        for n in ns:
            costs.append(min(rhs_cost(m, n) for _ in range(2)))
            if log:
                log(f"scaling: {m} n={n} {costs[-1] * 1e6:.3g} us/rhs")
        out["per_rhs_s"][m] = costs
        sel = [i for i, n in enumerate(ns) if n >= 64]
        if len(sel) >= 2:
            p = np.polyfit(np.log([ns[i] for i in sel]), np.log([costs[i] for i in sel]), 1)[0]
            out["exponent_n_ge_64"][m] = float(p)
    return out


# ------------------------------------------------------------------ report
def write_report(out_dir: Path, data: dict) -> list[Path]:
    """results.md, bench.json, wp_<scene>.png, scaling.png into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "bench.json"]
    written[0].write_text(json.dumps(data, indent=1))
    floats = ("wall_s", "rtf", "max_phi_error", "error_vs_full", "model_error", "cpu_s",
              "rtf_cpu", "max_hinge_error")
    rows = [BenchRow(**{k: (math.nan if v is None and k in floats else v)
                        for k, v in r.items()}) for r in data["rows"]]
    md = out_dir / "results.md"
    md.write_text(markdown(rows, data))
    written.append(md)
    written += plots(out_dir, rows, data.get("scaling"))
    return written


def _g(x, fmt=".3g"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


TARGET_TABLE = (
    # (label, key of targets(), check in targets()["met"] or None, error field)
    ("paper example, reduced >= 1000x", "paper_example_reduced", "reduced >= 1000x",
     "max_phi_error"),
    ("paper example, reduced >= 1300x (issue 12: no regression)", "paper_example_reduced",
     "reduced >= 1300x", "max_phi_error"),
    ("paper example, full >= 5x", "paper_example_full", "full >= 5x", "max_phi_error"),
    ("paper example, full >= 120x (issue 12, best integrator)", "paper_example_full",
     "full >= 120x", "max_phi_error"),
    ("n = 128, reduced >= 5x", "chain_n128_reduced", "n=128 reduced >= 5x", "max_phi_error"),
    ("deployment 0..10 s, reduced >= 1000x (hinge-angle error)", "deployment_reduced",
     "deployment reduced >= 1000x", "max_hinge_error"),
    ("deployment 0..10 s, full >= 20x (hinge-angle error)", "deployment_full",
     "deployment full >= 20x", "max_hinge_error"),
    ("paper example, rigid (no target)", "paper_example_rigid", None, "max_phi_error"),
    ("paper example, MuJoCo rigid peer (no target)", "paper_example_mujoco_rigid", None,
     "max_phi_error"),
)


def _met(tt, check):
    if check is None:
        return "-"
    if check not in tt["met"]:
        return "not run"
    return "yes" if tt["met"][check] else "**no**"


def _target_lines(t, tw) -> list[str]:
    """Rows of the targets table (CPU figures ``t``, wall figures ``tw``)."""
    lines = []
    for label, key, check, error in TARGET_TABLE:
        b, bw = t.get(key), tw.get(key)
        lines.append(f"| {label} | {_g(b and b['rtf'], '.4g')}x | "
                     f"{b['integrator'] + ' ' + b['setting'] if b else '-'} | "
                     f"{_g(b and b[error], '.2g')} | {_met(t, check)} | "
                     f"{_g(bw and bw['rtf'], '.4g')}x | {_met(tw, check)} |")
    lines.append(f"| reduced/full >= 100x (paper example) | "
                 f"{_g(t['reduced_over_full_speedup'], '.3g')}x | - | - | "
                 f"{_met(t, 'reduced/full >= 100x')} | "
                 f"{_g(tw['reduced_over_full_speedup'], '.3g')}x | "
                 f"{_met(tw, 'reduced/full >= 100x')} |")
    lines.append(f"| our rigid / MuJoCo rigid (no target) | "
                 f"{_g(t['rigid_over_mujoco_speedup'], '.3g')}x | - | - | - | "
                 f"{_g(tw['rigid_over_mujoco_speedup'], '.3g')}x | - |")
    return lines


def _hinge_cost_lines(cost, t) -> list[str]:
    """The per-rhs cost of the deployment scene's hinge features (issue 12)."""
    if not cost:
        return []
    check = f"hinge rhs cost <= {HINGE_COST_LIMIT:g}x plain"
    any_ = next(iter(cost.values()))
    lines = ["", f"Cost per rhs with the deployment scene's hinge features against the same "
                 f"chain without them (compiled rk4 loop over 0..{any_['span_s']:g} s, the two "
                 f"timed alternately {any_['rounds']} times, minimum of each; target <= "
                 f"{HINGE_COST_LIMIT:g}x: {_met(t, check)}):", "",
             "| model | with hinge features [us] | without [us] | ratio |", "|---|---|---|---|"]
    for m, c in cost.items():
        lines.append(f"| {m} | {c['hinge_s'] * 1e6:.3g} | {c['plain_s'] * 1e6:.3g} | "
                     f"{c['ratio']:.2f} |")
    return lines


def _bound_lines(b) -> list[str]:
    """Why the full model's speed is what it is (:func:`full_model_bound`), in words."""
    if not b:
        return []
    d = b["dop853_best"]
    lines = ["", f"### Why the full model is slower: the numbers of this run", "",
             f"- The linearised full model of `{b['scene']}` has max |lambda| = "
             f"{b['max_abs_lambda']:.4g} rad/s (lambda = {b['lambda_real']:.3g} "
             f"{b['lambda_imag']:+.4g}i: a bending vibration, nearly undamped; the largest "
             f"over {b['states_sampled']} states of the run).",
             f"- DOP853 is stable for h |lambda| <= {b['dop853_stability_limit']:.4g} on that "
             f"ray (from its tableau), so h <= {b['h_max_s'] * 1e3:.3g} ms: over "
             f"{b['t_end_s']:g} s at least {b['dop853_min_steps']} steps of "
             f"{b['dop853_stages']} rhs = {b['dop853_min_rhs']} rhs at **any** tolerance.",
             f"- This run's best dop853-jit row ({d['setting']}, phi error "
             f"{d['max_phi_error']:.2g} rad): {d['steps']} steps + {d['rejected']} rejected, "
             f"{d['rhs']} rhs, {d['cpu_per_rhs_s'] * 1e6:.3g} us CPU per rhs, "
             f"{d['rtf']:.3g}x. With no rejected step and the largest stable step it would "
             f"reach at most **{b['dop853_rtf_bound']:.3g}x**; 120x would need "
             f"<= {b['cpu_per_rhs_for_120x_at_min_rhs_s'] * 1e6:.3g} us per rhs at that "
             f"minimum."]
    r = b.get("radau_best")
    if r:
        lines.append(f"- radau-jit (implicit, not bound by stability) is bound by accuracy on "
                     f"the same vibrations: best row {r['setting']} (phi error "
                     f"{r['max_phi_error']:.2g} rad): {r['steps']} steps + {r['rejected']} "
                     f"rejected, {r['rhs']} rhs ({r['rhs_per_step']:.3g} per step, "
                     f"{r['jacobians']} Jacobians), {r['cpu_per_step_s'] * 1e6:.3g} us CPU per "
                     f"step: {r['rtf']:.3g}x. docs/bench.md splits that cost.")
    return lines


def markdown(rows, data) -> str:
    env = data["environment"]
    t = data["targets"]
    spans = "".join(f" ({k}: 0..{v:g} s)" for k, v in (env.get("scene_t_end_s") or {}).items())
    lines = ["# Benchmark results (generated by `rod-sim bench --out docs/bench`)", "",
             f"Generated {env['date_utc']} UTC on {env['cpu']} ({env['cpu_count']} cores, "
             f"load average {', '.join(f'{x:.1f}' for x in env['load_average_1_5_15'] or [])} "
             "at the end of the run: the machine is shared, timings are noisy). "
             f"rod_sim {env['rod_sim']}, Python {env['python']}, numpy {env['numpy']}, scipy "
             f"{env['scipy']}, numba {env['numba']}, mujoco {env['mujoco']}. "
             f"Each run: 0..{env['t_end_s']:g} s{spans}, "
             f"output at {env['sample_rate_hz']:g} Hz, "
             f"{env['timing']}; repeats {env.get('repeats')}, per-run cap {env.get('cap_s')} s. "
             f"Errors: max |phi - phi_ref| over rods and samples [rad] against the same model "
             f"at rtol {env['reference_rtol']:g} (checked against rtol "
             f"{env['reference_check_rtol']:g}: gap <= {env['reference_max_gap_rad']:g} rad); "
             "'hinge err' the same for the hinge angles (phi_1, phi_k+1 - phi_k); "
             "'vs full' against the full model's reference. RTF = simulated s / wall s.", "",
             f"## Targets (max phi error <= {t['max_phi_error']:g} rad, one run)", "",
             "RTF per CPU second of the process (one core; what other processes on the shared "
             "machine take is not counted) and per wall second (counted). The deployment "
             "targets are at max hinge-angle error <= the same bound (issue 12).", "",
             "| target | RTF (CPU) | best setting (CPU) | error [rad] | met (CPU) | RTF (wall) | "
             "met (wall) |", "|---|---|---|---|---|---|---|"]
    lines += _target_lines(t, data.get("targets_wall") or t)
    lines += _hinge_cost_lines(data.get("hinge_rhs_cost"), t)
    lines += _bound_lines(data.get("full_model_bound"))
    refs = data.get("references") or {}
    if refs:
        lines += ["", "## References", "", "| scene | model | gap rtol 1e-11 vs 1e-12 [rad] | "
                  "wall [s] | ok |", "|---|---|---|---|---|"]
        for scene, per in refs.items():
            for m, r in per.items():
                lines.append(f"| {scene} | {m} | {_g(r['gap_rad'], '.2g')} | "
                             f"{_g(r['wall_s'], '.3g')} | {'yes' if r['ok'] else r['message']} |")
    if data.get("long_chains"):
        from .bench_long import markdown_lines

        lines += markdown_lines(data["long_chains"])
    sc = data.get("scaling")
    if sc:
        lines += ["", "## Cost per right-hand side against n", "",
                  "| n | " + " | ".join(f"{m} [us]" for m in sc["per_rhs_s"]) + " |",
                  "|---" * (len(sc["per_rhs_s"]) + 1) + "|"]
        for i, n in enumerate(sc["n"]):
            lines.append(f"| {n} | " + " | ".join(_g(v[i] * 1e6, ".4g")
                                                  for v in sc["per_rhs_s"].values()) + " |")
        lines.append("")
        lines.append("Fitted exponent p (cost ~ n^p, n >= 64): " + ", ".join(
            f"{m} {p:.2f}" for m, p in sc["exponent_n_ge_64"].items()) + ".")
        lines.append("")
        lines.append("![cost per rhs](scaling.png)")
    for scene in dict.fromkeys(r.scene for r in rows):
        sub = [r for r in rows if r.scene == scene]
        lines += ["", f"## {scene} (n = {sub[0].n}, `{sub[0].scene_file}`)", "",
                  f"![work-precision {scene}](wp_{scene}.png)", "",
                  "| model | integrator | setting | wall [s] | RTF | CPU [s] | RTF (CPU) | "
                  "phi err | hinge err | vs full | model err | rhs evals | steps | rejected | "
                  "repeats | status |", "|---" * 16 + "|"]
        for r in sub:
            lines.append(f"| {r.model} | {r.integrator} | {r.setting} | {_g(r.wall_s, '.3g')} | "
                         f"{_g(r.rtf, '.4g')} | {_g(r.cpu_s, '.3g')} | {_g(r.rtf_cpu, '.4g')} | "
                         f"{_g(r.max_phi_error, '.2g')} | {_g(r.max_hinge_error, '.2g')} | "
                         f"{_g(r.error_vs_full, '.2g')} | {_g(r.model_error, '.2g')} | "
                         f"{r.nfev} | {r.steps} | {r.rejected} | {r.repeats} | {r.status} |")
    return "\n".join(lines) + "\n"


def plots(out_dir: Path, rows, scaling_data) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    markers = {"reduced": "o", "full": "s", "rigid": "^"}
    colors = plt.get_cmap("tab20").colors[::2] + plt.get_cmap("tab20").colors[1::2]
    integrators = list(dict.fromkeys(r.integrator for r in rows))
    for scene in dict.fromkeys(r.scene for r in rows):
        fig, ax = plt.subplots(figsize=(8, 6))
        sub = [r for r in rows if r.scene == scene and r.status == "ok"
               and r.max_phi_error > 0 and np.isfinite(r.cpu_s)]
        for key in dict.fromkeys((r.model, r.integrator) for r in sub):
            pts = sorted((r.cpu_s, r.max_phi_error) for r in sub if (r.model, r.integrator) == key)
            ax.loglog(*zip(*pts), marker=markers.get(key[0], "x"),
                      ls={"reduced": "-", "full": "--", "rigid": ":"}.get(key[0], "-"),
                      color=colors[integrators.index(key[1]) % len(colors)],
                      label=f"{key[0]} {key[1]}", ms=4, lw=1)
        ax.axhline(TARGET_ERROR, color="k", lw=0.6, ls=":")
        span = SCENE_T_END.get(scene, T_END)
        ax.axvline(span, color="r", lw=0.6, ls=":")
        ax.text(span, ax.get_ylim()[0], " real time", color="r", fontsize=7, va="bottom")
        ax.set_xlabel(f"CPU time [s] for {span:g} s simulated (median; one core)")
        ax.set_ylabel("max |phi - phi_ref| [rad] (same model)")
        n_rods = next(r.n for r in rows if r.scene == scene)
        ax.set_title(f"work-precision: {scene} (n = {n_rods})")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=6, ncol=2, title="color: integrator; line: - reduced, -- full, "
                                                  ": rigid", title_fontsize=6)
        path = out_dir / f"wp_{scene}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    if scaling_data:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        ns = np.array(scaling_data["n"])
        for m, costs in scaling_data["per_rhs_s"].items():
            p = scaling_data["exponent_n_ge_64"].get(m, math.nan)
            ax.loglog(ns, np.array(costs) * 1e6, marker=markers.get(m, "x"),
                      label=f"{m} (fit n>=64: n^{p:.2f})")
        ax.set_xlabel("n (rods)")
        ax.set_ylabel("wall time per right-hand side [us]")
        ax.set_title("cost per rhs (compiled, one core); per DOP853 step x12")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=8)
        path = out_dir / "scaling.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    return written


def format_targets(cpu: dict) -> str:
    """The speed targets of :func:`targets` as text (``--json`` gives every figure)."""
    lines = [f"speed targets at max |phi error| <= {cpu['max_phi_error']:g} rad "
             "(simulated s per CPU s):"]
    lines += [f"  {name}: {'met' if met else 'NOT met'}" for name, met in cpu["met"].items()]
    for key in ("reduced_over_full_speedup", "rigid_over_mujoco_speedup"):
        if cpu.get(key):
            lines.append(f"  {key.replace('_', ' ')}: {cpu[key]:.0f}x")
    return "\n".join(lines)


# ------------------------------------------------------------------ command line
def configure(parser) -> None:
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument("--quick", action="store_true",
                        help="the paper's example (n = 8) only, fewer settings (< 2 min)")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (median)")
    parser.add_argument("--cap", type=float, default=None,
                        help="per-run wall-time cap [s] (default 10 quick, 45 otherwise)")
    parser.add_argument("--scene", action="append", choices=sorted(SCENES), default=None,
                        help="bench only this scene (repeatable)")
    parser.add_argument("--model", action="append", choices=MODELS, default=None,
                        help="time only this model (repeatable; references of the others "
                             "are skipped too)")
    parser.add_argument("--integrator", action="append", choices=INTEGRATOR_NAMES,
                        default=None, help="time only this integrator (repeatable)")
    parser.add_argument("--no-mujoco", action="store_true", help="skip the MuJoCo peer")
    parser.add_argument("--no-scaling", action="store_true",
                        help="skip the cost-per-rhs scaling (n = 8 ... 512)")
    parser.add_argument("--no-long", action="store_true",
                        help="skip the long chains (n = 8 ... 4096 beside Pinocchio, start-up, "
                             "chain n = 256/1024, stiff tether n = 512; ~10 min)")
    parser.add_argument("--out", default=None,
                        help="directory for bench.json, results.md and the PNG plots")


def run(args) -> int:
    import sys

    if args.repeats < 1:
        raise UsageError(f"--repeats: must be >= 1 (got {args.repeats})")
    out_dir = Path(args.out) if args.out else None
    if out_dir is not None and out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"--out: {out_dir} is not a directory")
    scenes = tuple(args.scene) if args.scene else (QUICK_SCENES if args.quick else tuple(SCENES))
    cap = args.cap if args.cap is not None else (10.0 if args.quick else 45.0)
    cfg = BenchConfig(quick=args.quick, repeats=args.repeats, cap_s=cap, scenes=scenes,
                      models=tuple(args.model) if args.model else MODELS,
                      integrators=tuple(args.integrator or ()),
                      mujoco=not args.no_mujoco,
                      log=lambda s: print(s, file=sys.stderr, flush=True))
    rows, refs = [], {}
    cfg.extra["load_average_at_start"] = (list(os.getloadavg()) if hasattr(os, "getloadavg")
                                          else None)
    for key in scenes:
        r, summary = bench_scene(key, cfg)
        rows += r
        refs[key] = summary
    scale = None
    if out_dir is not None and not args.no_scaling and not args.quick:
        scale = scaling(log=cfg.log)
    long = None
    if out_dir is not None and not args.no_long and not args.quick:
        from . import bench_long

        long = bench_long.run_all(log=cfg.log)
    hinge_cost = bound = None
    if "deployment" in scenes:
        hinge_cost = hinge_rhs_cost(cfg.models)
        for m, c in hinge_cost.items():
            cfg.log(f"deployment: {m} rhs {c['hinge_s'] * 1e6:.3g} us with hinge features, "
                    f"{c['plain_s'] * 1e6:.3g} us without: ratio {c['ratio']:.2f}")
    if "paper_example" in scenes and "full" in cfg.models:
        bound = full_model_bound(rows)
        if bound:
            cfg.log(f"paper_example: full model |lambda|max {bound['max_abs_lambda']:.4g} rad/s, "
                    f"dop853-jit needs >= {bound['dop853_min_rhs']} rhs: RTF <= "
                    f"{bound['dop853_rtf_bound']:.3g}")
    data = as_json(rows, refs, cfg, scale, hinge_cost, bound)
    data["long_chains"] = long
    if out_dir is not None:
        for path in write_report(out_dir, data):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        print(json.dumps(data, indent=1))
    else:
        print(format_rows(rows))
        print(format_targets(data["targets"]))
    bad_refs = [f"{s}/{m}" for s, per in refs.items() for m, r in per.items() if not r["ok"]]
    if bad_refs:
        print(f"rod-sim bench: reference check failed for {', '.join(bad_refs)}", file=sys.stderr)
        return EXIT_CHECK_FAILED
    return EXIT_OK
