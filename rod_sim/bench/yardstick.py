"""How fast this machine runs rod_sim's three kinds of work right now: a yardstick for speed figures.

    python -m rod_sim.bench.yardstick [--rounds 5] [--json]

The machine these figures come from shares its cores with other jobs, and its speed swings
2-3x from hour to hour with the same code and a quiet load average (the node at n = 1024 and
1 kHz: RTF 0.95-1.00 in one phase, 0.48-0.78 in another). A speed figure is comparable with
another one only beside a yardstick measured at the same time. Three fixed workloads, each timed
``rounds`` times, taking turns:

- ``python``: a pure-Python loop of 200 000 iterations (integer and float arithmetic, a
  list append): the interpreter, which runs the glue of every period;
- ``numpy_small``: 1000 rounds of ten numpy calls on arrays of 8 elements: what a period of the
  n = 8 node is made of (a call's overhead, not its arithmetic);
- ``rhs_1024``: one reduced right-hand side of 1024 rods, compiled
  (:func:`rod_sim.bench.long_chains.uniform_chain`, random angles and rates), the median of 50
  calls back to back: compiled arithmetic on ~0.2 MB of work arrays.

Each is reported as its minimum [ms] over the rounds (what the machine can do now) and its
median (what other jobs left of it). :mod:`rod_sim.ros.rate_bench` measures it before and after each run.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np

WORKLOADS = ("python", "numpy_small", "rhs_1024")


def _python() -> None:
    acc, x, out = 0, 0.5, []
    for i in range(200_000):
        acc += i & 7
        x = x * 0.999 + 0.001
        if not i & 1023:
            out.append(x)


def _numpy_small(a: np.ndarray, b: np.ndarray) -> None:
    for _ in range(1000):
        c = a * b
        d = np.cos(a)
        e = c + d
        f = np.empty(8)
        np.subtract(e, b, out=f)
        g = f.cumsum()
        h = np.abs(g)
        float(h.max())
        np.concatenate([a, b])
        float(np.dot(a, b))


def _rhs_workload():
    """A function that runs the 1024-rod right-hand side 50 times and returns the median [s]."""
    from rod_sim.bench.wake_cost import rhs_call

    rhs = rhs_call(1024)

    def run() -> float:
        times = []
        for _ in range(50):
            start = time.perf_counter()
            rhs()
            times.append(time.perf_counter() - start)
        return statistics.median(times)
    return run


def measure(rounds: int = 5) -> dict[str, dict[str, float]]:
    """{workload: {"min_ms": ..., "median_ms": ...}} for :data:`WORKLOADS`, each timed
    ``rounds`` times (wall time), the workloads taking turns."""
    if rounds < 1:
        raise ValueError(f"rounds: at least 1 (got {rounds})")
    a = np.linspace(0.1, 0.8, 8)
    b = np.linspace(1.0, 2.0, 8)
    rhs = _rhs_workload()

    def timed(fn, *args) -> float:
        start = time.perf_counter()
        fn(*args)
        return time.perf_counter() - start

    times: dict[str, list[float]] = {w: [] for w in WORKLOADS}
    for _ in range(rounds):
        times["python"].append(timed(_python))
        times["numpy_small"].append(timed(_numpy_small, a, b))
        times["rhs_1024"].append(rhs())
    return {w: {"min_ms": 1e3 * min(t), "median_ms": 1e3 * statistics.median(t)}
            for w, t in times.items()}


def describe(result: dict[str, dict[str, float]]) -> str:
    """One line: each workload's minimum (median) [ms]."""
    return "yardstick (min / median of the rounds): " + ", ".join(
        f"{w} {v['min_ms']:.3g} / {v['median_ms']:.3g} ms" for w, v in result.items())


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rod_sim.bench.yardstick",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=5, help="times each workload is timed")
    p.add_argument("--json", action="store_true", help="the result as JSON")
    args = p.parse_args(argv)
    if args.rounds < 1:
        p.error(f"--rounds: at least 1 (got {args.rounds})")
    result = measure(args.rounds)
    print(json.dumps(result, indent=1) if args.json else describe(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
