"""Speed against error (SPEC section 6): wall time and max phi error of each model and
integrator setting on the seed's example, against a verified converged reference.

Run with ``rod-sim bench [--json] [--quick]``. Timings are the integration alone
(``Simulator.run`` sampling at 100 Hz, as the log does), the median of several repeats,
after a JIT warm-up.
"""
from __future__ import annotations

import platform
import statistics
import time
from dataclasses import asdict, dataclass

import numpy as np

from .. import __version__
from ..core.integrators import IntegrationError, make_integrator
from ..core.models import make_model
from ..core.simulator import Simulator

T_END = 2.0
RATE_HZ = 100.0
REFERENCE_RTOL = 1e-13


@dataclass
class BenchRow:
    scene: str
    n: int
    model: str
    integrator: str
    setting: str
    simulate_args: list
    wall_s: float
    sim_s: float
    rtf: float
    max_phi_error: float
    nfev: int
    status: str = "ok"


def reference(scene, model_name: str) -> np.ndarray:
    """phi (N, n) at 100 Hz from a run at rtol 1e-13, verified against rtol 1e-12."""
    runs = [Simulator(make_model(model_name, scene), make_integrator("dop853-jit", rtol=r))
            .run(T_END, RATE_HZ).phi for r in (REFERENCE_RTOL * 10, REFERENCE_RTOL)]
    gap = float(np.max(np.abs(runs[0] - runs[1])))
    if gap > 1e-9:
        raise RuntimeError(f"reference for {model_name} not converged: rtol 1e-12 vs 1e-13 "
                           f"differ by {gap:.2g} rad")
    return runs[1]


def time_run(scene, model_name, integrator_name, repeats, **settings):
    """(median wall [s], phi (N, n), rhs evaluations) of one setting."""
    model = make_model(model_name, scene)
    Simulator(model, make_integrator(integrator_name, **settings)).advance(1e-3)  # warm-up
    walls = []
    for _ in range(repeats):
        integ = make_integrator(integrator_name, **settings)
        sim = Simulator(model, integ)
        started = time.perf_counter()
        traj = sim.run(T_END, RATE_HZ)
        walls.append(time.perf_counter() - started)
    return statistics.median(walls), traj.phi, integ.stats.nfev


def settings_grid(quick: bool):
    adaptive = [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    grid = [("dop853-jit", {"rtol": r}) for r in adaptive]
    grid += [("rk4", {"step": h}) for h in (2e-3, 1e-3, 5e-4, 2.5e-4)]
    if not quick:
        grid += [(m, {"rtol": r}) for m in ("DOP853", "RK45", "Radau", "BDF", "LSODA")
                 for r in (1e-6, 1e-8)]
    return grid


def run_bench(scene, models=("reduced", "full", "rigid"), quick=False, repeats=5) -> list[BenchRow]:
    rows = []
    for model_name in models:
        ref = reference(scene, model_name)
        for integrator_name, settings in settings_grid(quick):
            key, value = next(iter(settings.items()))
            args = ["--model", model_name, "--integrator", integrator_name,
                    f"--{key}", f"{value:g}"]
            try:
                wall, phi, nfev = time_run(scene, model_name, integrator_name,
                                           1 if integrator_name[0].isupper() else repeats,
                                           **settings)
                err = float(np.max(np.abs(phi - ref)))
                status = "ok" if np.isfinite(err) else "diverged"
            except IntegrationError as exc:
                wall, err, nfev, status = float("nan"), float("nan"), 0, f"failed: {exc.reason}"
            rows.append(BenchRow(scene.name, scene.n, model_name, integrator_name,
                                 f"{key}={value:g}", args, wall, T_END, T_END / wall, err, nfev,
                                 status))
    return rows


def best_at(rows, model, max_error):
    """Fastest row of ``model`` whose error is <= max_error, or None."""
    ok = [r for r in rows if r.model == model and r.status == "ok" and r.max_phi_error <= max_error]
    return max(ok, key=lambda r: r.rtf) if ok else None


def environment() -> dict:
    import numba
    import scipy

    return {"rod_sim": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__,
            "machine": platform.machine(), "processor": platform.processor(),
            "t_end_s": T_END, "sample_rate_hz": RATE_HZ, "reference_rtol": REFERENCE_RTOL}


def format_rows(rows) -> str:
    lines = [f"{'model':8s} {'integrator':11s} {'setting':12s} {'wall [s]':>10s} {'RTF':>9s} "
             f"{'max phi err':>12s} {'nfev':>7s}  status"]
    for r in rows:
        lines.append(f"{r.model:8s} {r.integrator:11s} {r.setting:12s} {r.wall_s:10.4g} "
                     f"{r.rtf:9.4g} {r.max_phi_error:12.3g} {r.nfev:7d}  {r.status}")
    return "\n".join(lines)


def targets(rows, max_error=1e-6) -> dict:
    """The issue's targets at max phi error <= 1e-6 rad: RTF of the fastest passing setting."""
    out = {}
    for model in ("reduced", "full", "rigid"):
        best = best_at(rows, model, max_error)
        out[model] = None if best is None else {"rtf": best.rtf, "setting": best.setting,
                                                "integrator": best.integrator,
                                                "max_phi_error": best.max_phi_error}
    if out.get("reduced") and out.get("full"):
        out["reduced_over_full_speedup"] = out["reduced"]["rtf"] / out["full"]["rtf"]
    return out


def as_json(rows) -> dict:
    return {"environment": environment(), "rows": [asdict(r) for r in rows],
            "targets_at_1e-6_rad": targets(rows)}
