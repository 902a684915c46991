"""Measure ``rod-sim replay`` timing: replay LOG's /rod_states in a subprocess, receive it with
an rclpy subscriber here and print, per run, the arrival lag against log offset / rate
(median-centred |lag|: median, 95th percentile, max [ms]) and the wall span.

    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST python test/replay_timing.py LOG --rate 1 \
        --runs 3 [--domain ID]

Not a test (timings are noisy on a shared machine); docs/replay.md quotes its output.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import test_replay as T  # noqa: E402
from ros_domains import next_domain  # noqa: E402


class _Env:
    def setenv(self, key, value):
        os.environ[key] = value


def one_run(log: Path, rate: float, domain: int, workdir: Path) -> str:
    lis = T.Listener(domain, _Env(), [("/rod_states", T.ALL_TOPICS["/rod_states"])])
    try:
        proc = T.Replay(workdir, domain, log, "--rate", rate, "--topics", "/rod_states",
                        "--wait-for-subscribers", "--delay", "0.5")
        expected = T.recorded(log, "/rod_states")
        lis.spin_until(lambda: len(lis.received["/rod_states"]) >= len(expected), 300, "all",
                       proc.proc)
        proc.wait(timeout=60)
        received = lis.received["/rod_states"]
        lag = T.arrival_offsets(received, expected, rate) * 1e3
        lag = np.abs(lag - np.median(lag))
        arrive = np.array([a for a, _ in received]) / T.NS
        same = [d for _, d in received] == [d for _, d in expected]
        summary = proc.stderr.strip().splitlines()[-1]
        late = summary[summary.index("(latest"):summary.index(")", summary.index("(latest")) + 1]
        return (f"n={len(lag)} |lag| median {np.median(lag):.2f} ms, p95 "
                f"{np.percentile(lag, 95):.2f} ms, max {lag.max():.2f} ms; wall span "
                f"{arrive[-1] - arrive[0]:.3f} s (log span / rate "
                f"{(expected[-1][0] - expected[0][0]) / T.NS / rate:.3f} s); same bytes: {same}; "
                f"player {late}")
    finally:
        lis.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--rate", type=float, default=1.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--domain", type=int, default=None,
                        help="ROS domain id (default: one from test/ros_domains.py)")
    args = parser.parse_args()
    if args.domain is None:
        args.domain = next_domain()
    workdir = Path(os.environ.get("TMPDIR", "/tmp"))
    for k in range(args.runs):
        print(f"run {k + 1}: {one_run(args.log.resolve(), args.rate, args.domain, workdir)}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
