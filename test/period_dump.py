"""Dump what the node's control period publishes and books (``PeriodRunner.run``: snapshots,
the energy ledger, the momentum ledger's diagnostics, the validity monitor, the balance
samples) over scripted runs, and compare two dumps bit for bit.

A change of the node's per-period bookkeeping must not change a single published or booked
number: run the dump on the tree before and after the change and compare::

    PYTHONPATH=<the tree before> python test/period_dump.py dump /tmp/before.pkl
    PYTHONPATH=<the tree after>  python test/period_dump.py dump /tmp/after.pkl
    python test/period_dump.py compare /tmp/before.pkl /tmp/after.pkl

(run it from a directory that is not another tree: ``python -m`` and a script's directory
come before PYTHONPATH.) Cases: the shipped scenes (plain chains, stops and latches, free,
prescribed base, two chains) and the paper example with step and constant loads (breakpoints
at period boundaries), each model the scene allows, in lockstep (a new command every period),
in the real-time mode with a command held for 5 periods, and with zero inputs; small
commands, and large ones on a few scenes so that stop contacts, latches and force jumps
happen. ``force_jump`` findings are reported apart (their time and value may move with the
way the jump is judged); every other value must be equal.
"""
from __future__ import annotations

import dataclasses
import math
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from trajectory_dump import _scene  # noqa: E402  (its scenes, paper_shapes included)


def _held(k: int, n: int, rows: int, amp: float) -> np.ndarray:
    """Command ``k`` (rows, 3): smooth in k, a free base's and wheel's rows too."""
    j = np.arange(n)
    h = np.zeros((rows, 3))
    h[:n, 0] = amp * np.sin(0.3 * k + j)
    h[:n, 1] = amp * np.cos(0.17 * k - j)
    h[:n, 2] = 0.1 * amp * np.sin(0.5 * k + 2 * j)
    if rows > n:
        h[n] = [amp * math.sin(k), amp * math.cos(k), 0.1 * amp * math.sin(2 * k)]
        h[n + 1, 2] = 0.05 * amp * math.cos(k)
    return h


def _plain(x):
    """x as comparable plain data: arrays by dtype, shape and bytes, floats by hex."""
    if dataclasses.is_dataclass(x):
        return {f.name: _plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return ("nd", x.dtype.str, x.shape, x.tobytes())
    if isinstance(x, (float, np.floating)):
        return ("f", float(x).hex())
    return x


def run_case(scene_name, model_name, rate_hz, periods, ahead, pattern, amp) -> list[dict]:
    """One run's records, one per period (and the final booking)."""
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator
    from rod_sim.core.validity import balance_sample
    from rod_sim.ros import budget
    from rod_sim.ros.period import PeriodRunner

    model = make_model(model_name, _scene(scene_name))
    integ = make_integrator("dop853-jit", rtol=1e-8)
    sim = Simulator(model, integ)
    work = budget.fallback(integ, 1000.0)
    work.apply(sim)
    runner = PeriodRunner(sim, work, int(1e9 / rate_hz), ahead=ahead)
    n = model.n
    rows = n + 2 if model.is_spacecraft and model.nb else n
    out = []
    for k in range(periods):
        h = np.zeros((rows, 3)) if pattern(k) is None else _held(pattern(k), n, rows, amp)
        if k % 7 == 3 and rows == n:
            h = h[:, :2].copy()                    # (n, 2) forces
        snap = runner.run(h)
        ledger, mon = runner.ledger, runner.validity
        span = _plain(runner._span_start)
        if isinstance(span, dict):
            span.pop("energy")          # a span's start energy is never read (nan there)
        rec = {"k": k, "error": runner.error, "snapshot": _plain(snap), "span": span,
               "ledger": _plain([ledger.energy0, ledger.energy, ledger.work, ledger.abs_work,
                                 ledger.impacts, ledger.unresolved, ledger.residual,
                                 ledger.scale]),
               "spacecraft": _plain(runner.spacecraft_values()),
               "validity": _plain([mon.max_abs_alpha, mon.max_abs_beta,
                                   mon.energy_residual, mon.energy_scale]),
               "findings": _plain([f for f in mon.findings() if f.kind != "force_jump"]),
               "force_jump": [(f.t, f.rod, f.value, f.message) for f in mon.findings()
                              if f.kind == "force_jump"],
               "held_for": runner.held_for,
               "events": [(e.t, e.kind) for e in sim.events]}
        if snap is not None and k % 5 == 0:
            rec["sample"] = _plain(balance_sample(model, sim.t, sim.y, sim.held, sim.mode))
        out.append(rec)
    runner.book()
    out.append({"final": _plain([runner.ledger.residual, runner.ledger.scale,
                                 runner.ledger.work])})
    return out


CASES = [(s, m, rate, amp) for s, models, rate, amp in (
    ("paper_example", ("reduced", "full", "rigid"), 1000.0, 1.0),
    ("paper_example", ("reduced",), 1000.0, 300.0),
    ("paper_shapes", ("reduced", "full", "rigid"), 100.0, 5.0),
    ("deployment", ("reduced", "rigid", "full"), 200.0, 0.5),
    ("deployment", ("reduced",), 200.0, 100.0),            # stop contacts, latches, jumps
    ("two_wing_deployment", ("reduced", "rigid"), 200.0, 0.5),
    ("two_wing_deployment", ("reduced",), 200.0, 50.0),
    ("spin_up_beam", ("reduced", "rigid"), 200.0, 0.5),
    ("spin_up_beam", ("reduced",), 200.0, 50.0),
    ("tether_pair", ("reduced",), 200.0, 0.5),
    ("hub_arm_latch", ("reduced", "rigid"), 200.0, 0.5)) for m in models]

PATTERNS = {"lockstep": (False, lambda k: k), "held5": (True, lambda k: k // 5),
            "zero": (True, lambda k: None)}


def dump(path: str) -> None:
    result = {}
    for scene_name, model_name, rate, amp in CASES:
        periods = 160 if scene_name == "deployment" else 45 if scene_name == "paper_shapes" \
            else 60 if rate >= 1000 else 40
        for name, (ahead, pattern) in PATTERNS.items():
            key = f"{scene_name}/{model_name}/{name}/{amp:g}"
            try:
                result[key] = run_case(scene_name, model_name, rate, periods, ahead, pattern,
                                       amp)
            except Exception as exc:  # noqa: BLE001 - recorded and compared
                result[key] = f"{type(exc).__name__}: {exc}"
            print(key, "ok" if not isinstance(result[key], str) else result[key], flush=True)
    Path(path).write_bytes(pickle.dumps(result))


def compare(path_a: str, path_b: str) -> int:
    a, b = (pickle.loads(Path(p).read_bytes()) for p in (path_a, path_b))
    if a.keys() != b.keys():
        print("the dumps hold different cases")
        return 1
    bad = moved = 0
    for key in a:
        ra, rb = a[key], b[key]
        if isinstance(ra, str) or isinstance(rb, str) or len(ra) != len(rb):
            bad += ra != rb
            continue
        for x, y in zip(ra, rb):
            for field in x:
                if field != "force_jump" and x[field] != y.get(field):
                    bad += 1
                    if bad <= 20:
                        print("differs:", key, x.get("k"), field)
        fa, fb = ra[-2]["force_jump"], rb[-2]["force_jump"]
        if fa != fb:
            moved += 1
            print(f"force_jump {key}: {len(fa)} -> {len(fb)} findings; " + "; ".join(
                f"rod {p[1]}->{q[1]} t {p[0]:.4g}->{q[0]:.4g} value {p[2]:.6g}->{q[2]:.6g}"
                for p, q in zip(fa, fb)))
    print(f"{len(a)} cases, {bad} differences outside force_jump, {moved} cases with other "
          f"force_jump findings")
    return 1 if bad else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["dump"] and len(sys.argv) == 3:
        dump(sys.argv[2])
    elif sys.argv[1:2] == ["compare"] and len(sys.argv) == 4:
        sys.exit(compare(sys.argv[2], sys.argv[3]))
    else:
        sys.exit("usage: period_dump.py dump OUT | compare A B")
