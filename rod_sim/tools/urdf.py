"""``rod-sim urdf SCENE [--out FILE] [--frame-id F]``: write the chain of a scene as URDF (the
model the node publishes on ``robot_description``; links, joints and frames in
:mod:`rod_sim.io.urdf`). To stdout by default; ``--out`` must not exist and its directory must.
"""
from __future__ import annotations

import contextlib
import sys

HELP = "write a scene's chain as URDF (what the node publishes on robot_description)"


def configure(parser) -> None:
    parser.add_argument("scene", help="scene YAML file (docs/interface.md section 1)")
    parser.add_argument("--out", default=None, help="URDF file to write (must not exist); "
                        "default: standard output")
    parser.add_argument("--frame-id", default="world",
                        help="name of the root link, the fixed frame (default world, as the "
                             "node's frame_id)")


PROGRESS_AFTER_S = 2.0
"""[s] after which a long write (n = 1e6: ~20 s, 0.9 GB) says how far it is, every 5 s."""


def run(args) -> int:
    import time

    from ..io.urdf import urdf_chunks
    from rod_sim.app.common import EXIT_OK, UsageError, load_scene, new_output_path
    from rod_sim.app.signals import done

    if not args.frame_id or not args.frame_id.replace("_", "").replace("/", "").isalnum():
        raise UsageError(f"--frame-id: not a frame name: {args.frame_id!r}")
    out = new_output_path(args.out) if args.out else None
    scene = load_scene(args.scene)
    started = next_note = time.monotonic() + PROGRESS_AFTER_S
    started -= PROGRESS_AFTER_S
    # written as it is made, 1000 rods at a time: memory bounded whatever the chain's length
    with (open(out, "x", encoding="utf-8") if out else contextlib.nullcontext(sys.stdout)) as f:
        for k, chunk in enumerate(urdf_chunks(scene, args.frame_id, ROD_CHUNK)):
            f.write(chunk)
            if time.monotonic() > next_note:
                rods = min(scene.n, (k + 1) * ROD_CHUNK)
                print(f"rod-sim urdf: {rods} of {scene.n} rods written "
                      f"({time.monotonic() - started:.0f} s)", file=sys.stderr, flush=True)
                next_note = time.monotonic() + 5.0
    if out is not None:
        done(out)
        print(f"wrote {out}", file=sys.stderr)
    return EXIT_OK


ROD_CHUNK = 1000
