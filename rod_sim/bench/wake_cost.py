"""What a compiled right-hand side costs after the thread waited (this machine's, not the code's).

    python -m rod_sim.bench.wake_cost [--rods 1024] [--wait-ms 8] [--blocks 60] [--calls 20]
                                      [--work rhs|arithmetic|sum] [--kib 8]

A real-time node does its period's work after a wait of most of the period; ``--period-cost``
and the micro-benchmarks time the same work back to back. This measures the difference on the
one piece of pure compiled work of a period: the reduced model's right-hand side of
``--rods`` rods (:func:`rod_sim.bench.long_chains.uniform_chain`, random angles and rates),
wall time per call, in blocks of ``--calls`` calls each preceded by nothing (``back to back``),
by ``--wait-ms`` of busy waiting (``after spinning``) or by ``time.sleep`` of it (``after
sleeping``), the three kinds of block taking turns so that a slow phase of the machine falls
on all three alike. No ROS, no log, no Python between the timer and the kernel but the call.

``--work`` separates what the wait costs: ``arithmetic`` (a compiled chain of 20000
multiply-adds, no memory) pays for a slower or shared core, ``sum`` (a compiled sum of a
``--kib`` KiB array, 5 passes) for data evicted from the core's caches while it waited.
"""
from __future__ import annotations

import argparse
import statistics
import time
from typing import Callable

import numpy as np

WAYS = ("back to back", "after spinning", "after sleeping")
WORKS = ("rhs", "arithmetic", "sum")


def rhs_call(rods: int) -> Callable[[], None]:
    """A call of the reduced model's right-hand side of ``rods`` rods
    (:func:`rod_sim.bench.long_chains.uniform_chain`, random angles and rates, seed 1), its
    compiled code loaded and the caches warm (20 calls made): what each call costs is the
    compiled kernel and its Python entry (also :mod:`rod_sim.bench.yardstick`'s workload)."""
    from rod_sim.bench.long_chains import uniform_chain
    from rod_sim.core.models import make_model

    model = make_model("reduced", uniform_chain(rods))
    data = model.new_data()
    rng = np.random.default_rng(1)
    y = np.concatenate([0.3 * rng.standard_normal(rods), rng.standard_normal(rods)])

    def call() -> None:
        model.rhs(0.0, y, None, None, None, data)

    for _ in range(20):
        call()
    return call


def arithmetic_call() -> Callable[[], None]:
    """A compiled chain of 20000 dependent multiply-adds on one float (no memory traffic)."""
    import numba

    @numba.njit(cache=False)
    def chain(k):
        x = 1.0
        for _ in range(k):
            x = x * 1.0000001 + 1e-9
        return x

    def call() -> None:
        chain(20000)

    for _ in range(20):
        call()
    return call


def sum_call(kib: float) -> Callable[[], None]:
    """A compiled sum, 5 passes, over an array of ``kib`` KiB (float64): what it costs
    beyond back to back is the array's reloading into the core's caches."""
    import numba

    @numba.njit(cache=False)
    def passes(a, k):
        s = 0.0
        for _ in range(k):
            for i in range(a.size):
                s += a[i]
        return s

    a = np.ones(max(1, int(kib * 1024 / 8)))

    def call() -> None:
        passes(a, 5)

    for _ in range(20):
        call()
    return call


def work_call(work: str, rods: int, kib: float) -> Callable[[], None]:
    """The call of ``work`` (:data:`WORKS`), compiled and warm."""
    if work == "arithmetic":
        return arithmetic_call()
    if work == "sum":
        return sum_call(kib)
    return rhs_call(rods)


def work_label(work: str, rods: int, kib: float) -> str:
    """What :func:`work_call` times, in words."""
    if work == "arithmetic":
        return "20000 compiled multiply-adds"
    if work == "sum":
        return f"a compiled sum of {kib:g} KiB, 5 passes"
    return f"right-hand side of {rods} rods"


def measure(rods: int, wait_ms: float, blocks: int, calls: int, work: str = "rhs",
            kib: float = 8.0) -> dict[str, list[float]]:
    """Wall time [us] of each call of ``work`` (:func:`work_call`), per way of waiting before
    it (:data:`WAYS`)."""
    call = work_call(work, rods, kib)
    wait_s = wait_ms / 1e3
    out: dict[str, list[float]] = {way: [] for way in WAYS}
    for block in range(blocks):
        way = WAYS[block % len(WAYS)]
        for _ in range(calls):
            if way == "after spinning":
                end = time.perf_counter() + wait_s
                while time.perf_counter() < end:
                    pass
            elif way == "after sleeping":
                time.sleep(wait_s)
            start = time.perf_counter_ns()
            call()
            out[way].append((time.perf_counter_ns() - start) / 1e3)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rod_sim.bench.wake_cost",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--rods", type=int, default=1024)
    p.add_argument("--wait-ms", type=float, default=8.0, help="[ms] wait before each call")
    p.add_argument("--blocks", type=int, default=60, help="blocks of calls, ways taking turns")
    p.add_argument("--calls", type=int, default=20, help="calls per block")
    p.add_argument("--work", choices=WORKS, default="rhs",
                   help="what is timed: the right-hand side (default), compiled arithmetic "
                        "alone, or a compiled sum over --kib KiB")
    p.add_argument("--kib", type=float, default=8.0, help="[KiB] the array of --work sum")
    args = p.parse_args(argv)
    if args.rods < 1 or args.blocks < 1 or args.calls < 1 or args.wait_ms < 0:
        p.error("--rods, --blocks and --calls must be >= 1, --wait-ms >= 0")
    if not args.kib > 0:
        p.error("--kib must be > 0")
    result = measure(args.rods, args.wait_ms, args.blocks, args.calls, args.work, args.kib)
    label = work_label(args.work, args.rods, args.kib)
    base = statistics.median(result[WAYS[0]])
    for way, times in result.items():
        if not times:
            continue
        median = statistics.median(times)
        print(f"{way}: {label}: median {median:.1f} us, 10th "
              f"percentile {float(np.percentile(times, 10)):.1f} us ({len(times)} calls, "
              f"{median / base:.2f} x back to back; wait {args.wait_ms:g} ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
