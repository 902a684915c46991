"""The summary plot of a sweep: a few outputs against each swept parameter.

One column of panels per swept parameter, one row per output (tip displacement, max |phi|,
max bending slope, rhs evaluations: all reproducible, unlike wall time). Grid sweeps draw lines through
the runs that share every other parameter (and the model): the colour is the model, the line
style and marker the level of the other parameters (in the legend); Monte-Carlo sweeps are
scatter plots. Axes carry the units of the scene keys. Failed runs are marked with a red x on the bottom edge of each panel. matplotlib
(the ``plot`` extra) is used with the Agg backend.
"""
from __future__ import annotations

import math
from pathlib import Path

PLOTTED = (("max_tip_displacement", "max tip displacement [m]"),
           ("max_abs_phi", "max |phi| [rad]"),
           ("max_abs_bending", "max |alpha|, |beta| [rad]"),
           ("nfev", "rhs evaluations"))


# Units of the scene keys a sweep parameter path may end with (docs/interface.md section 1).
UNITS = {"length": "m", "mass_per_length": "kg/m", "bending_stiffness": "N m^2", "mass": "kg",
         "stiffness": "N m/rad", "damping": "N m s/rad", "phi": "rad", "phi_rate": "rad/s",
         "amplitude": "N", "start": "s", "duration": "s", "rest_angle": "rad", "latch": "rad",
         "angle": "rad"}
STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*")


def axis_label(path: str) -> str:
    """``path`` with the unit of its last key, e.g. ``hinges.stiffness [N m/rad]``."""
    last = path.split(".")[-1].split("[")[0]
    return f"{path} [{UNITS[last]}]" if last in UNITS else path


def _level_text(names: list[str], level: tuple) -> str:
    return ", ".join(f"{n} = {v:.4g}" if _number(v) else f"{n} = {v}"
                     for n, v in zip(names, level))


def _level_order(level: tuple) -> tuple:
    return tuple((0, v, "") if _number(v) else (1, 0.0, str(v)) for v in level)


def _value(row: dict, key: str) -> float:
    if key == "max_abs_bending":
        return max(row["max_abs_alpha"], row["max_abs_beta"])
    return row[key]


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def plot_sweep(rows: list[dict], params: list[str], random: set, path: str | Path,
               title: str = "", logx: set = frozenset()) -> None:
    """Write the summary figure of ``rows`` to ``path`` (PNG/SVG/PDF by extension).

    ``params``: swept parameter columns (numeric ones are plotted); ``random``: those drawn
    from a distribution (scatter instead of lines); ``logx``: those plotted on a log axis.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    xs = [p for p in params if all(_number(r[p]) for r in rows)] or ["run"]
    models = sorted({r["model"] for r in rows})
    colors = {m: f"C{i}" for i, m in enumerate(models)}
    fig, axes = plt.subplots(len(PLOTTED), len(xs), figsize=(4.2 * len(xs) + 0.6,
                                                            2.5 * len(PLOTTED) + 0.8),
                             squeeze=False, sharex="col")
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    for j, x in enumerate(xs):
        others = [p for p in params if p != x]
        for i, (key, label) in enumerate(PLOTTED):
            ax = axes[i][j]
            if x in random or x == "run" or any(o in random for o in others):
                for m in models:
                    pts = [(r[x], _value(r, key)) for r in ok if r["model"] == m]
                    if pts:
                        ax.scatter(*zip(*pts), s=14, color=colors[m], alpha=0.8,
                                   label=m if i == 0 else None)
            else:
                groups: dict = {}
                for r in ok:
                    groups.setdefault((r["model"],) + tuple(r[o] for o in others), []).append(r)
                levels = sorted({g[1:] for g in groups}, key=_level_order)
                style = {lv: (STYLES[k % len(STYLES)], MARKERS[k % len(MARKERS)])
                         for k, lv in enumerate(levels)}
                for g, members in groups.items():
                    members.sort(key=lambda r: r[x])
                    ls, mk = style[g[1:]]
                    ax.plot([r[x] for r in members], [_value(r, key) for r in members],
                            ls=ls, marker=mk, ms=3, lw=1, color=colors[g[0]], alpha=0.75)
                if i == 0:
                    for m in models:
                        ax.plot([], [], "-", color=colors[m], label=m)
                    if others and len(levels) > 1:
                        for lv in levels:
                            ls, mk = style[lv]
                            ax.plot([], [], ls=ls, marker=mk, ms=3, color="0.4",
                                    label=_level_text(others, lv))
            if failed:
                ax.plot([r[x] for r in failed], [0.0] * len(failed), "x", color="red",
                        transform=ax.get_xaxis_transform(), clip_on=False,
                        label="failed" if i == 0 else None)
            values = sorted({r[x] for r in rows if _number(r[x])})
            if x in logx and values and min(values) > 0:
                ax.set_xscale("log")
                ax.xaxis.set_minor_formatter(NullFormatter())
            if x not in random and x != "run" and 1 < len(values) <= 8:
                ax.set_xticks(values, [f"{v:.4g}" for v in values])
                ax.minorticks_off()
            if j == 0:
                ax.set_ylabel(label)
            if i == len(PLOTTED) - 1:
                ax.set_xlabel("run" if x == "run" else axis_label(x))
            ax.grid(alpha=0.3)
        axes[0][j].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
