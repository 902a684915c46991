"""Long chains for ``rod-sim bench`` (docs/bench.md, "Long chains"): cost per right-hand side
from n = 8 to 4096 beside Pinocchio's articulated-body algorithm on the same chain, start-up
(a 4-step ``rod-sim simulate`` in a fresh process) and peak memory against n, work-precision
rows of a uniform chain (n = 256, 1024) and of a stiff tether (n = 512 short rods), and
radau-jit's cost per step against n.

Every timing is one core, in this run; the rows name the settings that reproduce them.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from . import pinocchio_peer
from .config import TARGET_ERROR
from .micro import rhs_cost
from .config import cell

SCALING_NS = (8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096)
STARTUP_NS = (8, 256, 1024, 2048, 4096)
LONG_CHAIN_NS = (256, 1024)
LONG_T_END = 2.0
TETHER_N = 512
TETHER_T_END = 0.05          # dop853-jit needs ~2e-6 s steps on the full tether (4800 per 0.01 s)
RADAU_STEP_NS = (512, 1024, 2048, 4096)
PEER_MAX_N = 256
"""Pinocchio's Data grows as ~n^3 in memory here (64: 17 MB, 256: 0.58 GB, 512: 4.4 GB
measured): the peer is timed up to this n."""


def uniform_chain(n: int, load: bool = True):
    """The paper's rods, node masses and hinges (config/bench/chain_n32.yaml) with n rods at
    rest along x, the paper's two tip pulses at node n (``load``)."""
    from rod_sim.core.scene import Scene

    d = {"name": f"chain_n{n}",
         "rods": {"count": n, "length": 2.0, "mass_per_length": 3.0, "bending_stiffness": 1e5},
         "nodes": {"mass": 3.0}, "hinges": {"stiffness": 100.0, "damping": 0.01},
         "initial": {"phi": 0.0, "phi_rate": 0.0}}
    if load:
        d["loads"] = [{"node": n, "axis": "x", "shape": "raised_cosine_pulse",
                       "amplitude": -150.0, "start": 0.0, "duration": 0.5},
                      {"node": n, "axis": "y", "shape": "raised_cosine_pulse",
                       "amplitude": 1200.0, "start": 0.0, "duration": 1.0}]
    return Scene.from_dict(d)


def tether(n: int = TETHER_N):
    """A stiff tether: n rods of 5 cm (0.1 kg/m, EI 0.5 N m^2: first bending mode 1.56 kHz,
    growing as 1/l^2), soft damped hinges, hanging straight along x, a 0.2 s sideways pulse
    of 2 N at the tip."""
    from rod_sim.core.scene import Scene

    return Scene.from_dict({
        "name": f"tether_n{n}",
        "rods": {"count": n, "length": 0.05, "mass_per_length": 0.1, "bending_stiffness": 0.5},
        "nodes": {"mass": 0.001}, "hinges": {"stiffness": 2.0, "damping": 0.02},
        "initial": {"phi": 0.0, "phi_rate": 0.0},
        "loads": [{"node": n, "axis": "y", "shape": "raised_cosine_pulse", "amplitude": 2.0,
                   "start": 0.0, "duration": 0.2}]})


def scaling(ns=SCALING_NS, models=("rigid", "reduced", "full"), log=None) -> dict:
    """Cost per rhs [s] of each model and of Pinocchio's ``aba`` (per Python call, up to
    PEER_MAX_N; its accelerations first checked against the rigid model) for every n, the
    fitted exponents over n >= 512 and the issue-18 ratios."""
    say = log or (lambda s: None)
    out = {"n": list(ns), "per_rhs_s": {m: [] for m in models}, "pinocchio_aba_s": [],
           "pinocchio_data_bytes": [], "pinocchio_check": None}
    for m in models:
        rhs_cost(m, uniform_chain(8), 0.001)                       # JIT warm-up
    have_peer = pinocchio_peer.available()
    for n in ns:
        scene = uniform_chain(n)
        for m in models:
            out["per_rhs_s"][m].append(min(rhs_cost(m, scene) for _ in range(2)))
        peer = data = math.nan
        if have_peer and n <= PEER_MAX_N:
            from rod_sim.core.models import make_model

            err = pinocchio_peer.check(scene, make_model("rigid", scene))
            out["pinocchio_check"] = max(out["pinocchio_check"] or 0.0, err)
            data = pinocchio_peer.data_rss_bytes(scene)
            peer = min(pinocchio_peer.aba_cost(scene) for _ in range(2))
        out["pinocchio_aba_s"].append(peer)
        out["pinocchio_data_bytes"].append(data)
        say(f"scaling n={n}: " + ", ".join(f"{m} {out['per_rhs_s'][m][-1] * 1e6:.3g} us"
                                           for m in models)
            + (f", pinocchio aba {peer * 1e6:.3g} us" if peer == peer else ""))
    sel = [i for i, n in enumerate(ns) if n >= 512]
    out["exponent_n_ge_512"] = {
        m: float(np.polyfit(np.log([ns[i] for i in sel]),
                            np.log([out["per_rhs_s"][m][i] for i in sel]), 1)[0])
        for m in models} if len(sel) >= 2 else {}
    i512, i4096 = (ns.index(k) if k in ns else None for k in (512, 4096))
    if i512 is not None and i4096 is not None:
        out["ratio_4096_over_512"] = {m: out["per_rhs_s"][m][i4096] / out["per_rhs_s"][m][i512]
                                      for m in models}
    if 256 in ns and out["pinocchio_aba_s"][ns.index(256)] == out["pinocchio_aba_s"][
            ns.index(256)]:
        i = ns.index(256)
        out["over_pinocchio_at_256"] = {m: out["per_rhs_s"][m][i] / out["pinocchio_aba_s"][i]
                                        for m in models}
    return out


def startup(ns=STARTUP_NS, log=None) -> list[dict]:
    """Wall time [s] and peak RSS [bytes] of ``rod-sim simulate`` (reduced, 4 rk4 steps of
    0.1 ms, a fresh Python process, the numba cache warm) on the uniform chain of n rods."""
    from rod_sim.io.scene_yaml import scene_to_yaml

    say = log or (lambda s: None)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in ns:
            scene_file = Path(tmp) / f"chain_{n}.yaml"
            scene_file.write_text(scene_to_yaml(uniform_chain(n)))
            out = Path(tmp) / f"run_{n}.mcap"
            cmd = [sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(scene_file),
                   "--model", "reduced", "--integrator", "rk4", "--step", "1e-4",
                   "--t-end", "4e-4", "--out", str(out)]
            started = time.perf_counter()
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            timer = threading.Timer(900.0, proc.kill)
            timer.start()
            try:
                _, status, usage = os.wait4(proc.pid, 0)     # this child's own peak RSS
            finally:
                timer.cancel()
            wall = time.perf_counter() - started
            proc.returncode = os.waitstatus_to_exitcode(status)
            rows.append({"n": n, "wall_s": wall, "exit": proc.returncode,
                         "peak_rss_bytes": usage.ru_maxrss * 1024,
                         "command": " ".join(["rod-sim"] + cmd[3:4] + ["CHAIN.yaml"] + cmd[5:-2])})
            say(f"start-up n={n}: {wall:.2f} s, exit {proc.returncode}")
            out.unlink(missing_ok=True)
    return rows


def _phi_run(scene, model_name, integrator, rtol, t_end, rate=50.0):
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator

    sim = Simulator(make_model(model_name, scene), make_integrator(integrator, rtol=rtol))
    cpu = time.process_time()
    traj = sim.run(t_end, rate)
    return traj.phi, time.process_time() - cpu, sim.stats


def work_precision(scene, model_name, t_end, settings, ref_rtol=1e-11, check_rtol=1e-10,
                   log=None) -> dict:
    """Rows (integrator, rtol, CPU [s], RTF (CPU), max phi error [rad], rhs, steps) against a
    dop853-jit reference at ``ref_rtol`` (checked against ``check_rtol``)."""
    say = log or (lambda s: None)
    ref, ref_cpu, _ = _phi_run(scene, model_name, "dop853-jit", ref_rtol, t_end)
    chk, _, _ = _phi_run(scene, model_name, "dop853-jit", check_rtol, t_end)
    gap = float(np.max(np.abs(ref - chk)))
    rows = []
    for integrator, rtol in settings:
        _phi_run(scene, model_name, integrator, rtol, min(t_end, 1e-3))        # JIT warm-up
        phi, cpu, stats = _phi_run(scene, model_name, integrator, rtol, t_end)
        err = float(np.max(np.abs(phi - ref)))
        rows.append({"integrator": integrator, "rtol": rtol, "cpu_s": cpu,
                     "rtf_cpu": t_end / cpu, "max_phi_error": err, "nfev": stats.nfev,
                     "steps": stats.steps, "newton_iters": stats.newton_iters})
        say(f"{scene.name} {model_name} {integrator} rtol {rtol:g}: CPU {cpu:.3g} s, "
            f"RTF {t_end / cpu:.3g}, err {err:.2g}")
    return {"scene": scene.name, "n": scene.n, "model": model_name, "t_end": t_end,
            "reference_rtol": ref_rtol, "reference_gap": gap, "reference_cpu_s": ref_cpu,
            "rows": rows}


def best_rtf(block: dict, integrator: str, max_error=TARGET_ERROR) -> float:
    """Best CPU RTF of ``integrator``'s rows within ``max_error`` (nan: none)."""
    rtfs = [r["rtf_cpu"] for r in block["rows"]
            if r["integrator"] == integrator and r["max_phi_error"] <= max_error]
    return max(rtfs) if rtfs else math.nan


def radau_cost_per_step(ns=RADAU_STEP_NS, t_end=0.02, rtol=1e-7, log=None) -> dict:
    """radau-jit CPU time per accepted step [s] on the tether family (full model) against n."""
    say = log or (lambda s: None)
    out = {"n": list(ns), "cpu_per_step_s": [], "steps": [], "t_end": t_end, "rtol": rtol}
    _phi_run(tether(8), "full", "radau-jit", rtol, 1e-3)
    for n in ns:
        _, cpu, stats = _phi_run(tether(n), "full", "radau-jit", rtol, t_end)
        out["cpu_per_step_s"].append(cpu / max(stats.steps, 1))
        out["steps"].append(stats.steps)
        say(f"radau-jit tether n={n}: {cpu / max(stats.steps, 1) * 1e3:.3g} ms per step")
    c = out["cpu_per_step_s"]
    out["ratio_last_over_first"] = c[-1] / c[0]
    return out


def run_all(quick: bool = False, log=None) -> dict:
    """Every long-chain measurement of the bench (``quick``: small n only)."""
    if quick:
        return {"scaling": scaling((8, 64, 512), log=log)}
    data = {"scaling": scaling(log=log), "startup": startup(log=log)}
    settings = [("dop853-jit", r) for r in (1e-6, 1e-7, 1e-8, 1e-9)] + \
        [("radau-jit", r) for r in (1e-6, 1e-7, 1e-8)]
    data["long_chain"] = [work_precision(uniform_chain(n), "reduced", LONG_T_END, settings,
                                         log=log) for n in LONG_CHAIN_NS]
    tether_settings = [("dop853-jit", r) for r in (1e-6, 1e-7, 1e-8)] + \
        [("radau-jit", r) for r in (1e-5, 1e-6, 1e-7, 1e-8)]
    data["tether"] = [work_precision(tether(), m, TETHER_T_END, tether_settings, log=log)
                      for m in ("full", "reduced")]
    data["radau_per_step"] = radau_cost_per_step(log=log)
    return data


def targets(data: dict) -> dict:
    """The issue-18 targets that this run measured: name -> (value, met)."""
    t = {}
    sc = data.get("scaling") or {}
    for m, r in (sc.get("ratio_4096_over_512") or {}).items():
        t[f"{m}: cost(4096) / cost(512) <= 10"] = (r, r <= 10.0)
    limits = {"rigid": 0.5, "reduced": 1.0, "full": 3.0}
    for m, r in (sc.get("over_pinocchio_at_256") or {}).items():
        t[f"{m} rhs / Pinocchio aba at n = 256 <= {limits[m]:g}"] = (r, r <= limits[m])
    for block in data.get("long_chain") or []:
        need = 1.0 if block["n"] >= 1024 else 10.0
        rtf = max(best_rtf(block, "dop853-jit"), best_rtf(block, "radau-jit"))
        t[f"reduced chain n = {block['n']}, 0-{block['t_end']:g} s, RTF (CPU) >= {need:g}"] = (
            rtf, rtf >= need)
    for block in data.get("tether") or []:
        if block["model"] == "full":
            d, r = best_rtf(block, "dop853-jit"), best_rtf(block, "radau-jit")
            t[f"tether n = {block['n']} full: radau-jit RTF / dop853-jit RTF > 1"] = (
                r / d, r > d)
    rp = data.get("radau_per_step")
    if rp:
        t[f"radau-jit cost per step n = {rp['n'][-1]} / n = {rp['n'][0]} <= 10"] = (
            rp["ratio_last_over_first"], rp["ratio_last_over_first"] <= 10.0)
    for row in data.get("startup") or []:
        if row["n"] == 2048:
            t["start-up n = 2048 (4-step simulate, wall) < 20 s"] = (row["wall_s"],
                                                                     row["wall_s"] < 20.0)
    return t


def markdown_lines(data: dict) -> list[str]:
    """The "Long chains" section of results.md."""
    if not data:
        return []
    lines = ["", "## Long chains (issue 18)", "", "| target | value | met |", "|---|---|---|"]
    for name, (value, met) in targets(data).items():
        lines.append(f"| {name} | {cell(value)} | {'yes' if met else 'no'} |")
    sc = data.get("scaling")
    if sc:
        models = list(sc["per_rhs_s"])
        lines += ["", "Cost per right-hand side (compiled rk4 loop, one core) and Pinocchio's "
                  "`aba` per call from Python on the same chain (its accelerations agree with "
                  f"the rigid model to {cell(sc.get('pinocchio_check'), '.1e')} relative); per "
                  "rod in ns:", "",
                  "| n | " + " | ".join(f"{m} [us]" for m in models)
                  + " | Pinocchio aba [us] | " + " | ".join(f"{m} [ns/rod]" for m in models)
                  + " | Pinocchio [ns/joint] | Pinocchio Data [MB] |",
                  "|---" * (2 * len(models) + 4) + "|"]
        for i, n in enumerate(sc["n"]):
            peer = sc["pinocchio_aba_s"][i]
            lines.append(f"| {n} | " + " | ".join(cell(sc["per_rhs_s"][m][i] * 1e6)
                                                  for m in models)
                         + f" | {cell(peer * 1e6)} | "
                         + " | ".join(cell(sc["per_rhs_s"][m][i] * 1e9 / n, ".0f") for m in models)
                         + f" | {cell(peer * 1e9 / n, '.0f')} | "
                         + f"{cell(sc['pinocchio_data_bytes'][i] / 1e6, '.0f')} |")
        lines += ["", "Fitted exponent (n >= 512): " + ", ".join(
            f"{m} {p:.2f}" for m, p in (sc.get("exponent_n_ge_512") or {}).items()) + "."]
    st = data.get("startup")
    if st:
        lines += ["", f"Start-up: `{st[0]['command']}` in a fresh process (numba cache warm):",
                  "", "| n | wall [s] | peak RSS [MB] | exit |", "|---|---|---|---|"]
        for r in st:
            lines.append(f"| {r['n']} | {cell(r['wall_s'])} | "
                         f"{cell(r['peak_rss_bytes'] / 1e6, '.0f')} | {r['exit']} |")
    for key, title in (("long_chain", "Uniform chain"), ("tether", "Stiff tether")):
        for block in data.get(key) or []:
            lines += ["", f"{title} `{block['scene']}` (n = {block['n']}), {block['model']} "
                      f"model, 0..{block['t_end']:g} s; reference dop853-jit rtol "
                      f"{block['reference_rtol']:g} (gap to 1e-10: "
                      f"{cell(block['reference_gap'], '.2g')} rad, CPU "
                      f"{cell(block['reference_cpu_s'])} s):", "",
                      "| integrator | rtol | CPU [s] | RTF (CPU) | phi err [rad] | rhs | steps | "
                      "Newton iterations |", "|---|---|---|---|---|---|---|---|"]
            for r in block["rows"]:
                lines.append(f"| {r['integrator']} | {r['rtol']:g} | {cell(r['cpu_s'])} | "
                             f"{cell(r['rtf_cpu'])} | {cell(r['max_phi_error'], '.2g')} | "
                             f"{r['nfev']} | {r['steps']} | {r['newton_iters']} |")
    rp = data.get("radau_per_step")
    if rp:
        lines += ["", f"radau-jit cost per accepted step on the tether family (full model, "
                  f"rtol {rp['rtol']:g}, 0..{rp['t_end']:g} s): " + ", ".join(
                      f"n = {n}: {c * 1e3:.3g} ms ({s} steps)"
                      for n, c, s in zip(rp["n"], rp["cpu_per_step_s"], rp["steps"])) + "."]
    return lines


def main(argv=None) -> int:
    """``python -m rod_sim.bench.long_chains [--quick]``: print the section's markdown."""
    import argparse
    import json

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="scaling at n = 8, 64, 512 only")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    data = run_all(args.quick, log=lambda s: print(s, file=sys.stderr, flush=True))
    print(json.dumps(data, indent=1) if args.json else "\n".join(markdown_lines(data)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
