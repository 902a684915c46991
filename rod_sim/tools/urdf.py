"""``rod-sim urdf SCENE [--out FILE] [--frame-id F]``: write the chain of a scene as URDF (the
model the node publishes on ``robot_description``; links, joints and frames in
:mod:`rod_sim.io.urdf`). To stdout by default; ``--out`` must not exist and its directory must.
"""
from __future__ import annotations

import sys

HELP = "write a scene's chain as URDF (what the node publishes on robot_description)"


def configure(parser) -> None:
    parser.add_argument("scene", help="scene YAML file (docs/interface.md section 1)")
    parser.add_argument("--out", default=None, help="URDF file to write (must not exist); "
                        "default: standard output")
    parser.add_argument("--frame-id", default="world",
                        help="name of the root link, the fixed frame (default world, as the "
                             "node's frame_id)")


def run(args) -> int:
    from ..io.urdf import scene_urdf
    from .common import EXIT_OK, UsageError, load_scene, new_output_path

    if not args.frame_id or not args.frame_id.replace("_", "").replace("/", "").isalnum():
        raise UsageError(f"--frame-id: not a frame name: {args.frame_id!r}")
    out = new_output_path(args.out) if args.out else None
    text = scene_urdf(load_scene(args.scene), args.frame_id)
    if out is None:
        sys.stdout.write(text)
    else:
        out.write_text(text, encoding="utf-8")
        print(f"wrote {out}", file=sys.stderr)
    return EXIT_OK
