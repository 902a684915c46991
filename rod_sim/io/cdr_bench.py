"""Per-topic cost of building and CDR-encoding the logged messages (docs/recording_speed.md).

    python -m rod_sim.io.cdr_bench [--repeat 300]

For each topic the node records per control period (and diagnostics, clock): the median over
5 rounds of the time [us] to encode one message with mcap_ros2's ``serialize_dynamic`` (what
LogWriter used before) and with :func:`rod_sim.io.cdr.encoder`, after checking that both give
the same bytes; when the ``rosbags`` library is installed, also with its Jazzy type store's
``serialize_cdr``: on message objects built beforehand (``rosbags ser``, the serializer alone)
and from the same dicts (``rosbags dict``: building its message objects, then serializing; what
LogWriter would have to do). Then the time to build the message dicts
(:mod:`rod_sim.io.topics`). The scene is config/paper_example.yaml (n = 8), reduced model,
state at t = 0.05 s.
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


_DTYPES = {"float64": "<f8", "float32": "<f4", "int8": "i1", "uint8": "u1", "byte": "u1",
           "char": "i1", "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4",
           "int64": "<i8", "uint64": "<u8", "bool": "?"}


def rosbags_message(store, type_name: str, msg):
    """The rosbags message object of ``type_name`` holding the message dict ``msg`` (missing
    fields: zero, empty)."""
    import numpy as np

    def value(desc, v):
        kind, arg = desc
        if kind.name == "NAME":
            return rosbags_message(store, arg, v or {})
        if kind.name == "BASE":
            if v is not None:
                return v
            return "" if arg[0] == "string" else False if arg[0] == "bool" else 0
        inner = arg[0]
        items = [] if v is None else v
        if inner[0].name == "BASE" and inner[1][0] in _DTYPES:
            return np.asarray(items, dtype=_DTYPES[inner[1][0]])
        return [value(inner, x) for x in items]

    fields = store.fielddefs[type_name][1]
    return store.types[type_name](**{name: value(desc, msg.get(name)) for name, desc in fields})


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
    try:
        from rosbags.typesys import Stores, get_typestore
        store = get_typestore(Stores.ROS2_JAZZY)
    except ImportError:
        store = None
    totals = [0.0] * 4
    print(f"{'topic':15s} {'mcap_ros2 [us]':>15s} {'rod_sim.io.cdr [us]':>20s} {'bytes':>6s}"
          + (f" {'rosbags ser [us]':>17s} {'rosbags dict [us]':>18s}" if store else ""))
    for name, msg in msgs.items():
        type_name = topics.TOPIC_TYPES[name]
        old = serialize_dynamic(type_name, msgdefs.SCHEMAS[type_name])[type_name]
        new = cdr.encoder(type_name)
        data = new(msg)
        if old(msg) != data:
            print(f"{name}: the encoders disagree")
            return 1
        times = [_median_us(old, msg, args.repeat), _median_us(new, msg, args.repeat)]
        line = f"{name:15s} {times[0]:15.1f} {times[1]:20.1f} {len(data):6d}"
        if store is not None:
            obj = rosbags_message(store, type_name, msg)
            if bytes(store.serialize_cdr(obj, type_name)) != data:
                print(f"{name}: rosbags' bytes differ")
                return 1
            times.append(_median_us(lambda o: store.serialize_cdr(o, type_name), obj,
                                    args.repeat))
            times.append(_median_us(lambda m: store.serialize_cdr(
                rosbags_message(store, type_name, m), type_name), msg, args.repeat))
            line += f" {times[2]:17.1f} {times[3]:18.1f}"
        if name in topics.DEFAULT_TOPICS:
            totals = [a + b for a, b in zip(totals, times + [0.0] * (4 - len(times)))]
        print(line)
    print(f"{'6 per period':15s} {totals[0]:15.1f} {totals[1]:20.1f} {'':6s}"
          + (f" {totals[2]:17.1f} {totals[3]:18.1f}" if store else ""))
    for name in topics.DEFAULT_TOPICS:
        cost = _median_us(lambda s: topics.snapshot_messages(s, scene, "world", [name]), snap,
                          args.repeat)
        print(f"build {name:15s} {cost:8.1f} us")
    cost = _median_us(lambda s: topics.snapshot_messages(s, scene, "world"), snap, args.repeat)
    print(f"build all 6       {cost:8.1f} us")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
