"""``rod-sim ctl``: the node's services, parameters and topics without the ``ros2`` CLI (the
PyPI wheels have none). ``rod-sim ctl [--ns NS] [--node NAME] [--timeout S] ACTION ...``:

- ``pause`` | ``resume`` | ``step`` | ``reset``: call ``~/pause`` (true / false), ``~/step``,
  ``~/reset`` and print the answer (exit 1 when the node refuses, e.g. ``step`` while running);
- ``param NAME [VALUE]``: print a parameter, or set it (VALUE as ``ros2 param set`` reads it:
  ``1.0`` double, ``1`` integer, ``true`` bool, else a string; an integer for a double
  parameter is sent as a double); exit 1 when the node refuses, with its reason;
- ``echo TOPIC [--count N]``: print messages as YAML documents;
- ``hz TOPIC [--duration S]``: print the rate every second.

Topic names are relative to ``--ns`` as the node's are. Exit 1 when the node or a publisher is
not found within ``--timeout`` (the message names the node, namespace and ROS_DOMAIN_ID).
"""
from __future__ import annotations

import argparse
import sys

from rod_sim.app.common import EXIT_CHECK_FAILED, UsageError, positive_float

HELP = "call the node's services, get/set its parameters, echo or time a topic (no ros2 CLI)"
ACTIONS = ("pause", "resume", "step", "reset", "param", "echo", "hz")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = __doc__.replace("``", "")
    parser.add_argument("--ns", default="/", help="namespace of the node (e.g. /arm1; "
                        "default /): services and relative topics are looked up under it")
    parser.add_argument("--node", default="rod_sim", help="node name (default rod_sim)")
    parser.add_argument("--timeout", type=positive_float, default=10.0,
                        help="[s] to wait for the node or a publisher (default 10)")
    parser.add_argument("action", choices=ACTIONS, help="what to do")
    parser.add_argument("args", nargs="*", help="param: NAME [VALUE]; echo, hz: TOPIC")
    parser.add_argument("--count", type=int, default=0,
                        help="echo: stop after this many messages (default: until Ctrl-C)")
    parser.add_argument("--duration", type=positive_float, default=None,
                        help="hz: stop after this many seconds (default: until Ctrl-C)")


def _expect(args, low: int, high: int, usage: str) -> None:
    if not low <= len(args.args) <= high:
        raise UsageError(f"{args.action}: expected {usage} (got {' '.join(args.args) or 'nothing'})")


def run(args) -> int:
    from ..ros.ctl_client import CtlClient, CtlError, CtlNameError, check_names

    if args.action in ("pause", "resume", "step", "reset"):
        _expect(args, 0, 0, "no further arguments")
    elif args.action == "param":
        _expect(args, 1, 2, "NAME [VALUE]")
    else:
        _expect(args, 1, 1, "TOPIC")
    if args.count < 0:
        raise UsageError("--count: must be >= 0")
    try:
        check_names(args.ns, args.node, args.args[0] if args.action in ("echo", "hz") else None)
    except CtlNameError as exc:
        raise UsageError(str(exc)) from None
    try:
        with CtlClient(args.ns, args.node, args.timeout) as ctl:
            if args.action == "param" and len(args.args) == 1:
                value = ctl.get_parameter(args.args[0])
                if value is None:
                    raise CtlError(f"{ctl.target} has no parameter {args.args[0]!r}")
                print(f"{args.args[0]}: {value!r}")
                return 0
            if args.action == "param":
                return ctl.set_parameter(*args.args)
            if args.action == "echo":
                return ctl.echo(args.args[0], args.count)
            if args.action == "hz":
                return ctl.hz(args.args[0], duration=args.duration or 0.0)
            return ctl.service(args.action)
    except CtlError as exc:
        print(f"rod-sim ctl: {exc}", file=sys.stderr)
        return EXIT_CHECK_FAILED
