"""Run a quiet command and say every few seconds that it is still running.

``python rod_sim/tools/heartbeat.py [--every S] WHAT -- COMMAND [ARGS...]``: the Makefile's
``pip install -q`` prints nothing for a minute or more on a fresh clone; this prints
``make: WHAT (N s so far)`` every ``--every`` seconds (default 8) while COMMAND runs, then exits
with COMMAND's status. Ctrl-C or SIGTERM is passed on to COMMAND, which is killed 1 s later if
it has not ended. Standard library only: it runs before the package is installed.
"""
from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import time


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" not in argv:
        print("heartbeat: usage: heartbeat.py [--every S] WHAT -- COMMAND [ARGS...]",
              file=sys.stderr)
        return 2
    cut = argv.index("--")
    parser = argparse.ArgumentParser(prog="heartbeat.py")
    parser.add_argument("--every", type=float, default=8.0)
    parser.add_argument("what")
    args = parser.parse_args(argv[:cut])
    command = argv[cut + 1:]
    if not command or args.every <= 0:
        parser.error("a command after -- and --every > 0 are needed")
    started = time.monotonic()
    proc = subprocess.Popen(command)
    stop = []

    def forward(signum, frame):
        stop.append(signum)
        if proc.poll() is None:
            proc.send_signal(signum)

    signal.signal(signal.SIGINT, forward)
    signal.signal(signal.SIGTERM, forward)
    next_line = started + args.every
    while proc.poll() is None:
        if stop:                        # passed on: 1 s to end, then killed
            _end_within(proc, 1.0)
            break
        now = time.monotonic()
        if now >= next_line:
            print(f"make: {args.what} ({now - started:.0f} s so far)", flush=True)
            next_line += args.every
        try:
            proc.wait(timeout=min(0.2, max(0.0, next_line - now)))
        except subprocess.TimeoutExpired:
            pass
    if proc.poll() is None:
        proc.kill()
    code = proc.wait()
    if stop:
        return 128 + stop[0]
    return code if code >= 0 else 128 - code


def _end_within(proc, seconds: float) -> None:
    """Wait up to ``seconds`` for the command to end, then kill it."""
    try:
        proc.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        proc.kill()


if __name__ == "__main__":
    sys.exit(main())
