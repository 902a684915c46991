"""Where the time of a radau-jit run goes: work counters of one run times the measured unit
cost of each operation (rhs, Jacobian update, Newton matrix set-up pair, O(n) Newton solve
pair: :mod:`rod_sim.core.newton`), against the measured CPU time of the whole run.

``python -m rod_sim.tools.radau_cost [SCENE] [--model full] [--rtol 3e-6] [--t-end 2]``
(docs/bench.md, section "radau-jit"); ``--hard-cases`` instead times dop853-jit against
radau-jit on the full-model hard cases of ``rod_sim.tools.hard_cases``; ``--periods`` advances
the full model in control periods as the node does. Unit costs are the minimum over 5 batches of a compiled
loop (one core); the run's CPU time is the median of 5 runs after a warm-up.
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from ..core import newton, radau
from ..core.integrators import make_integrator
from ..core.jit import njit
from ..core.kernels import Problem
from ..core.models import make_model
from ..core.simulator import Simulator
from rod_sim.app.common import PAPER_EXAMPLE


@njit
def _loop_rhs(reps, rhs, y, chain, extra, loads, held, out):
    for _ in range(reps):
        rhs(0.1, y, chain, extra, loads, held, 0.1, out)


@njit
def _loop_jacobian(reps, rhs, y, chain, extra, loads, held, f, work, stats):
    problem = Problem(chain, extra, loads, held)
    for _ in range(reps):
        newton.chain_jac(rhs, problem, 0.1, 0.1, y, f, work, stats)


@njit
def _loop_factor(reps, chain, extra, work, h, stats):
    for r in range(reps):
        hr = h * (1.0 + 1e-6 * r)
        newton.chain_factor(chain, extra, work, radau.MU_REAL / hr,
                            complex(radau.MU_C_RE, radau.MU_C_IM) / hr, stats)


@njit
def _loop_solve(reps, chain, extra, work, h, fr, xr, fc, xc):
    for _ in range(reps):
        newton.chain_solve(chain, extra, work.jac, work.real, work.real_aux,
                           radau.MU_REAL / h, fr, xr)
        newton.chain_solve(chain, extra, work.jac, work.cplx, work.cplx_aux,
                           complex(radau.MU_C_RE, radau.MU_C_IM) / h, fc, xc)


def _unit_cost(fn, reps, *args) -> float:
    """Seconds per call: minimum over 5 batches of ``reps`` calls (after a warm-up)."""
    fn(1, *args)
    best = np.inf
    for _ in range(5):
        started = time.perf_counter()
        fn(reps, *args)
        best = min(best, (time.perf_counter() - started) / reps)
    return best


def measure(scene, model_name="full", rtol=3e-6, t_end=2.0) -> dict:
    """Counters of one radau-jit run, unit costs [s] and the run's CPU time [s]."""
    model = make_model(model_name, scene)
    Simulator(model, make_integrator("radau-jit", rtol=rtol)).run(t_end, 100.0)   # warm-up
    cpus = []
    for _ in range(5):
        sim = Simulator(model, make_integrator("radau-jit", rtol=rtol))
        started = time.process_time()
        traj = sim.run(t_end, 100.0)
        cpus.append(time.process_time() - started)
    y = traj.y[len(traj.t) // 2].copy()
    held = model._held(None)
    extra = model.new_data().plan().extra          # the model's constants with scratch
    args = (model.kernel, y, model.chain, extra, model.loads, held)
    n = y.size
    work = radau.chain_radau_workspace(model)
    stats = np.zeros(6, dtype=np.int64)
    f = model.rhs(0.1, y)
    s = sim.stats
    h = t_end / max(s.steps, 1)
    unit = {"rhs": _unit_cost(_loop_rhs, 20000, *args, np.empty(n)),
            "jacobian": _unit_cost(_loop_jacobian, 300, *args, f, work, stats),
            "lu_pair": _unit_cost(_loop_factor, 2000, model.chain, extra, work, h, stats),
            "solve_pair": _unit_cost(_loop_solve, 20000, model.chain, extra, work, h,
                                     np.random.default_rng(0).random(n), np.empty(n),
                                     np.ones(n, complex), np.empty(n, complex))}
    counts = {"rhs (Newton stages, step ends, error refinements)": (s.nfev, "rhs"),
              "Jacobian updates (the inertia's angles, O(n))": (s.njev, "jacobian"),
              "Newton matrix set-ups (real + complex, O(n))": (s.nlu, "lu_pair"),
              "O(n) Newton solve pairs (per Newton iteration)": (s.newton_iters,
                                                                  "solve_pair")}
    split = {k: {"count": c, "unit_us": unit[u] * 1e6, "total_ms": c * unit[u] * 1e3}
             for k, (c, u) in counts.items()}
    return {"model": model_name, "rtol": rtol, "t_end": t_end, "steps": s.steps,
            "rejected": s.rejected, "nfev": s.nfev, "njev": s.njev, "nlu": s.nlu,
            "newton_iterations": s.newton_iters, "cpu_ms": statistics.median(cpus) * 1e3,
            "split": split}


def format_report(r: dict) -> str:
    lines = [f"radau-jit, {r['model']} model, rtol {r['rtol']:g}, {r['t_end']:g} s: "
             f"{r['steps']} steps ({r['rejected']} rejected), {r['nfev']} rhs, {r['njev']} "
             f"Jacobians, {r['nlu']} LU pairs, {r['newton_iterations']} Newton iterations "
             f"({r['newton_iterations'] / max(r['steps'], 1):.2f} per step)",
             f"{'operation':50s} {'count':>7s} {'unit [us]':>10s} {'total [ms]':>11s} {'share':>6s}"]
    total = sum(v["total_ms"] for v in r["split"].values())
    for k, v in r["split"].items():
        lines.append(f"{k:50s} {v['count']:7d} {v['unit_us']:10.3g} {v['total_ms']:11.3g} "
                     f"{v['total_ms'] / total:6.0%}")
    lines.append(f"{'sum of the parts':50s} {'':7s} {'':10s} {total:11.3g}")
    lines.append(f"{'measured CPU time of the run (median of 5)':50s} {'':7s} {'':10s} "
                 f"{r['cpu_ms']:11.3g}   -> {r['t_end'] / r['cpu_ms'] * 1e3:.0f}x real time")
    return "\n".join(lines)


HARD_CASES = ("n = 64 full", "EI = 1e8 full", "EI = 1e8 full, n = 16", "EI = 1e8 full, n = 32",
              "locked hinges full", "whipping tip full", "heavy tip full",
              "nearly massless rods full")
SETTINGS = (("dop853-jit", 1e-8), ("radau-jit", 1e-8), ("radau-jit", 1e-6))


def hard_case_rows(names=HARD_CASES, settings=SETTINGS) -> list[dict]:
    """The full-model hard cases of ``rod_sim.tools.hard_cases`` (those without commanded
    forces) with each (integrator, rtol): CPU time [s] of one run after a warm-up, work
    counters, max phi error against dop853-jit at rtol 1e-11."""
    from . import hard_cases

    larger = [hard_cases.Case(f"EI = 1e8 full, n = {n}", hard_cases.chain(n=n, EI=1e8), "full",
                              t_end, "stiff bending, more rods")
              for n, t_end in ((16, 1.0), (32, 0.5))]
    rows = []
    for case in hard_cases.cases() + larger:
        if case.name not in names or case.forces_at:
            continue
        model = make_model(case.model, case.scene)
        ref = Simulator(model, make_integrator("dop853-jit", rtol=1e-11)).run(case.t_end,
                                                                               100.0).phi
        for name, rtol in settings:
            Simulator(model, make_integrator(name, rtol=rtol)).advance(1e-4)     # compile
            sim = Simulator(model, make_integrator(name, rtol=rtol))
            started = time.process_time()
            phi = sim.run(case.t_end, 100.0).phi
            s = sim.stats
            rows.append({"case": case.name, "t_end": case.t_end, "integrator": name,
                         "rtol": rtol, "cpu_s": time.process_time() - started,
                         "nfev": s.nfev, "steps": s.steps, "rejected": s.rejected,
                         "njev": s.njev, "max_phi_error": float(np.max(np.abs(phi - ref)))})
    return rows


def format_hard_cases(rows) -> str:
    lines = ["| case | t_end [s] | integrator | rtol | CPU [s] | rhs | steps (rejected) | "
             "Jacobians | phi error [rad] |", "|---" * 9 + "|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['t_end']:g} | {r['integrator']} | {r['rtol']:g} | "
                     f"{r['cpu_s']:.3g} | {r['nfev']} | {r['steps']} ({r['rejected']}) | "
                     f"{r['njev']} | {r['max_phi_error']:.2g} |")
    return "\n".join(lines)


def period_rows(scene_files, periods=(0.01, 0.001), span=0.5, rtol=1e-8,
                integrators=("dop853-jit", "radau-jit")) -> list[dict]:
    """CPU time [s] of advancing the full model ``span`` s in control periods (as the node
    does) with each integrator, second of two runs, and its counters."""
    from ..io.scene_yaml import load_scene

    rows = []
    for path in scene_files:
        model = make_model("full", load_scene(path))
        for name, period in ((i, p) for i in integrators for p in periods):
            for _ in range(2):
                sim = Simulator(model, make_integrator(name, rtol=rtol))
                started = time.process_time()
                for _ in range(int(round(span / period))):
                    sim.advance(period)
                cpu = time.process_time() - started
            s = sim.stats
            rows.append({"scene": str(path), "integrator": name, "period_s": period,
                         "cpu_s": cpu, "nfev": s.nfev,
                         "njev": s.njev, "steps": s.steps})
    return rows


def main(argv=None) -> int:
    from ..io.scene_yaml import load_scene

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default=str(PAPER_EXAMPLE))
    parser.add_argument("--model", default="full", choices=("full", "reduced", "rigid"))
    parser.add_argument("--rtol", type=float, default=3e-6)
    parser.add_argument("--t-end", type=float, default=2.0)
    parser.add_argument("--hard-cases", action="store_true",
                        help="instead: dop853-jit against radau-jit on the full-model hard cases")
    parser.add_argument("--periods", action="store_true",
                        help="instead: the full model advanced in 10 ms and 1 ms periods")
    args = parser.parse_args(argv)
    if args.periods:
        for r in period_rows([args.scene, PAPER_EXAMPLE.parent / "bench" / "paper_stiff.yaml"]):
            print(f"{r['scene']}: {r['integrator']}, periods of {r['period_s'] * 1e3:g} ms: "
                  f"{r['cpu_s']:.3g} s CPU "
                  f"for 0.5 s, {r['nfev']} rhs, {r['njev']} Jacobians, {r['steps']} steps")
        return 0
    if args.hard_cases:
        print(format_hard_cases(hard_case_rows()))
        return 0
    print(format_report(measure(load_scene(args.scene), args.model, args.rtol, args.t_end)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
