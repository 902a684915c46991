"""The spacecraft bench (issue 25, SPEC section 8): chains on a moving base, one core.

``rod-sim bench --spacecraft`` (or ``python -m rod_sim.bench.spacecraft [--json]``)
measures, each in one run so that the ratios share the machine's load:

- :func:`base_rhs_ratio`: the cost of one right-hand side (compiled rk4 loop) of 2 chains x
  2048 rods on a free base against the same chains on a fixed base, per model, timed
  alternately (``rounds`` times each, minimum kept); target ratio <= :data:`RHS_RATIO_TARGET`;
- :func:`two_wing_rtf`: the two-wing deployment (config/two_wing_deployment.yaml, reduced
  model) over :data:`TWO_WING_T_END` (every latch fires by 13.4 s): real-time factor of each
  setting and its max rod-angle error (over rods and 100 Hz samples, rod angles in Oxy) and
  base-angle error against a reference at rtol 1e-12 (checked against 1e-11); the fastest
  setting within :data:`TARGET_ERROR` is the result (target >= :data:`RTF_TARGET`);
- :func:`radau_scaling`: radau-jit on a free base with 2 chains x n rods, n = 128 .. 4096:
  wall time per step (accepted + rejected) and per simulated second, and the slope of
  cost per step against n on log-log (O(n): slope ~ 1);
- :func:`basilisk_comparison`: Basilisk (:mod:`.basilisk_peer`, hub + N hinged rigid panels,
  fixed-step RK4) against rod_sim's rigid model with N one-rod chains on a free base
  (dop853-jit), N = 2, 8, 32, 64, 128: each code's cheapest setting whose hub attitude at t_end
  is within :data:`PEER_ERROR` of its own tight reference, as simulated seconds per wall
  second; the two tight references are compared too (they must agree: same physics).

Times are wall times (``time.perf_counter``) of the integration alone after a JIT warm-up:
the median (two-wing rows, which give the CPU time too) or the minimum (peer rows) of at least
``repeats`` runs, repeated up to 0.3 s or 15 runs for fast ones (as ``rod-sim bench``).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from .config import CONFIG, FAST_BUDGET_S, MAX_REPEATS, MODELS, RATE_HZ, TARGET_ERROR

RHS_RATIO_TARGET = 1.1
RTF_TARGET = 1000.0
TWO_WING = CONFIG / "two_wing_deployment.yaml"
TWO_WING_T_END = 15.0
"""[s]: the deployment (the last latches fire at 13.4 s in every tolerance tried)."""
TWO_WING_SETTINGS = ([("dop853-jit", {"rtol": r, "atol": r})
                      for r in (1e-5, 1e-6, 3e-7, 1e-7, 1e-8, 1e-9, 1e-10)]
                     + [("radau-jit", {"rtol": r, "atol": r}) for r in (1e-5, 1e-6, 1e-7, 1e-8)])
RADAU_NS = (128, 256, 512, 1024, 2048, 4096)
PEER_NS = (2, 8, 32, 64, 128)
PEER_T_END = 5.0
PEER_ERROR = 1e-8
"""[rad]: the matched accuracy of the peer comparison (hub attitude at PEER_T_END against
each code's own tight reference)."""
PEER_RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)


def _core():
    from rod_sim.core.integrators import IntegrationError, make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator

    return IntegrationError, make_integrator, make_model, Simulator


def two_chain_scene(n: int, mode: str = "free"):
    """Two chains of ``n`` rods each (0.1 m, 1 kg/m, EI 1 N m^2, node masses 0.01 kg, hinges
    10 N m/rad and 0.01 N m s/rad) at (+-1, 0) m of a base (``mode`` free: 100 kg,
    50 kg m^2; fixed: at the origin), bent and moving (phi 0.1 rad + their direction, rates
    0.5 rad/s), turning at 0.1 rad/s (free)."""
    from rod_sim.core.scene import Scene

    chains = []
    for name, x, off in (("east", 1.0, 0.0), ("west", -1.0, math.pi)):
        chains.append({"name": name, "attach": [x, 0.0],
                       "rods": {"count": n, "length": 0.1, "mass_per_length": 1.0,
                                "bending_stiffness": 1.0},
                       "nodes": {"mass": 0.01},
                       "hinges": {"stiffness": 10.0, "damping": 0.01},
                       "initial": {"phi": off + 0.1, "phi_rate": 0.5}})
    base = ({"mode": "free", "mass": 100.0, "inertia": 50.0, "initial": {"psi_rate": 0.1}}
            if mode == "free" else {"mode": mode})
    return Scene.from_dict({"name": f"two_chains_{mode}_n{n}", "base": base, "chains": chains})


def base_rhs_ratio(n: int = 2048, models=MODELS, rounds: int = 7, span_s: float = 2e-3,
                   log=None) -> dict:
    """Cost per rhs [s] (compiled rk4 loop, step 1e-5 s over ``span_s``) of 2 chains x ``n``
    rods on a free base and on a fixed base, per model, timed alternately ``rounds`` times
    each (the minimum kept), and their ratio free / fixed."""
    _, make_integrator, make_model, Simulator = _core()
    out = {}
    for m in models:
        pair = {mode: make_model(m, two_chain_scene(n, mode)) for mode in ("free", "fixed")}
        for model in pair.values():                         # JIT warm-up
            Simulator(model, make_integrator("rk4", step=1e-5)).advance(2e-5)
        cost = {"free": math.inf, "fixed": math.inf}
        for _ in range(rounds):
            for mode, model in pair.items():
                sim = Simulator(model, make_integrator("rk4", step=1e-5))
                started = time.perf_counter()
                sim.advance(span_s)
                cost[mode] = min(cost[mode], (time.perf_counter() - started) / sim.stats.nfev)
        out[m] = {"free_s": cost["free"], "fixed_s": cost["fixed"],
                  "ratio": cost["free"] / cost["fixed"], "n_total": 2 * n, "rounds": rounds,
                  "span_s": span_s, "met": cost["free"] / cost["fixed"] <= RHS_RATIO_TARGET}
        if log:
            log(f"rhs free/fixed, 2 x {n} rods, {m}: {cost['free'] * 1e6:.4g} us / "
                f"{cost['fixed'] * 1e6:.4g} us = {out[m]['ratio']:.3f}")
    return out


def _run(model, integrator: str, settings: dict, t_end: float, repeats: int = 1):
    """(median wall [s], median CPU [s], phi (N, n), psi (N,), stats) of one setting."""
    _, make_integrator, _, Simulator = _core()
    Simulator(model, make_integrator(integrator, **settings)).advance(1e-3)    # JIT warm-up
    walls, cpus = [], []
    while len(walls) < max(1, repeats) or (sum(walls) < FAST_BUDGET_S
                                           and len(walls) < MAX_REPEATS):
        sim = Simulator(model, make_integrator(integrator, **settings))
        cpu0, started = time.process_time(), time.perf_counter()
        traj = sim.run(t_end, RATE_HZ)
        walls.append(time.perf_counter() - started)
        cpus.append(time.process_time() - cpu0)
    psi = traj.y[:, model.base_index + 2]
    return statistics.median(walls), statistics.median(cpus), traj.phi, psi, sim.stats


def two_wing_rtf(model_name: str = "reduced", t_end: float = TWO_WING_T_END,
                 repeats: int = 5, log=None) -> dict:
    """Real-time factor against error of the two-wing deployment (module docstring)."""
    from rod_sim.io.scene_yaml import load_scene

    IntegrationError = _core()[0]
    model = _core()[2](model_name, load_scene(str(TWO_WING)))
    _, _, check_phi, check_psi, _ = _run(model, "dop853-jit", {"rtol": 1e-11, "atol": 1e-11},
                                         t_end)
    _, _, ref_phi, ref_psi, _ = _run(model, "dop853-jit", {"rtol": 1e-12, "atol": 1e-12},
                                     t_end)
    gap = float(max(np.max(np.abs(check_phi - ref_phi)), np.max(np.abs(check_psi - ref_psi))))
    rows = []
    for integ, settings in TWO_WING_SETTINGS:
        row = {"integrator": integ, "rtol": settings["rtol"]}
        try:
            wall, cpu, phi, psi, st = _run(model, integ, settings, t_end, repeats)
        except IntegrationError as exc:
            row["status"] = f"failed: {exc}"
            rows.append(row)
            continue
        row.update(status="ok", wall_s=wall, cpu_s=cpu, rtf=t_end / wall, rtf_cpu=t_end / cpu,
                   nfev=st.nfev, steps=st.steps, rejected=st.rejected,
                   max_phi_error=float(np.max(np.abs(phi - ref_phi))),
                   max_psi_error=float(np.max(np.abs(psi - ref_psi))))
        row["met_error"] = row["max_phi_error"] <= TARGET_ERROR
        rows.append(row)
        if log:
            log(f"two-wing {model_name} {integ} rtol {settings['rtol']:g}: RTF {row['rtf']:.4g} "
                f"(wall {wall * 1e3:.3g} ms, {st.nfev} rhs), phi error "
                f"{row['max_phi_error']:.2g} rad, psi error {row['max_psi_error']:.2g} rad")
    ok = [r for r in rows if r.get("met_error")]
    best = max(ok, key=lambda r: r["rtf"]) if ok else None
    return {"scene": str(TWO_WING.name), "model": model_name, "t_end_s": t_end,
            "reference": {"rtol": 1e-12, "check_rtol": 1e-11, "gap_rad": gap,
                          "ok": gap <= 1e-9},
            "target_error_rad": TARGET_ERROR, "rows": rows, "best": best,
            "met": best is not None and best["rtf"] >= RTF_TARGET and gap <= 1e-9}


def radau_scaling(ns=RADAU_NS, models=("reduced", "full"), rtol: float = 1e-6,
                  t_end: float = 0.01, log=None) -> dict:
    """radau-jit (rtol = atol = ``rtol``) on 2 chains x n rods on a free base over [0, t_end]:
    wall time per step (accepted + rejected) [s] and per simulated second, and the fitted
    exponent p of cost per step ~ (2n)^p (least squares in log-log over every n)."""
    _, make_integrator, make_model, Simulator = _core()
    out = {"n_per_chain": list(ns), "rtol": rtol, "t_end_s": t_end, "models": {}}
    for m in models:
        rows = []
        for n in ns:
            model = make_model(m, two_chain_scene(n, "free"))
            Simulator(model, make_integrator("radau-jit", rtol=rtol, atol=rtol)).advance(1e-4)
            best = None
            for _ in range(2):
                sim = Simulator(model, make_integrator("radau-jit", rtol=rtol, atol=rtol))
                started = time.perf_counter()
                sim.advance(t_end)
                wall = time.perf_counter() - started
                if best is None or wall < best[0]:
                    best = (wall, sim.stats)
            wall, st = best
            steps = st.steps + st.rejected
            rows.append({"n_total": 2 * n, "wall_s": wall, "steps": steps, "nfev": st.nfev,
                         "njev": st.njev, "per_step_s": wall / steps,
                         "per_sim_second_s": wall / t_end})
            if log:
                log(f"radau-jit free base {m} 2 x {n}: {wall:.3g} s, {steps} steps, "
                    f"{wall / steps * 1e3:.3g} ms/step, {st.njev} Jacobians")
        x = np.log([r["n_total"] for r in rows])
        out["models"][m] = {"rows": rows,
                            "slope_per_step": float(np.polyfit(x, np.log([r["per_step_s"]
                                                                          for r in rows]), 1)[0]),
                            "slope_per_sim_second": float(np.polyfit(
                                x, np.log([r["per_sim_second_s"] for r in rows]), 1)[0])}
    return out


def peer_spacecraft(n_panels: int):
    """The peer's spacecraft with ``n_panels`` panels around a 750 kg, 600 kg m^2 hub turning
    at 0.1 rad/s: panel i (10 kg, 3 m, hinge spring 400 N m/rad, damper 2 N m s/rad) hinged
    at radius 1 m in the direction a_i = 2 pi i / N, pointing outwards, with initial hinge
    angle 0.05 sin(i + 1) rad and rate 0.1 cos(i) rad/s."""
    from .basilisk_peer import Panel, Spacecraft

    panels = []
    for i in range(n_panels):
        a = 2.0 * math.pi * i / n_panels
        panels.append(Panel((math.cos(a), math.sin(a)), a, 0.05 * math.sin(i + 1),
                            0.1 * math.cos(i)))
    return Spacecraft(750.0, 600.0, 0.1, tuple(panels), 10.0, 3.0, 400.0, 2.0)


def peer_scene(craft):
    """The same spacecraft as a rod_sim scene: one one-rod chain per panel (rest angle a_i,
    phi_i = a_i + theta_i, rate omega + theta_rate_i), a free base, no node masses."""
    from rod_sim.core.scene import Scene

    chains = [{"name": f"panel{i}", "attach": list(p.attach),
               "rods": {"count": 1, "length": craft.length,
                        "mass_per_length": craft.mass / craft.length,
                        "bending_stiffness": 1.0e6},
               "nodes": {"mass": 0.0},
               "hinges": {"stiffness": craft.k, "damping": craft.c, "rest_angle": p.angle},
               "initial": {"phi": [p.angle + p.theta], "phi_rate": [craft.omega + p.theta_rate]}}
              for i, p in enumerate(craft.panels)]
    base = {"mode": "free", "mass": craft.hub_mass, "inertia": craft.hub_inertia,
            "initial": {"psi_rate": craft.omega}}
    return Scene.from_dict({"name": f"peer_{len(craft.panels)}_panels", "base": base,
                            "chains": chains})


def _wrap(a: float) -> float:
    return float((a + math.pi) % (2.0 * math.pi) - math.pi)


def _rod_sim_final(model, rtol: float, t_end: float, repeats: int):
    """(min wall [s], psi at t_end, hinge angles theta (N,) at t_end, rhs count)."""
    _, make_integrator, _, Simulator = _core()
    Simulator(model, make_integrator("dop853-jit", rtol=rtol, atol=rtol)).advance(1e-3)
    best, total, runs = math.inf, 0.0, 0
    while runs < max(1, repeats) or (total < FAST_BUDGET_S and runs < MAX_REPEATS):
        sim = Simulator(model, make_integrator("dop853-jit", rtol=rtol, atol=rtol))
        started = time.perf_counter()
        sim.advance(t_end)
        wall = time.perf_counter() - started
        best, total, runs = min(best, wall), total + wall, runs + 1
    y = sim.y
    psi = float(y[model.base_index + 2])
    theta = model.phi(y) - psi - np.asarray(model.scene.hinge_rest_angle)
    return best, psi, theta, sim.stats.nfev


def basilisk_comparison(ns=PEER_NS, t_end: float = PEER_T_END, error: float = PEER_ERROR,
                        repeats: int = 3, log=None) -> dict:
    """Simulated seconds per wall second of Basilisk and of rod_sim's rigid model at matched
    accuracy (module docstring); ``available`` False when Basilisk is not installed."""
    from . import basilisk_peer as peer

    if not peer.available():
        return {"available": False, "reason": "Basilisk is not installed (pip install bsk)"}
    make_model = _core()[2]
    out = {"available": True, "t_end_s": t_end, "error_rad": error, "rows": []}
    for n in ns:
        craft = peer_spacecraft(n)
        model = make_model("rigid", peer_scene(craft))
        bsk_ref = peer.time_run(craft, t_end, 1e-4, repeats=1)
        _, ours_psi, ours_theta, _ = _rod_sim_final(model, 1e-12, t_end, 1)
        agree = {"psi_rad": abs(_wrap(ours_psi - bsk_ref.psi)),
                 "theta_rad": float(np.max(np.abs(ours_theta - bsk_ref.theta)))}
        bsk_rows = []
        for _, dt in peer.bench_settings():
            r = peer.time_run(craft, t_end, dt, repeats=repeats)
            bsk_rows.append({"step_s": dt, "wall_s": r.wall_s, "rate": t_end / r.wall_s,
                             "psi_error": abs(_wrap(r.psi - bsk_ref.psi))})
        ours_rows = []
        for rtol in PEER_RTOLS:
            wall, psi, _, nfev = _rod_sim_final(model, rtol, t_end, repeats)
            ours_rows.append({"rtol": rtol, "wall_s": wall, "rate": t_end / wall, "nfev": nfev,
                              "psi_error": abs(_wrap(psi - ours_psi))})
        pick = {name: max((r for r in rows if r["psi_error"] <= error),
                          key=lambda r: r["rate"], default=None)
                for name, rows in (("basilisk", bsk_rows), ("rod_sim", ours_rows))}
        row = {"panels": n, "references_agree": agree, "basilisk": bsk_rows,
               "rod_sim": ours_rows, "best_basilisk": pick["basilisk"],
               "best_rod_sim": pick["rod_sim"],
               "speedup": (pick["rod_sim"]["rate"] / pick["basilisk"]["rate"]
                           if pick["basilisk"] and pick["rod_sim"] else None)}
        out["rows"].append(row)
        if log:
            b, o = pick["basilisk"], pick["rod_sim"]
            log(f"peer N = {n}: references differ by psi {agree['psi_rad']:.2g} rad, theta "
                f"{agree['theta_rad']:.2g} rad; basilisk "
                + (f"{b['rate']:.4g} s/s (rk4 {b['step_s']:g} s, err {b['psi_error']:.2g})"
                   if b else "none within the error")
                + "; rod_sim " + (f"{o['rate']:.4g} s/s (rtol {o['rtol']:g}, err "
                                  f"{o['psi_error']:.2g})" if o else "none within the error"))
    return out


def run_all(parts=("rhs", "two_wing", "radau", "peer"), log=None) -> dict:
    """Every spacecraft measurement named in ``parts`` as one dict (the load average at the
    start and the end included)."""
    out = {"load_average_start": list(os.getloadavg())}
    if "rhs" in parts:
        out["rhs_free_vs_fixed"] = base_rhs_ratio(log=log)
    if "two_wing" in parts:
        out["two_wing"] = two_wing_rtf(log=log)
    if "radau" in parts:
        out["radau_scaling"] = radau_scaling(log=log)
    if "peer" in parts:
        out["basilisk"] = basilisk_comparison(log=log)
    out["load_average_end"] = list(os.getloadavg())
    return out


def format_text(res: dict) -> str:
    """The measured figures as a short text report (targets first)."""
    lines = [f"load average at start {res['load_average_start']}, end {res['load_average_end']}"]
    for m, r in res.get("rhs_free_vs_fixed", {}).items():
        lines.append(f"rhs 2 x {r['n_total'] // 2} rods, {m}: free {r['free_s'] * 1e6:.4g} us, "
                     f"fixed {r['fixed_s'] * 1e6:.4g} us, ratio {r['ratio']:.3f} (target <= "
                     f"{RHS_RATIO_TARGET:g}: {'met' if r['met'] else 'NOT met'})")
    tw = res.get("two_wing")
    if tw:
        b = tw["best"]
        lines.append(f"two-wing deployment, {tw['model']}, {tw['t_end_s']:g} s (reference gap "
                     f"{tw['reference']['gap_rad']:.2g} rad): "
                     + (f"RTF {b['rtf']:.4g} ({b['integrator']} rtol {b['rtol']:g}, phi error "
                        f"{b['max_phi_error']:.2g} rad, psi error {b['max_psi_error']:.2g} rad)"
                        if b else "no setting within the error")
                     + f" (target >= {RTF_TARGET:g}: {'met' if tw['met'] else 'NOT met'})")
    rs = res.get("radau_scaling")
    if rs:
        for m, r in rs["models"].items():
            lines.append(f"radau-jit free base {m}: cost/step slope {r['slope_per_step']:.3f}, "
                         f"cost/simulated-second slope {r['slope_per_sim_second']:.3f} over "
                         f"2 x {rs['n_per_chain'][0]} .. 2 x {rs['n_per_chain'][-1]} rods")
    pr = res.get("basilisk")
    if pr:
        if not pr["available"]:
            lines.append(f"Basilisk: {pr['reason']}")
        for r in pr.get("rows", []):
            b, o = r["best_basilisk"], r["best_rod_sim"]
            lines.append(f"N = {r['panels']} panels: Basilisk "
                         + (f"{b['rate']:.4g} s/s (rk4 step {b['step_s']:g})" if b else "-")
                         + ", rod_sim rigid " + (f"{o['rate']:.4g} s/s (rtol {o['rtol']:g})"
                                                 if o else "-")
                         + (f", ratio {r['speedup']:.3g}" if r["speedup"] else "")
                         + f"; references differ by {r['references_agree']['psi_rad']:.2g} rad")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rod_sim.bench.spacecraft",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", action="append", choices=("rhs", "two_wing", "radau", "peer"),
                        help="measure only this part (repeatable; default all)")
    parser.add_argument("--json", default=None, help="also write every figure to this file")
    args = parser.parse_args(argv)
    res = run_all(tuple(args.part or ("rhs", "two_wing", "radau", "peer")),
                  log=lambda s: print(s, file=sys.stderr, flush=True))
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1, default=float))
    print(format_text(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
