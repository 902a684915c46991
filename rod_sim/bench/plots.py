"""The plots of ``rod-sim bench --out``: one work-precision plot per scene (``wp_<scene>.png``,
max phi error [rad] against CPU time [s], log-log) and the cost per rhs against n
(``scaling.png``). matplotlib is imported when they are drawn.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .config import SCENE_T_END, T_END, TARGET_ERROR


def plots(out_dir: Path, rows, scaling_data) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    markers = {"reduced": "o", "full": "s", "rigid": "^"}
    colors = plt.get_cmap("tab20").colors[::2] + plt.get_cmap("tab20").colors[1::2]
    integrators = list(dict.fromkeys(r.integrator for r in rows))
    for scene in dict.fromkeys(r.scene for r in rows):
        fig, ax = plt.subplots(figsize=(8, 6))
        sub = [r for r in rows if r.scene == scene and r.status == "ok"
               and r.max_phi_error > 0 and np.isfinite(r.cpu_s)]
        for key in dict.fromkeys((r.model, r.integrator) for r in sub):
            pts = sorted((r.cpu_s, r.max_phi_error) for r in sub if (r.model, r.integrator) == key)
            ax.loglog(*zip(*pts), marker=markers.get(key[0], "x"),
                      ls={"reduced": "-", "full": "--", "rigid": ":"}.get(key[0], "-"),
                      color=colors[integrators.index(key[1]) % len(colors)],
                      label=f"{key[0]} {key[1]}", ms=4, lw=1)
        ax.axhline(TARGET_ERROR, color="k", lw=0.6, ls=":")
        span = SCENE_T_END.get(scene, T_END)
        ax.axvline(span, color="r", lw=0.6, ls=":")
        ax.text(span, ax.get_ylim()[0], " real time", color="r", fontsize=7, va="bottom")
        ax.set_xlabel(f"CPU time [s] for {span:g} s simulated (median; one core)")
        ax.set_ylabel("max |phi - phi_ref| [rad] (same model)")
        n_rods = next(r.n for r in rows if r.scene == scene)
        ax.set_title(f"work-precision: {scene} (n = {n_rods})")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=6, ncol=2, title="color: integrator; line: - reduced, -- full, "
                                                  ": rigid", title_fontsize=6)
        path = out_dir / f"wp_{scene}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    if scaling_data:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        ns = np.array(scaling_data["n"])
        for m, costs in scaling_data["per_rhs_s"].items():
            p = scaling_data["exponent_n_ge_64"].get(m, math.nan)
            ax.loglog(ns, np.array(costs) * 1e6, marker=markers.get(m, "x"),
                      label=f"{m} (fit n>=64: n^{p:.2f})")
        ax.set_xlabel("n (rods)")
        ax.set_ylabel("wall time per right-hand side [us]")
        ax.set_title("cost per rhs (compiled, one core); per DOP853 step x12")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=8)
        path = out_dir / "scaling.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    return written
