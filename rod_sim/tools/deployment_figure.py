"""Snapshots of a chain from a log: ``python -m rod_sim.tools.deployment_figure LOG PNG``.

Draws the chords of the rods (node positions from the logged rod angles and the scene's rod
lengths) at several simulated times, and marks the latch events of ``/hinge_events``
(docs/hinges.md). Also ``rod-sim deployment-figure LOG PNG``.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from ..core.quote import quote
from .common import UsageError, new_output_path

HELP = "draw snapshots of a logged chain (e.g. the deployment scene) with its latch events"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", help="log written by rod-sim simulate or the node (an MCAP "
                        "file or a rosbag2 bag directory, e.g. a rosbags-convert copy)")
    parser.add_argument("png", help="picture to write (must not exist)")
    parser.add_argument("--times", type=finite_time, nargs="+", default=None,
                        help="snapshot times [s] (default: 8 evenly spaced up to the last "
                             "latch, and the end)")


def finite_time(text: str) -> float:
    """argparse type: a finite time [s] >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {quote(text)}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite time >= 0 s (got {text})")
    return value


def _log_scene(path: str):
    """(the log's scene, where it came from) as compare finds it: the rod_sim metadata, else
    the latched /scene topic (a rosbag2-converted copy); UsageError when there is neither."""
    from ..io.log_source import read_log

    with read_log(path) as log:
        scene, where = log.scene()       # bounded: YAML bombs refused
    if scene is None:
        raise UsageError(f"{path}: the log holds no scene (no rod_sim metadata and no /scene "
                         "topic)")
    return scene, where


def run(args) -> int:
    from ..io.hinge_events import read_hinge_events
    from ..io.series import read_rod_states

    png = new_output_path(args.png, "png")
    scene, where = _log_scene(args.log)
    t, phi, _ = read_rod_states(args.log)
    if phi.shape[1] != scene.n:
        raise UsageError(f"{args.log}: /rod_states has {phi.shape[1]} rods but the scene in "
                         f"{where} has {scene.n}")
    try:
        import matplotlib
    except ImportError:
        raise UsageError("the picture needs matplotlib: pip install 'rod_sim[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..core.kinematics import node_positions
    events = read_hinge_events(args.log)
    latches = [e for e in events if e["event"] == "latch"]
    if args.times:
        times = args.times
    else:
        t_last = max([e["t"] for e in latches], default=t[-1])
        times = list(np.linspace(0.0, t_last, 8)) + [float(t[-1])]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 8), gridspec_kw={"height_ratios": [3, 1.4]})
    cmap = plt.get_cmap("viridis")
    for j, ts in enumerate(times):
        i = int(np.argmin(np.abs(t - ts)))
        xy = node_positions(np.asarray(scene.length), phi[i])
        ax.plot(xy[:, 0], xy[:, 1], "-o", ms=3, color=cmap(j / max(len(times) - 1, 1)),
                label=f"t = {t[i]:.2f} s")
    ax.plot([0], [0], "ks", ms=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{scene.name}: chain at several times ({len(latches)} latch events)")
    ax.legend(fontsize=7, loc="best")
    theta = np.diff(phi, prepend=0.0, axis=1)
    for h in range(scene.n):
        ax2.plot(t, theta[:, h], label=f"hinge {h}")
    for e in latches:
        ax2.axvline(e["t"], color="k", lw=0.6, ls=":")
        ax2.annotate(f"latch {e['hinge']}", (e["t"], 0.0), rotation=90, fontsize=7,
                     xytext=(2, 5), textcoords="offset points")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("hinge angle [rad]")
    ax2.legend(fontsize=7, ncol=scene.n)
    fig.tight_layout()
    try:
        fig.savefig(png, dpi=110)
    except OSError as err:
        raise UsageError(f"png: cannot write {png}: {err.strerror or err}") from None
    print(f"{png}: {len(times)} snapshots, {len(latches)} latch events")
    return 0


def main(argv=None) -> int:
    """The same as ``rod-sim deployment-figure ...`` (one-line errors, exit statuses)."""
    from .cli import main as cli_main

    return cli_main([COMMAND, *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
