"""Flake hunt: run the tests that meet ROS graphs, signals and wall time (pytest markers ``ros``
and ``timing``) N times beside one CPU-burning process per core, and print each test's failure
rate. ``make flake`` runs it (``make flake N=5``); it is not part of ``make test``.

    python test/flake_hunt.py [--repeats N] [--marker EXPR] [--burners K] [--out DIR] [-- ARGS]

Each repeat is a separate ``pytest -m EXPR`` process (so each takes other ROS domain ids, see
test/ros_domains.py), with a JUnit XML report in DIR (default out/flake); ARGS go to pytest
(e.g. ``-k clock``). The burners are plain busy loops at normal priority, as another user's
build would be, killed at the end (also on Ctrl-C). Exit status 0 when no selected test failed
in any repeat, 1 otherwise (2: bad arguments, or a repeat that ran no test; 130: interrupted).
A repeat whose pytest crashed (killed by a signal) counts as a failure of ``CRASH in FILE:LINE
in FUNCTION`` (faulthandler's innermost test frame) and the hunt goes on."""
from __future__ import annotations

import argparse
import os
import shlex
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_MARKER = "ros or timing"


def burners(count: int) -> list[subprocess.Popen]:
    """``count`` busy-loop processes (one core each)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(count)]


def stop(procs: list[subprocess.Popen]) -> None:
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=10)


def run_pytest(args: list[str], log: Path) -> int:
    """``pytest ARGS`` in the repository, output to ``log``; on Ctrl-C or SIGTERM it gets
    SIGINT (its fixtures stop the processes it started) and 60 s before it is killed."""
    with open(log, "w") as out:
        proc = subprocess.Popen([sys.executable, "-m", "pytest", *args], cwd=REPO, stdout=out,
                                stderr=subprocess.STDOUT)
        try:
            return proc.wait()
        except KeyboardInterrupt:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            raise


def terminated(signum, frame):
    raise KeyboardInterrupt


def outcomes(report: Path) -> dict[str, tuple[str, str]]:
    """test id -> (outcome, first line of the failure message) from one JUnit XML report;
    outcome is passed, failed (a failure or an error) or skipped."""
    found = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        module = case.get("classname", "").replace(".", "/")
        test_id = f"{module}.py::{case.get('name')}"
        outcome, message = "passed", ""
        for child in case:
            if child.tag in ("failure", "error"):
                outcome = "failed"
                message = (child.get("message") or child.text or "").strip().splitlines()[:1]
                message = message[0] if message else child.tag
                break
            if child.tag == "skipped":
                outcome = "skipped"
        found[test_id] = (outcome, message)
    return found


def crash_site(log: Path) -> str:
    """Where a crashed pytest was, from faulthandler's dump in ``log``: the innermost test
    file frame of the crashing thread (``test_x.py:51 in client_in``), else 'unknown'."""
    import re

    text = log.read_text(errors="replace")
    current = text[text.find("Current thread"):] if "Current thread" in text else text
    frame = re.search(r'File "[^"]*/(test_\w+\.py)", line (\d+) in (\w+)', current)
    return f"{frame.group(1)}:{frame.group(2)} in {frame.group(3)}" if frame else "unknown"


def table(results: dict[str, list[tuple[str, str]]]) -> str:
    """One row per test: runs (not skipped), failures, failure rate; worst first."""
    rows = []
    for test_id, runs in results.items():
        ran = [r for r in runs if r[0] != "skipped"]
        failed = [r for r in ran if r[0] == "failed"]
        rows.append((len(failed) / len(ran) if ran else 0.0, len(failed), len(ran), test_id))
    rows.sort(key=lambda r: (-r[0], r[3]))
    width = max([len(r[3]) for r in rows] + [4])
    lines = [f"{'test':<{width}}  runs  failed   rate"]
    lines += [f"{test_id:<{width}}  {ran:4d}  {failed:6d}  {rate:5.0%}"
              for rate, failed, ran, test_id in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", "-n", type=int, default=20, help="pytest runs (default 20)")
    parser.add_argument("--marker", "-m", default=DEFAULT_MARKER,
                        help=f"pytest marker expression (default {DEFAULT_MARKER!r})")
    parser.add_argument("--burners", type=int, default=os.cpu_count() or 1,
                        help="busy-loop processes beside the tests (default: one per core)")
    parser.add_argument("--out", type=Path, default=REPO / "out" / "flake",
                        help="directory of the JUnit reports (default out/flake)")
    parser.add_argument("pytest_args", nargs="*", help="more pytest arguments (after --)")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.burners < 0:
        parser.error("--repeats must be >= 1 and --burners >= 0")
    args.out.mkdir(parents=True, exist_ok=True)
    results: dict[str, list[tuple[str, str]]] = defaultdict(list)
    print(f"flake hunt: {args.repeats} x pytest -m {shlex.quote(args.marker)} "
          f"{shlex.join(args.pytest_args)}"
          f" beside {args.burners} busy process(es); load {os.getloadavg()[0]:.1f}", flush=True)
    started = time.monotonic()
    interrupted = False
    signal.signal(signal.SIGTERM, terminated)
    busy = burners(args.burners)
    try:
        for k in range(args.repeats):
            report = args.out / f"run_{k + 1:03d}.xml"
            report.unlink(missing_ok=True)
            t0 = time.monotonic()
            log = args.out / f"run_{k + 1:03d}.log"
            code = run_pytest(["-m", args.marker, "-q", "-p", "no:cacheprovider",
                               f"--junitxml={report}", *args.pytest_args], log)
            found = outcomes(report) if report.exists() else {}
            if not found and code < 0:
                # pytest itself crashed (a segfault in a middleware's teardown was seen): a
                # failure of the test it was in, and the hunt goes on
                found = {f"CRASH in {crash_site(log)}": ("failed", f"pytest killed by signal "
                                                          f"{-code}; see {log}")}
            if not found:
                print(f"run {k + 1}: no test ran (pytest exit {code}); see {log}", flush=True)
                return 2
            for test_id, outcome in found.items():
                results[test_id].append(outcome)
            failed = sorted(t for t, (o, _) in found.items() if o == "failed")
            print(f"run {k + 1}/{args.repeats}: {len(found)} tests, {len(failed)} failed, "
                  f"{time.monotonic() - t0:.0f} s, load {os.getloadavg()[0]:.1f}"
                  + "".join(f"\n  FAILED {t}: {found[t][1][:160]}" for t in failed), flush=True)
    except KeyboardInterrupt:
        interrupted = True
        print("flake hunt: interrupted; the figures so far:", flush=True)
    finally:
        stop(busy)
    print(f"\n{table(results)}\n\n{sum(len(r) for r in results.values())} test runs in "
          f"{time.monotonic() - started:.0f} s; load {os.getloadavg()[0]:.1f} at the end")
    if interrupted:
        return 130
    return 1 if any(o == "failed" for runs in results.values() for o, _ in runs) else 0


if __name__ == "__main__":
    sys.exit(main())
