"""Per-topic cost of building and CDR-encoding the logged messages (docs/recording_speed.md).

    python -m rod_sim.io.cdr_bench [--repeat 300]

For each topic the node records per control period (and diagnostics, clock): the median over
5 rounds of the time [us] to encode one message with mcap_ros2's ``serialize_dynamic`` (what
LogWriter used before) and with :func:`rod_sim.io.cdr.encoder`, after checking that both give
the same bytes; then the time to build the message dicts (:mod:`rod_sim.io.topics`). The scene
is config/paper_example.yaml (n = 8), reduced model, state at t = 0.05 s.
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _median_us(fn, arg, repeat: int) -> float:
    rounds = []
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(repeat):
            fn(arg)
        rounds.append((time.perf_counter() - start) / repeat * 1e6)
    return statistics.median(rounds)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rod_sim.io.cdr_bench", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=300, help="calls per round")
    args = parser.parse_args(argv)

    from mcap_ros2._dynamic import serialize_dynamic

    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator
    from rod_sim.io import cdr, msgdefs, topics
    from rod_sim.io.scene_yaml import load_scene

    scene = load_scene(REPO / "config" / "paper_example.yaml")
    traj = Simulator(make_model("reduced", scene), make_integrator("dop853-jit")).run(0.1, 1000)
    snap = traj.snapshot(50)
    msgs = topics.snapshot_messages(snap, scene, "world")
    msgs["diagnostics"] = topics.diagnostics(snap.t, {"rtf": 0.99, "steps": 1000}, scene.name)
    msgs["clock"] = topics.clock(snap.t)
    total_old = total_new = 0.0
    print(f"{'topic':15s} {'mcap_ros2 [us]':>15s} {'rod_sim.io.cdr [us]':>20s} {'bytes':>6s}")
    for name, msg in msgs.items():
        type_name = topics.TOPIC_TYPES[name]
        old = serialize_dynamic(type_name, msgdefs.SCHEMAS[type_name])[type_name]
        new = cdr.encoder(type_name)
        data = new(msg)
        if old(msg) != data:
            print(f"{name}: the encoders disagree")
            return 1
        t_old, t_new = _median_us(old, msg, args.repeat), _median_us(new, msg, args.repeat)
        if name in topics.DEFAULT_TOPICS:
            total_old += t_old
            total_new += t_new
        print(f"{name:15s} {t_old:15.1f} {t_new:20.1f} {len(data):6d}")
    print(f"{'6 per period':15s} {total_old:15.1f} {total_new:20.1f}")
    for name in topics.DEFAULT_TOPICS:
        cost = _median_us(lambda s: topics.snapshot_messages(s, scene, "world", [name]), snap,
                          args.repeat)
        print(f"build {name:15s} {cost:8.1f} us")
    cost = _median_us(lambda s: topics.snapshot_messages(s, scene, "world"), snap, args.repeat)
    print(f"build all 6       {cost:8.1f} us")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
