"""Where cold compile time goes, and what numba's optimisation level costs at run time:
``python -m rod_sim.tools.jit_profile``.

Each measurement runs in a child process with an empty numba cache of its own
(``NUMBA_CACHE_DIR``) and the optimisation level ``NUMBA_OPT`` under test, so that every
driver compiles from scratch. Compile cost is the *CPU time of the process*
(``time.process_time``; the machine may be loaded, wall time would measure the neighbours),
split per compiled function by numba's compile events (only dispatchers compiled from scratch
fire them; a cache hit does not), and into type inference + lowering vs LLVM by numba's own
timers (``metadata['timers']``: ``compiler_lock`` the whole compile, ``llvm_lock`` LLVM's
part, both wall seconds). Run cost is the best of ``--repeats`` process CPU times of a
workload. Trajectories are saved per level and compared with ``np.array_equal``
(bit-identical or not).

    python -m rod_sim.tools.jit_profile --levels 3 2 1 0 --out /tmp/jit_profile

prints one table; ``--out`` keeps the JSON reports and the trajectories.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

CONFIG = Path(__file__).resolve().parents[2] / "config"

COMPILE_STEPS = (("paper_example.yaml", "reduced", "dop853-jit"),
                 ("paper_example.yaml", "full", "dop853-jit"),
                 ("paper_example.yaml", "full", "radau-jit"))
"""(scene, model, integrator) compiled in this order in one child, each for 1 ms."""
EXTRA_STEPS = (("paper_example.yaml", "full", "Radau"),
               ("deployment.yaml", "full", "dop853-jit"),
               ("deployment.yaml", "reduced", "dop853-jit"))
"""With ``--extra``: what a scipy method compiles, what a scene with hinge features adds."""

RUNS = (("paper", "paper_example.yaml", "reduced", "dop853-jit", 2.0),
        ("paper", "paper_example.yaml", "full", "dop853-jit", 2.0),
        ("paper", "paper_example.yaml", "full", "radau-jit", 2.0),
        ("chain1024", 1024, "reduced", "dop853-jit", 1.0))
MIN_RUN_CPU_S = 3.0
"""A workload is repeated until it has used this much CPU (and ``--repeats`` times)."""
"""(label, scene file or rod count, model, integrator, simulated seconds) timed after the
compiles; a rod count is the uniform chain of the long-chain benchmark."""


class CompileLog:
    """Listener of numba's ``numba:compile`` events: per outermost compile, the dispatcher's
    name, the process CPU seconds and the wall seconds it took, and the functions compiled
    from scratch inside it."""

    def __init__(self):
        from numba.core import event

        self.records: list[dict] = []
        self._local = threading.local()
        log = self

        class _Listener(event.Listener):
            def on_start(self, ev):
                stack = getattr(log._local, "stack", None)
                if stack is None:
                    stack = log._local.stack = []
                stack.append((ev.data["dispatcher"].py_func.__qualname__,
                              time.process_time(), time.perf_counter(), []))

            def on_end(self, ev):
                name, cpu0, wall0, inner = log._local.stack.pop()
                rec = {"name": name, "cpu": time.process_time() - cpu0,
                       "wall": time.perf_counter() - wall0, "inner": inner}
                if log._local.stack:
                    log._local.stack[-1][3].append(name)
                else:
                    log.records.append(rec)

        event.register("numba:compile", _Listener())

    def take(self) -> list[dict]:
        out, self.records = self.records, []
        return out


def _scene(spec):
    if isinstance(spec, int):
        from rod_sim.bench.long_chains import uniform_chain

        return uniform_chain(spec)
    from ..io.scene_yaml import load_scene

    return load_scene(CONFIG / spec)


def _timers(model, integrator_name: str) -> dict:
    """numba's timers of the driver an integrator name runs (empty for scipy's)."""
    disp = {"dop853-jit": model.compiled.dop853, "radau-jit": model.compiled.radau}.get(
        integrator_name)
    if disp is None or not disp.overloads:
        return {}
    cres = list(disp.overloads.values())[-1]
    return dict(cres.metadata.get("timers", {})) if cres.metadata else {}


def child(out_dir: Path, repeats: int, extra: bool = False, compile_steps: bool = True,
          runs: str = "") -> dict:
    """Compile COMPILE_STEPS then time RUNS in this process; save trajectories to out_dir."""
    from ..core.integrators import make_integrator
    from ..core.models import make_model
    from ..core.simulator import Simulator
    import numba

    log = CompileLog()
    report = {"opt": int(numba.config.OPT), "compiles": [], "runs": []}
    steps = (COMPILE_STEPS + (EXTRA_STEPS if extra else ())) if compile_steps else ()
    for scene, model_name, integ in steps:
        model = make_model(model_name, _scene(scene))
        sim = Simulator(model, make_integrator(integ))
        c0, w0 = time.process_time(), time.perf_counter()
        sim.advance(1e-3)
        report["compiles"].append({
            "driver": f"{model_name} x {integ} on {scene}", "cpu": time.process_time() - c0,
            "wall": time.perf_counter() - w0, "timers": _timers(model, integ),
            "events": log.take()})
        print(json.dumps(report["compiles"][-1])[:400], file=sys.stderr, flush=True)
    for label, scene, model_name, integ, t_end in RUNS:
        if runs and runs not in f"{label}_{model_name}_{integ}":
            continue
        model = make_model(model_name, _scene(scene))
        best, spent, reps = np.inf, 0.0, 0
        while reps < repeats or spent < MIN_RUN_CPU_S:
            sim = Simulator(model, make_integrator(integ))
            c0 = time.process_time()
            traj = sim.run(t_end)
            took = time.process_time() - c0
            best, spent, reps = min(best, took), spent + took, reps + 1
        name = f"{label}_{model_name}_{integ}"
        np.save(out_dir / f"{name}.npy", traj.y)
        report["runs"].append({"run": name, "cpu": best, "repeats": reps,
                               "compiled_during": log.take()})
    return report


def run_level(level: str, out: Path, repeats: int, extra: bool = False,
              cache: str | None = None, compile_steps: bool = True, runs: str = "") -> dict:
    """One child at NUMBA_OPT=level with an empty cache; its report."""
    lvl_dir = out / f"opt{level}"
    lvl_dir.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "NUMBA_OPT": str(level), "ROD_SIM_NUMBA_OPT": str(level)}
    if cache != "in-tree":
        env["NUMBA_CACHE_DIR"] = cache or tempfile.mkdtemp(prefix=f"numba_opt{level}_")
    subprocess.run([sys.executable, "-m", "rod_sim.tools.jit_profile", "--child",
                    str(lvl_dir), "--repeats", str(repeats), "--runs", runs] + ["--extra"] * extra
                   + ["--no-compile"] * (not compile_steps), env=env, check=True)
    return json.loads((lvl_dir / "report.json").read_text())


def table(reports: dict, out: Path) -> str:
    """Compile CPU per driver, run CPU per workload and bit-identity against the first
    level, one row per level."""
    lines = []
    levels = list(reports)
    ref = levels[0]
    for lvl in levels:
        r = reports[lvl]
        comp = ", ".join(f"{c['driver'].split(' on ')[0]}"
                         f"{'' if 'paper' in c['driver'] else ' (deploy)'} {c['cpu']:.1f}"
                         for c in r["compiles"])
        llvm = sum(c["timers"].get("llvm_lock", 0.0) for c in r["compiles"])
        total = sum(c["timers"].get("compiler_lock", 0.0) for c in r["compiles"])
        lines.append(f"NUMBA_OPT={lvl}: compile CPU s: {comp}; total "
                     f"{sum(c['cpu'] for c in r['compiles']):.1f} s (LLVM {llvm:.0f} of "
                     f"{total:.0f} s wall in numba's timers)")
        for run in r["runs"]:
            same = np.array_equal(np.load(out / f"opt{lvl}" / f"{run['run']}.npy"),
                                  np.load(out / f"opt{ref}" / f"{run['run']}.npy"))
            base = next(x["cpu"] for x in reports[ref]["runs"] if x["run"] == run["run"])
            lines.append(f"    run {run['run']}: {run['cpu']:.3f} s CPU "
                         f"({run['cpu'] / base:.2f} x NUMBA_OPT={ref}); "
                         f"bit-identical to NUMBA_OPT={ref}: {same}")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rod_sim.tools.jit_profile",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--levels", nargs="+", default=["3", "2", "1", "0"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--extra", action="store_true", help="also compile EXTRA_STEPS")
    parser.add_argument("--cache", default=None,
                        help="numba cache directory ('in-tree': the package's __pycache__; "
                             "default: a new empty one per level)")
    parser.add_argument("--no-compile", action="store_true",
                        help="time the runs only (with --cache: drivers cached there)")
    parser.add_argument("--runs", default="", help="only the runs whose name contains this")
    parser.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        report = child(args.child, args.repeats, args.extra, not args.no_compile, args.runs)
        (args.child / "report.json").write_text(json.dumps(report, indent=1))
        return 0
    out = args.out or Path(tempfile.mkdtemp(prefix="jit_profile_"))
    reports = {}
    for level in args.levels:
        done = out / f"opt{level}" / "report.json"
        reports[level] = (json.loads(done.read_text()) if done.exists()
                          else run_level(level, out, args.repeats, args.extra, args.cache,
                                         not args.no_compile, args.runs))
    text = table(reports, out)
    (out / "table.txt").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
