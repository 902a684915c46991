"""Snapshots of a chain from a log: ``python -m rod_sim.tools.deployment_figure LOG PNG``.

Draws the chords of the rods (node positions from the logged rod angles and the scene's rod
lengths) at several simulated times, and marks the latch events of ``/hinge_events``
(docs/hinges.md). On a spacecraft scene every chain hangs on the base, drawn as a box at its
centre of mass turned by psi (from ``/base_odometry`` on a moving base), and a third panel shows
the bus turning, psi(t). Also ``rod-sim deployment-figure LOG PNG``.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from ..core.quote import quote
from rod_sim.app.common import UsageError, largest, new_output_path
from rod_sim.app.signals import done

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
    from ..io.log_reader import passes_reused

    with passes_reused():               # the log is opened four times: checked once
        return _draw(args)


def _draw(args) -> int:
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
        # a time is drawn at its nearest sample: one past the log's ends by more than a
        # sample's spacing is not in the log
        spacing = float(np.max(np.diff(t))) if t.size > 1 else 0.0
        outside = [x for x in times if x > t[-1] + spacing or x < t[0] - spacing]
        if outside:
            raise UsageError(f"--times: {outside[0]:g} s is outside the log "
                             f"(t = {t[0]:g}..{t[-1]:g} s)")
    else:
        t_last = max([e["t"] for e in latches], default=t[-1])
        times = list(np.linspace(0.0, t_last, 8))
        if float(t[-1]) > t_last:       # the end, when it is not the last of those already
            times.append(float(t[-1]))
    base = _base_series(args.log, scene, t) if scene.is_spacecraft else None
    if base is None:
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 8),
                                      gridspec_kw={"height_ratios": [3, 1.4]})
    else:
        fig, (ax, ax2, ax3) = plt.subplots(3, 1, figsize=(8, 10),
                                           gridspec_kw={"height_ratios": [3, 1.4, 1.0]})
    cmap = plt.get_cmap("viridis")
    for j, ts in enumerate(times):
        i = int(np.argmin(np.abs(t - ts)))
        color = cmap(j / max(len(times) - 1, 1))
        if base is None:
            xy = node_positions(np.asarray(scene.length), phi[i])
            ax.plot(xy[:, 0], xy[:, 1], _chain_style(scene.n), ms=3, color=color,
                    label=f"t = {t[i]:.2f} s")
        else:
            _draw_spacecraft(ax, scene, phi[i], base[i], color, f"t = {t[i]:.2f} s")
    if base is None:
        ax.plot([0], [0], "ks", ms=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{scene.name}: chain at several times ({len(latches)} latch events)")
    ax.legend(fontsize=7, loc="best")
    if base is None:
        theta = np.diff(phi, prepend=0.0, axis=1)
        labels = [f"hinge {h}" for h in range(scene.n)]
    else:
        from rod_sim.compare.spacecraft import hinge_angles

        theta = hinge_angles(np.asarray(scene.chain_root), phi, base[:, 2])
        labels = [f"{c.name or 'chain'} {h}" for c in scene.chains for h in range(c.count)]
    shown = hinges_shown(theta)
    if len(shown) < scene.n:            # the others as the band they span, unlabelled
        ax2.fill_between(t, theta.min(axis=1), theta.max(axis=1), color="0.85", lw=0,
                         label=f"all {scene.n} hinges (min .. max)")
    for h in shown:
        ax2.plot(t, theta[:, h], label=labels[h])
    for e in latches:
        ax2.axvline(e["t"], color="k", lw=0.6, ls=":")
        ax2.annotate(f"latch {e['hinge']}", (e["t"], 0.0), rotation=90, fontsize=7,
                     xytext=(2, 5), textcoords="offset points")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("hinge angle [rad]")
    ax2.legend(fontsize=7, ncol=min(len(shown) + (len(shown) < scene.n), 5),
               title=None if len(shown) == scene.n else
               f"the {len(shown)} hinges of the largest range", title_fontsize=7)
    if base is not None:
        ax3.plot(t, base[:, 2], "k-")
        ax3.set_xlabel("t [s]")
        ax3.set_ylabel("base angle psi [rad]")
        ax3.set_title(f"the bus turns: psi from {base[0, 2]:.4g} to {base[-1, 2]:.4g} rad")
    fig.tight_layout()
    try:
        fig.savefig(png, dpi=110)
    except OSError as err:
        raise UsageError(f"png: cannot write {png}: {err.strerror or err}") from None
    done(png)
    print(f"{png}: {len(times)} snapshots, {len(latches)} latch events")
    return 0


HINGES_SHOWN = 10
"""Hinge angles drawn one by one (with a legend entry) at most; a longer chain's others are
drawn as the band from the smallest to the largest hinge angle at each time."""
NODE_MARKERS_UP_TO = 50
"""Rods per chain up to which the snapshots mark every node."""


def hinges_shown(theta: np.ndarray) -> list[int]:
    """The hinges (0-based, ascending) drawn one by one from the angles ``theta`` (N, n)
    [rad]: all of them up to :data:`HINGES_SHOWN`, else those of the largest range
    (max - min over the log; ties go to the lower hinge)."""
    return largest(np.ptp(theta, axis=0), HINGES_SHOWN)


def _chain_style(rods: int) -> str:
    """Line style of a snapshot: the nodes marked on a chain of at most
    :data:`NODE_MARKERS_UP_TO` rods (a longer one's markers hide its shape)."""
    return "-o" if rods <= NODE_MARKERS_UP_TO else "-"


def _base_series(log: str, scene, t: np.ndarray) -> np.ndarray:
    """(N, 3) the base's x, y [m], psi [rad] at the rod_states times ``t`` [s]: from
    ``/base_odometry`` on a moving base (psi unwrapped), the scene's constant pose otherwise."""
    b = scene.base
    if not scene.moving_base:
        return np.tile([b.x, b.y, b.psi], (t.size, 1))
    from ..io.series import read_base_odometry

    tb, base = read_base_odometry(log)
    return np.column_stack([np.interp(t, tb, base[:, k]) for k in range(3)])


def _draw_spacecraft(ax, scene, phi: np.ndarray, base: np.ndarray, color, label: str) -> None:
    """Every chain's chords and the base's box (side :func:`~rod_sim.io.encoders.base_box`,
    at its centre of mass, turned by psi) at one instant."""
    from ..core.kinematics import chain_node_positions
    from ..io.encoders import base_box

    x, y, psi = (float(v) for v in base)
    seg = scene.chain_starts
    attach = np.array([c.attach for c in scene.chains], dtype=float).reshape(-1, 2)
    nodes = chain_node_positions(np.asarray(scene.length, float), phi, seg, attach, x, y, psi)
    for c in range(len(scene.chains)):
        a, b = int(seg[c]) + c, int(seg[c + 1]) + c + 1
        ax.plot(nodes[a:b, 0], nodes[a:b, 1], _chain_style(scene.chains[c].count), ms=3,
                color=color, label=label if c == 0 else None)
    half = 0.5 * base_box(scene)
    rot = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]]) * half \
        + np.asarray(scene.base.centre_of_mass, float)
    box = corners @ rot.T + np.array([x, y])
    ax.plot(box[:, 0], box[:, 1], "-", color=color, lw=1.5)


def main(argv=None) -> int:
    """The same as ``rod-sim deployment-figure ...`` (one-line errors, exit statuses)."""
    from .cli import main as cli_main

    return cli_main([COMMAND, *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
