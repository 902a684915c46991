"""``rod-sim node --ros-args ...``: the rod_sim ROS 2 node (docs/interface.md section 3), run by
:func:`rod_sim.ros.node.main` with its own parser (``rod-sim --help`` lists it; ``rclpy`` is
imported only when it runs)."""
from __future__ import annotations

import argparse

HELP = "the ROS 2 simulator node (docs/interface.md section 3)"
DESCRIPTION = ("Run the rod_sim ROS 2 node until SIGINT/SIGTERM. ROS arguments follow "
               "--ros-args, e.g. --ros-args -p scene_file:=config/paper_example.yaml -p "
               "sync_mode:=true (see `python -m rod_sim.ros.node --help`).")
PROG = "rod-sim node"


def configure(parser) -> None:
    parser.add_argument("ros_args", nargs=argparse.REMAINDER, metavar="--ros-args ...",
                        help="ROS 2 arguments (parameters, remappings, --params-file)")


def forward(ros_args: list[str]) -> int:
    """Run the node with ``ros_args`` (everything after ``rod-sim node``); its exit status."""
    from ..ros.node import main as node_main

    return node_main(list(ros_args), prog=PROG)


def run(args) -> int:
    # reached only through cli.run(); cli.main() forwards the raw arguments (argparse cannot
    # hand "--ros-args ..." through a subparser untouched)
    return forward(args.ros_args)
