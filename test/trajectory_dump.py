"""Dump trajectories of every model x integrator on the paper example (and a variant with
step and constant loads, held forces and hinge torques), the two-wing deployment and the
spin-up beam, and compare two dumps bit for bit.

A refactoring of the core must not change a single bit of any result: run the dump on the
tree before and after the change and compare (np.array_equal on every array)::

    PYTHONPATH=/work/main python test/trajectory_dump.py dump /tmp/main.npz
    PYTHONPATH=.          python test/trajectory_dump.py dump /tmp/branch.npz
    python test/trajectory_dump.py compare /tmp/main.npz /tmp/branch.npz

Recorded per case: the sampled states, the end state, the latch modes, the hinge events
(time, hinge, kind), the work counters, and the Python-side quantities at the end
(snapshot arrays, energies, momentum, powers, the applied loads); a refused combination
records its one-line reason.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

CONFIG = Path(__file__).resolve().parents[1] / "config"

# scene -> (t_end [s], output rate [Hz])
CASES = {"paper_example": (0.6, 50.0), "paper_shapes": (0.6, 50.0),
         "two_wing_deployment": (1.0, 20.0), "spin_up_beam": (1.0, 20.0)}
FAST = ("dop853-jit", "radau-jit", "rk4", "rk2", "euler")
SCIPY = ("RK45", "DOP853", "Radau", "BDF", "LSODA")


def _scene(name):
    from rod_sim.io.scene_yaml import load_scene, scene_from_yaml_text
    if name != "paper_shapes":
        return load_scene(CONFIG / f"{name}.yaml")
    text = (CONFIG / "paper_example.yaml").read_text() + (
        "  - {node: 3, axis: x, shape: step, amplitude: 40.0, start: 0.1, duration: 0.2}\n"
        "  - {node: 5, axis: y, shape: constant, amplitude: -25.0, start: 0.25}\n"
        "  - {node: 8, axis: x, shape: raised_cosine_pulse, amplitude: 60.0, start: 0.3,"
        " duration: 0.2}\n")
    return scene_from_yaml_text(text)


def run_case(scene, model_name, integ_name, t_end, rate):
    """Arrays of one run (a dict of name -> np.ndarray)."""
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator

    model = make_model(model_name, scene)
    sim = Simulator(model, make_integrator(integ_name, rtol=1e-7,
                                             step=2e-4 if model_name == "full" else 2e-3))
    out = {}
    half = round(t_end / 2, 3)
    tr1 = sim.run(half, rate)
    if scene.name.startswith("paper"):
        sim.set_forces(np.linspace(-5.0, 5.0, 2 * model.n))
        sim.set_hinge_torques(np.linspace(0.0, 2.0, model.n))
    tr2 = sim.run(t_end, rate)
    for _ in range(3):
        sim.advance(0.01)
    out["Y"] = np.concatenate([tr1.y, tr2.y])
    out["t"] = np.concatenate([tr1.t, tr2.t])
    out["y_end"] = sim.y
    out["mode"] = sim.mode
    out["contact"] = sim.contact
    out["events"] = np.array([(e.t, e.hinge) for e in sim.events], dtype=float).reshape(-1, 2)
    out["event_kinds"] = np.array([e.kind for e in sim.events], dtype=str)
    st = sim.stats
    out["stats"] = np.array([st.nfev, st.steps, st.rejected, st.njev, st.nlu, st.newton_iters])
    snap = sim.snapshot()
    for f in ("phi", "phi_rate", "alpha", "beta", "hinge_angle", "hinge_rate",
              "hinge_moment", "nodes", "forces"):
        out["snap_" + f] = np.asarray(getattr(snap, f))
    e = model.energies(sim.t, sim.y, sim.held, mode=sim.mode)
    out["energies"] = np.array([e.kinetic, e.hinge, e.bending, e.gravity])
    mom = model.momentum(sim.t, sim.y, sim.held)
    out["momentum"] = np.array([*mom.linear, mom.angular_origin, mom.angular_com, *mom.com,
                                mom.mass])
    out["powers"] = np.array(model.powers(sim.t, sim.y, sim.held, sim.mode))
    out["loads"] = model.loads_at(sim.t, sim.held)
    out["rhs"] = model.rhs(sim.t, sim.y, sim.held, sim.mode)
    out["scripted"] = scene.scripted_load_table(0.37)
    return out


def dump(path, scenes=None, integrators=None):
    from rod_sim.core.models import MODELS
    arrays = {}
    for sname in scenes or CASES:
        t_end, rate = CASES[sname]
        scene = _scene(sname)
        for m in sorted(MODELS):
            for i in integrators or FAST + SCIPY:
                key = f"{sname}|{m}|{i}"
                t0, c0 = time.perf_counter(), time.process_time()
                try:
                    res = run_case(scene, m, i, t_end, rate)
                except Exception as exc:          # a refused combination: record why
                    arrays[key + "|refused"] = np.array(f"{type(exc).__name__}: {exc}")
                    print(f"{key}: refused ({type(exc).__name__})", flush=True)
                    continue
                for name, a in res.items():
                    arrays[f"{key}|{name}"] = a
                print(f"{key}: {time.perf_counter() - t0:.2f} s "
                      f"(CPU {time.process_time() - c0:.2f} s)", flush=True)
    np.savez(path, **arrays)


def compare(a_path, b_path) -> int:
    a, b = np.load(a_path), np.load(b_path)
    ka, kb = set(a.files), set(b.files)
    bad = 0
    for k in sorted(ka ^ kb):
        print(f"only in {'first' if k in ka else 'second'}: {k}")
        bad += 1
    for k in sorted(ka & kb):
        if not (a[k].shape == b[k].shape and a[k].dtype == b[k].dtype
                and np.array_equal(a[k], b[k])):
            print(f"DIFFERS: {k}")
            bad += 1
    print(f"{len(ka & kb)} arrays compared, {bad} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2], sys.argv[3].split(",") if len(sys.argv) > 3 else None,
             sys.argv[4].split(",") if len(sys.argv) > 4 else None)
    else:
        sys.exit(compare(sys.argv[2], sys.argv[3]))
