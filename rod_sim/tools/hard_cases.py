"""Hard cases: scenes that push the models and integrators, and the table of how the DEFAULT
settings (dop853-jit, rtol 1e-8, as ``rod-sim simulate`` and ``Simulator`` use them) fare.

``python -m rod_sim.tools.hard_cases [--quick] [--markdown]`` runs every case with the default
integrator, then a reference (the same model at rtol 1e-11) and prints wall time, right-hand
side evaluations, steps (rejected), max |phi_rate|, max |phi - phi_ref| and the validity
monitor's findings. ``test/test_hard_cases.py`` builds the same scenes (:func:`chain`) and checks
them against independent references.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..api import IntegrationError, Simulator, make_integrator, make_model
from ..core.scene import Scene
from ..core.validity import assess_trajectory

TIP_PULSES = "tip_pulses"


def chain(n=8, *, total_length=16.0, m=3.0, EI=1e5, mu=3.0, kappa=100.0, nu=0.01, phi=0.0,
          phi_rate=0.0, loads=TIP_PULSES, scale=1.0, name="hard") -> Scene:
    """The paper's example generalised: n equal rods of total length ``total_length`` [m],
    m [kg/m], EI [N m^2], node masses mu [kg] (scalar or list), hinges kappa [N m/rad],
    nu [N m s/rad]; ``loads`` = the paper's tip pulses times ``scale``, or a list of load dicts."""
    if loads == TIP_PULSES:
        loads = [{"node": n, "axis": "x", "shape": "raised_cosine_pulse",
                  "amplitude": -150.0 * scale, "start": 0.0, "duration": 0.5},
                 {"node": n, "axis": "y", "shape": "raised_cosine_pulse",
                  "amplitude": 1200.0 * scale, "start": 0.0, "duration": 1.0}]
    return Scene.from_dict({
        "name": name,
        "rods": {"count": n, "length": total_length / n, "mass_per_length": m,
                 "bending_stiffness": EI},
        "nodes": {"mass": mu}, "hinges": {"stiffness": kappa, "damping": nu},
        "initial": {"phi": phi, "phi_rate": phi_rate}, "loads": loads})


def folded(n=8, **kw) -> Scene:
    """A zig-zag folded array: neighbouring rods at 0 and +-(pi - 0.05) (hinges near +-pi)."""
    phi = [0.0 if k % 2 == 0 else (np.pi - 0.05) * (1 if (k // 2) % 2 == 0 else -1)
           for k in range(n)]
    return chain(n, phi=phi, **kw)


@dataclass
class Case:
    """One hard case: a scene, a model, an end time [s] and what it stresses."""

    name: str
    scene: Scene
    model: str
    t_end: float
    what: str
    forces_at: tuple = ()            # ((t [s], held forces (n, 2)), ...) set mid-run


def step_forces_case(model="reduced") -> Case:
    n = 8
    f = np.zeros((n, 2))
    f[-1] = (0.0, 300.0)
    g = np.zeros((n, 2))
    g[3] = (-200.0, 0.0)
    return Case(f"step commands ({model})", chain(n, loads=[]), model, 2.0,
                "Simulator.set_forces: 300 N at the tip from 0.3 s, -200 N x at node 4 "
                "instead from 1.1 s", ((0.3, f), (1.1, g)))


def cases(quick: bool = False) -> list[Case]:
    """The catalogue (``quick`` drops the largest and slowest ones)."""
    out = [
        Case("n = 256 rigid", chain(256), "rigid", 0.25, "large chain, O(n^3) per evaluation"),
        Case("n = 256 reduced", chain(256), "reduced", 0.25, "large chain"),
        Case("n = 64 full", chain(64), "full", 0.02, "large chain, stiff bending of short rods"),
        Case("EI = 1e8 full", chain(EI=1e8), "full", 2.0, "stiff bending (kHz modes)"),
        Case("EI = 1e8 reduced", chain(EI=1e8), "reduced", 2.0, "stiff bending"),
        Case("locked hinges full", chain(kappa=[100.0] + [1e6] * 7), "full", 2.0,
             "hinges 1..7 locked the paper's way (kappa 1e6)"),
        Case("locked hinges reduced", chain(kappa=[100.0] + [1e6] * 7), "reduced", 2.0,
             "hinges 1..7 locked (kappa 1e6)"),
        Case("free hinges full", chain(kappa=0.0, nu=0.0), "full", 2.0, "kappa = nu = 0"),
        Case("free hinges reduced", chain(kappa=0.0, nu=0.0), "reduced", 2.0, "kappa = nu = 0"),
        Case("1000 s undamped rigid",
             chain(nu=0.0, loads=[], phi_rate=[0.5, -0.3, 0.2, 0.1, -0.4, 0.3, 0.2, -0.1]),
             "rigid", 1000.0, "energy drift without damping"),
        Case("1000 s undamped reduced",
             chain(nu=0.0, loads=[], phi_rate=[0.5, -0.3, 0.2, 0.1, -0.4, 0.3, 0.2, -0.1]),
             "reduced", 1000.0, "energy drift without damping"),
        Case("100 s undamped full",
             chain(nu=0.0, loads=[], phi_rate=[0.5, -0.3, 0.2, 0.1, -0.4, 0.3, 0.2, -0.1]),
             "full", 100.0, "energy drift without damping"),
        Case("whipping tip reduced", chain(scale=4.0, kappa=10.0), "reduced", 2.0,
             "4x the paper's pulses, soft hinges: |phi_rate| ~ 50 rad/s"),
        Case("whipping tip full", chain(scale=4.0, kappa=10.0), "full", 2.0, "violent load"),
        Case("heavy tip full", chain(mu=[3.0] * 7 + [3000.0], scale=10.0), "full", 2.0,
             "tip mass 1000x the others"),
        Case("nearly massless rods reduced", chain(m=1e-6, mu=3.0), "reduced", 2.0,
             "m = 1e-6 kg/m: inertia in the node masses only"),
        Case("nearly massless rods full", chain(m=1e-3, mu=3.0), "full", 0.2,
             "m = 1e-3 kg/m: bending modes at ~40 kHz"),
        Case("folded full", folded(), "full", 2.0, "neighbouring rods near +-pi"),
        Case("folded reduced", folded(), "reduced", 2.0, "neighbouring rods near +-pi"),
        step_forces_case("reduced"),
        step_forces_case("full"),
    ]
    if quick:
        out = [c for c in out if not c.name.startswith(("n = 256", "n = 64", "100 s"))]
    return out


def run_case(case: Case, rtol: float | None = None):
    """Run a case with the default integrator (or dop853-jit at ``rtol``). Returns
    (trajectory or None, held forces (N, n, 2) per sample, wall [s], stats, error text)."""
    model = make_model(case.model, case.scene)
    Simulator(model, make_integrator(rtol=rtol)).advance(1e-4)    # compile outside the timing
    sim = Simulator(model, make_integrator(rtol=rtol))
    t_parts, y_parts, h_parts = [], [], []
    edges = [t for t, _ in case.forces_at] + [case.t_end]
    forces = [np.zeros((model.n, 2))] + [f for _, f in case.forces_at]
    start = time.perf_counter()
    error = None
    try:
        for k, (t1, f) in enumerate(zip(edges, forces)):
            sim.set_forces(f)
            tr = sim.run(t1, 100.0)
            s = 0 if k == 0 else 1
            t_parts.append(tr.t[s:])
            y_parts.append(tr.y[s:])
            h_parts.append(np.repeat(f[None], tr.t.size - s, axis=0))
    except IntegrationError as exc:
        error = str(exc)
    wall = time.perf_counter() - start
    if error:
        return None, None, wall, sim.stats, error
    from ..core.simulator import Trajectory
    traj = Trajectory(model, np.concatenate(t_parts), np.concatenate(y_parts))
    return traj, np.concatenate(h_parts), wall, sim.stats, None


def measure(case: Case) -> dict:
    """One table row: default run, reference run (rtol 1e-11), validity findings."""
    traj, held, wall, stats, error = run_case(case)
    row = {"case": case.name, "model": case.model, "n": case.scene.n, "t_end": case.t_end,
           "what": case.what, "wall_s": wall, "nfev": stats.nfev, "steps": stats.steps,
           "rejected": stats.rejected, "error": error}
    if traj is None:
        return row
    ref, _, ref_wall, _, ref_error = run_case(case, rtol=1e-11)
    row["max_phi_rate"] = float(np.max(np.abs(traj.phi_rate)))
    row["max_phi_error"] = (float(np.max(np.abs(traj.phi - ref.phi))) if ref is not None
                            else None)
    row["ref_wall_s"] = ref_wall
    step = max(1, traj.t.size // 400)
    mon = assess_trajectory(traj.model, traj.t[::step], traj.y[::step], held[::step])
    row["max_slope"] = max(mon.max_abs_alpha, mon.max_abs_beta)
    row["validity"] = "; ".join(sorted({f.kind for f in mon.findings()})) or "ok"
    return row


def markdown(rows: list[dict]) -> str:
    head = ("| case | model | n | t_end [s] | wall [s] | nfev | steps (rejected) | "
            "max abs phi_rate [rad/s] | max phi error vs rtol 1e-11 [rad] | max slope [rad] | "
            "validity monitor | outcome |\n|" + "---|" * 12)
    lines = [head]
    for r in rows:
        if r["error"]:
            lines.append(f"| {r['case']} | {r['model']} | {r['n']} | {r['t_end']:g} | "
                         f"{r['wall_s']:.3g} | {r['nfev']} | {r['steps']} ({r['rejected']}) | "
                         f"- | - | - | - | IntegrationError: {r['error']} |")
            continue
        err = r["max_phi_error"]
        lines.append(
            f"| {r['case']} | {r['model']} | {r['n']} | {r['t_end']:g} | {r['wall_s']:.3g} | "
            f"{r['nfev']} | {r['steps']} ({r['rejected']}) | {r['max_phi_rate']:.3g} | "
            f"{'n/a' if err is None else f'{err:.2g}'} | {r['max_slope']:.2g} | "
            f"{r['validity']} | ok |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rod_sim.tools.hard_cases",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the slowest cases")
    args = parser.parse_args(argv)
    rows = []
    for case in cases(args.quick):
        rows.append(measure(case))
        print(f"done: {case.name} ({rows[-1]['wall_s']:.2f} s)", file=sys.stderr, flush=True)
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
