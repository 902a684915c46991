"""Micro-benchmarks of ``rod-sim bench``: the cost of one right-hand side against n
(:func:`scaling`), of the deployment scene's hinge features (:func:`hinge_rhs_cost`), and the
stability bound on the full model's speed (:func:`full_model_bound`). Times in s, per rhs.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .config import MODELS, RATE_HZ, SCENE_T_END, T_END, load_bench_scene
from .runs import _core


def rhs_cost(model_name: str, scene, budget_s: float = 0.05) -> float:
    """Wall time of one right-hand side [s] inside the compiled rk4 loop (a bent, moving
    state: phi 0.1 rad, rates 0.5 rad/s)."""
    _, make_integrator, make_model, Simulator = _core()
    scene = scene.with_changes(phi0=np.full(scene.n, 0.1), phi_rate0=np.full(scene.n, 0.5))
    model = make_model(model_name, scene)
    steps = 1
    while True:
        sim = Simulator(model, make_integrator("rk4", step=1e-5))
        started = time.perf_counter()
        sim.advance(steps * 1e-5)
        wall = time.perf_counter() - started
        if wall > budget_s or steps >= 1 << 16:
            return wall / sim.stats.nfev
        steps *= 4


def paper_chain(n: int):
    """The paper's example with n rods: its first rod's length, mass, stiffness and hinge, node
    masses and tip pulses (at node n), a bent initial state (phi 0.1 rad, rates 0.5 rad/s)."""
    from rod_sim.core.scene import Scene

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
    return Scene.from_dict(d)


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


def full_model_bound(rows, scene_key: str = "paper_example", samples: int = 21) -> dict | None:
    """Why the full model runs at the speed it does on ``scene_key``, in numbers of this run.

    The largest |lambda| of the linearised full model (Jacobian by central differences at
    ``samples`` states of a run at rtol 1e-8, the largest over them), the stability limit of
    DOP853 on the ray of that eigenvalue (from its tableau), hence the largest stable step
    h_max = limit / |lambda| [s], the fewest steps and rhs evaluations (12 per step) any
    dop853-jit run over the span can take, and with the CPU time per rhs of this run's best
    dop853-jit row the highest RTF it could reach. radau-jit's best row gives its steps, rhs
    and CPU per step. None when the scene's full-model rows are missing."""
    from rod_sim.core import erk
    from rod_sim.core.stability import spectral_radius, stability_limit
    from .summary import best_at

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
        rhs_cost(m, paper_chain(8), 0.001)                           # warm-up / JIT
        costs = []
        for n in ns:
            scene = paper_chain(n)
            costs.append(min(rhs_cost(m, scene) for _ in range(2)))
            if log:
                log(f"scaling: {m} n={n} {costs[-1] * 1e6:.3g} us/rhs")
        out["per_rhs_s"][m] = costs
        sel = [i for i, n in enumerate(ns) if n >= 64]
        if len(sel) >= 2:
            p = np.polyfit(np.log([ns[i] for i in sel]), np.log([costs[i] for i in sel]), 1)[0]
            out["exponent_n_ge_64"][m] = float(p)
    return out
