"""The timed runs of ``rod-sim bench``: per scene the verified reference of every model, then
every setting of the grid timed (integration alone, median of repeats after a JIT warm-up) and
its errors measured; runs that fail, diverge or would exceed the cap become a row's status.
Peers (MuJoCo's rigid chain) give rows of the same kind (:func:`peer_rows`).
"""
from __future__ import annotations

import copy
import math
import os
import statistics
import time

import numpy as np

from rod_sim.core.names import SCIPY_METHODS
from .config import (BENCH_CHECK_RTOL, BENCH_REFERENCE_RTOL, FAST_BUDGET_S, MAX_REPEATS,
                     PILOT_FRACTION, RATE_HZ, REFERENCE_GAP, SCENE_T_END, SCENES, T_END,
                     BenchConfig, BenchRow, Reference, describe_setting, load_bench_scene,
                     settings_grid, simulate_args)


def _core():
    """The numerical core, imported on first use (``rod-sim --help`` stays light)."""
    from rod_sim.core.integrators import IntegrationError, make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator

    return IntegrationError, make_integrator, make_model, Simulator


class RunTimeout(RuntimeError):
    """A run would exceed (or exceeded) the per-run wall-time cap."""

def run_phi(scene, model_name, integrator, t_end=T_END, **settings):
    """phi (N, n) sampled at RATE_HZ on [0, t_end] and the run's work counters."""
    _, make_integrator, make_model, Simulator = _core()
    sim = Simulator(make_model(model_name, scene), make_integrator(integrator, **settings))
    traj = sim.run(t_end, RATE_HZ)
    return traj.phi, sim.stats


def reference(scene, model_name: str, rtol=BENCH_REFERENCE_RTOL, check_rtol=BENCH_CHECK_RTOL,
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
                   "rtol": BENCH_REFERENCE_RTOL, "check_rtol": BENCH_CHECK_RTOL}
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

    return peer_rows(mujoco_peer, key, scene, refs, full_ref, cfg)


def peer_rows(peer, key, scene, refs, full_ref, cfg) -> list[BenchRow]:
    """Rows of a peer simulator at each of its settings, errors against our reference of
    ``peer.MODEL``. ``peer`` is a module with NAME (its rows' integrator prefix), MODEL, and
    ``available()``, ``bench_settings(quick) -> [(integrator, dt [s])]``, ``time_run(scene,
    t_end, rate_hz, dt, integrator, repeats=, cap_s=)`` (wall_s, cpu_s, phi (N, n), steps,
    repeats) and ``PeerError`` (see :mod:`.mujoco_peer`): a new peer is such a module."""
    name, model = peer.NAME, peer.MODEL
    if not peer.available():
        return [BenchRow(key, scene.n, model, name, "-", None, math.nan, T_END, math.nan,
                         math.nan, status=f"not run: {name} not installed (pip install "
                                          "'rod_sim[peer]')")]
    rows = []
    for integrator, dt in peer.bench_settings(cfg.quick):
        row = BenchRow(key, scene.n, model, f"{name}-{integrator}", f"step={dt:g}", None,
                       math.nan, T_END, math.nan, math.nan,
                       model_error=_max_err(refs[model].phi, full_ref),
                       scene_file=os.path.relpath(SCENES[key]))
        try:
            res = peer.time_run(scene, T_END, RATE_HZ, dt, integrator,
                                repeats=cfg.repeats, cap_s=cfg.cap_s)
            row.wall_s, row.rtf = res.wall_s, T_END / res.wall_s
            row.cpu_s, row.rtf_cpu = res.cpu_s, T_END / max(res.cpu_s, 1e-9)
            row.max_phi_error = _max_err(res.phi, refs[model].phi)
            row.error_vs_full = _max_err(res.phi, full_ref)
            row.steps, row.repeats = res.steps, res.repeats
            if not np.isfinite(row.max_phi_error):
                row.status = "diverged (non-finite phi)"
        except peer.PeerError as exc:
            row.status = f"failed: {exc}"
        rows.append(row)
        (cfg.log or (lambda s: None))(
            f"{key}: {name:7s} {integrator:10s} {row.setting:12s} rtf {row.rtf:9.4g} "
            f"cpu-rtf {row.rtf_cpu:9.4g} "
            f"err {row.max_phi_error:9.3g}  {row.status}")
    return rows
