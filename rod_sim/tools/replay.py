"""``rod-sim replay LOG``: republish a log's topics on a live ROS graph, with their timing and
/clock, like ``ros2 bag play`` on machines without rosbag2 (see docs/replay.md).

LOG is an MCAP file (a rod_sim log or any ROS 2 MCAP) or a rosbag2 bag directory with MCAP
storage. Exit 0 at the end of the log or on SIGINT/SIGTERM; 2 with a one-line message for a
missing or unreadable log, an unknown topic or a bad option.
"""
from __future__ import annotations

import argparse
import gc
import sys

from rod_sim.app.common import (EXIT_CHECK_FAILED, EXIT_OK, UsageError, non_negative_float,
                                port_number, positive_float)

HELP = "republish a log's topics on a live ROS graph with their timing and /clock"
DEFAULT_CLOCK_HZ = 100.0


def remap_rule(text: str) -> str:
    """argparse type: a ROS remapping rule FROM:=TO (both sides non-empty)."""
    source, sep, target = text.partition(":=")
    if not (sep and source.strip() and target.strip()):
        raise argparse.ArgumentTypeError(f"not a remapping FROM:=TO: {text!r}")
    return text


def _strict(parser: argparse.ArgumentParser) -> None:
    """Make ``parser`` (a subparser) report unknown arguments itself, with its own usage,
    instead of leaving them to ``rod-sim``'s top-level usage."""
    parse_known = parser.parse_known_args

    def parse_known_args(args=None, namespace=None):
        namespace, extras = parse_known(args, namespace)
        if extras:
            parser.error(f"unrecognized arguments: {' '.join(extras)}")
        return namespace, []

    parser.parse_known_args = parse_known_args


def ros_arguments(args: argparse.Namespace) -> list[str]:
    """The ROS arguments of the player node: ``--remap`` rules, then ``--ros-args ...``."""
    rules = [token for rule in args.remap for token in ("-r", rule)]
    return ["--ros-args", *rules, *args.ros_args] if rules or args.ros_args else []


def configure(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Republish the topics of an MCAP log (or a rosbag2 MCAP bag directory) on the ROS "
        "graph with their recorded timing, QoS and bytes, and publish the log time on /clock "
        "(use_sim_time nodes follow it). Stops at the end of the log (or, with --loop, on "
        "SIGINT/SIGTERM).")
    parser.add_argument("log", metavar="LOG", help="MCAP file or rosbag2 bag directory")
    parser.add_argument("-r", "--rate", type=positive_float, default=1.0,
                        help="log seconds per wall second (default 1; 2 = twice as fast)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC",
                        help="replay only these topics (default: all)")
    parser.add_argument("--exclude-topics", nargs="+", metavar="TOPIC", default=(),
                        help="do not replay these topics")
    parser.add_argument("-l", "--loop", action="store_true",
                        help="start again at the end of the log, until stopped")
    clock = parser.add_mutually_exclusive_group()
    clock.add_argument("--clock", type=positive_float, nargs="?", const=DEFAULT_CLOCK_HZ,
                       default=DEFAULT_CLOCK_HZ, metavar="HZ",
                       help="publish the log time on /clock at HZ wall-clock Hz and at every "
                            f"message (default: on, {DEFAULT_CLOCK_HZ:g} Hz)")
    clock.add_argument("--no-clock", dest="clock", action="store_const", const=0.0,
                       help="do not publish /clock")
    parser.add_argument("--start-offset", type=non_negative_float, default=0.0, metavar="S",
                        help="start S seconds (log time) after the first message")
    parser.add_argument("-d", "--delay", type=non_negative_float, default=0.0, metavar="S",
                        help="wait S wall seconds after creating the publishers")
    parser.add_argument("--wait-for-subscribers", action="store_true",
                        help="before playing, wait until every replayed topic has a "
                             "subscriber")
    parser.add_argument("--start-paused", action="store_true",
                        help="start paused; resume with the ~/pause service (std_srvs/SetBool "
                             "data: false) or ~/toggle_paused (std_srvs/Trigger)")
    parser.add_argument("--live-view", type=port_number, default=0, metavar="PORT",
                        help="also show the replayed markers, joint states and node poses in "
                             "a live view: a Foxglove WebSocket server on 127.0.0.1:PORT "
                             "(foxglove-sdk; connect the Foxglove app or Lichtblick)")
    parser.add_argument("--remap", action="append", type=remap_rule, default=[],
                        metavar="FROM:=TO",
                        help="publish topic FROM (as recorded, e.g. /rod_states) under TO "
                             "(e.g. /arm1/rod_states); repeatable")
    parser.add_argument("--ros-args", nargs=argparse.REMAINDER, default=[], dest="ros_args",
                        metavar="ARG", help="ROS arguments of the player node, up to the end "
                        "(e.g. --ros-args -r __ns:=/arm1 moves its services; recorded "
                        "topics are absolute: move them with --remap)")
    _strict(parser)


def _select(source, args) -> list[str]:
    from ..io.playback import select_topics
    from ..ros.conversions import message_class

    selected = select_topics(source.tracks, args.topics, args.exclude_topics)
    explicit = bool(args.topics)
    kept = []
    for topic in selected:
        track = source.tracks[topic]
        problem = None
        if track.encoding != "cdr":
            problem = f"its encoding is {track.encoding!r}, not cdr"
        else:
            try:
                message_class(track.type_name)
            except ValueError as exc:
                problem = str(exc)
        if problem is None:
            kept.append(topic)
        elif explicit:
            raise UsageError(f"cannot replay {topic}: {problem}")
        else:
            print(f"rod-sim replay: skipping {topic}: {problem}", file=sys.stderr)
    if args.clock and "/clock" in kept:
        kept.remove("/clock")
        print("rod-sim replay: the log's own /clock is not replayed (the player publishes the "
              "log time; pass --no-clock to replay the recorded one)", file=sys.stderr)
    if not kept:
        raise UsageError("no topic left to replay")
    return kept


def run(args: argparse.Namespace) -> int:
    from ..core.units import NS_PER_S
    from ..io.playback import open_source

    with open_source(args.log) as source:
        topics = _select(source, args)
        for topic in topics:
            note = source.tracks[topic].note
            if note:
                print(f"rod-sim replay: {topic}: {note}", file=sys.stderr)
        if not source.complete:
            print(f"rod-sim replay: {args.log} has no summary (its writer was stopped): "
                  "replaying its complete chunks", file=sys.stderr)
        stats = _play(source, topics, args)
    span = ((stats.last_ns - stats.first_ns) / NS_PER_S
            if stats.last_ns is not None and stats.first_ns is not None else 0.0)
    end = "stopped" if stats.stopped else "end of log"
    print(f"rod-sim replay: {end}: {stats.messages} messages on {len(topics)} topics, "
          f"{stats.passes} pass(es), last pass {span:.3f} s of log time in "
          f"{stats.wall_s:.3f} s wall at rate {args.rate:g} (latest publication "
          f"{stats.max_late_s * 1e3:.1f} ms after its time), {stats.clock_messages} /clock "
          "messages", file=sys.stderr)
    if stats.skipped:
        counts = ", ".join(f"{t} {k}" for t, k in sorted(stats.skipped.items()))
        print(f"rod-sim replay: skipped {sum(stats.skipped.values())} corrupt message(s), not "
              f"published ({counts}); the first: {stats.first_skip}", file=sys.stderr)
        return EXIT_CHECK_FAILED
    return EXIT_OK


def _live_view(port: int):
    """The live view on ``port`` (None for 0); UsageError when it cannot start."""
    if not port:
        return None
    from ..io.live_view import LiveView, LiveViewError

    try:
        view = LiveView(port, name="rod-sim replay")
    except LiveViewError as exc:
        raise UsageError(str(exc)) from None
    print(f"rod-sim replay: live view on ws://127.0.0.1:{view.port}", file=sys.stderr)
    return view


def _play(source, topics: list[str], args):
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    from ..ros.executor import LeanExecutor
    from ..ros.process import StopRequest
    from ..ros.replay import PlayStats, Player, wait_for_subscribers

    view = _live_view(args.live_view)
    try:
        rclpy.init(args=["rod-sim replay", *ros_arguments(args)],
                   signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as exc:       # rclpy's RCLInvalidROSArgsError
        raise UsageError(f"invalid ROS arguments: {' '.join(str(exc).split()).split(', at ')[0]}"
                         ) from None
    player = None
    stats = PlayStats(stopped=True)
    with StopRequest() as stop:
        try:
            player = Player(source, topics, rate=args.rate, clock_hz=args.clock,
                            loop=args.loop, start_paused=args.start_paused,
                            start_offset_s=args.start_offset, live_view=view)
            stats = player.stats
            executor = LeanExecutor()
            executor.add_node(player)
            player.get_logger().info(
                f"replaying {len(topics)} topic(s) of {args.log} at rate {args.rate:g}"
                + (f", /clock at {args.clock:g} Hz" if args.clock else ", no /clock")
                + (", looping" if args.loop else "") + (", paused" if args.start_paused else ""))
            ready = not args.wait_for_subscribers or wait_for_subscribers(player, executor, stop)
            if ready and args.delay > 0:
                stop.event.wait(args.delay)          # discovery runs in the background
            if ready and not stop.requested:
                gc.collect()
                gc.freeze()       # full collections of the startup heap stalled playback ~0.1 s
                stats = player.play(executor, stop)
                player.flush()
            else:
                stats.stopped = True
        except (KeyboardInterrupt, ExternalShutdownException):
            stats.stopped = True
        finally:
            if player is not None:
                player.destroy_node()
            if view is not None:
                view.close()
            rclpy.try_shutdown()
    return stats
