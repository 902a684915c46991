"""``rod-sim compare LOG``: can this logged run be trusted? Checks every logged sample against a
converged re-run of the full model with the logged applied forces (docs/interface.md section 2).

Exit 0: max |phi error| <= --tolerance, no gap in the states, reference converged;
1: any of these fails; 2: the log cannot be compared (one line on stderr, no traceback).
The numbers are computed by :mod:`rod_sim.tools.comparison`; docs/compare.md explains them.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from .common import EXIT_CHECK_FAILED, EXIT_OK, UsageError, positive_float

COMMAND = "compare"
HELP = "check a log against a converged re-run of the full model"


def configure(parser) -> None:
    parser.add_argument("log", help="MCAP log (rod-sim simulate, the node's record_path) or a "
                                    "rosbag2 bag directory with MCAP storage")
    parser.add_argument("--json", action="store_true", help="machine-readable report")
    parser.add_argument("--plot", metavar="PNG", default=None,
                        help="write phi of both models and the error over time to PNG "
                             "(must not exist)")
    parser.add_argument("--tolerance", type=positive_float, default=None,
                        metavar="RAD", help="largest accepted |phi_log - phi_full| [rad] "
                                            "(default 0.01, see docs/compare.md)")
    parser.add_argument("--scene", default=None, metavar="SCENE.yaml",
                        help="scene file, for logs without rod_sim metadata (overrides the "
                             "log's scene when given)")


def _scene_for(log, scene_path: str | None):
    """(scene, where it came from, note or None)."""
    from ..io.scene_yaml import load_scene, scene_from_yaml_text, scene_to_yaml

    logged = None
    if log.metadata is not None and "scene" in log.metadata:
        logged = scene_from_yaml_text(log.metadata["scene"])
    if scene_path is not None:
        scene = load_scene(scene_path)
        note = None
        if logged is not None and scene_to_yaml(logged) != scene_to_yaml(scene):
            note = f"--scene {scene_path} differs from the scene in the log's metadata; using --scene"
        return scene, f"--scene {scene_path}", note
    if logged is None:
        raise UsageError(f"{log.path} has no rod_sim metadata with a scene; pass --scene "
                         "SCENE.yaml")
    return logged, "log metadata", None


def _rate(metadata) -> float | None:
    try:
        rate = float((metadata or {}).get("rate_hz", "nan"))
    except ValueError:
        return None
    return rate if math.isfinite(rate) and rate > 0 else None


def format_report(report, info: dict) -> str:
    """The human-readable report: header, verdict, per-rod table, notes."""
    q = report.quantities
    lines = [f"log: {info['log']} ({info['model']} model, {info['integrator']}, "
             f"source {info['source']})",
             f"scene: {info['scene']} (n = {report.n}, from {info['scene_source']}); "
             f"{report.samples} samples, t = {report.t_start:g}..{report.t_end:g} s"
             + (" [TRUNCATED LOG: readable part only]" if report.truncated else ""),
             f"reference: full model, {report.reference['integrator']} "
             f"({report.reference['segments']} segment(s)); check run "
             f"{report.reference.get('check_integrator', '-')} differs by "
             f"{report.reference['phi_change']:.1e} rad in phi"
             f" -> {'converged' if report.reference['converged'] else 'NOT converged'}",
             f"forces: {report.forces['messages']} /applied_forces messages, "
             f"{report.forces['segments']} held-command segment(s), max |held| "
             f"{report.forces['max_abs_held']:.3g} N", ""]
    cols = [("phi", "rad"), ("phi_rate", "rad/s"), ("node_position", "m"), ("alpha", "rad"),
            ("beta", "rad")]
    head = f"{'rod':>3}  " + "  ".join(f"{name + ' [' + unit + ']':>20}" for name, unit in cols)
    head += f"  {'t of max phi err [s]':>20}"
    lines += ["max |log - full| per rod (node_position: node k, the end of rod k):", head]
    for k in range(1, report.n + 1):
        cells = []
        for name, _ in cols:
            if name in q and k in q[name].labels and q[name].err.size:
                cells.append(f"{max(q[name].err[:, q[name].labels.index(k)]):>20.3e}")
            else:
                cells.append(f"{'-':>20}")
        j = q["phi"].err[:, k - 1].argmax()
        lines.append(f"{k:>3}  " + "  ".join(cells) + f"  {q['phi'].t[j]:>20.6g}")
    cells = [f"{q[name].max:>20.3e}" if name in q else f"{'-':>20}" for name, _ in cols]
    lines.append(f"{'max':>3}  " + "  ".join(cells))
    cells = [f"{q[name].scd:>20.2f}" if name in q else f"{'-':>20}" for name, _ in cols]
    lines.append(f"{'scd':>3}  " + "  ".join(cells)
                 + "   (significant correct digits, see docs/compare.md)")
    for note in report.notes:
        lines.append(f"note: {note}")
    lines.append("")
    rod, t = q["phi"].argmax()
    if report.passed:
        lines.append(f"PASS: max |phi error| {q['phi'].max:.3g} rad (rod {rod}, t = {t:.6g} s) "
                     f"<= tolerance {report.tolerance:g} rad"
                     + (f" -- TRUNCATED LOG: only t = {report.t_start:g}..{report.t_end:g} s "
                        "was checked" if report.truncated else ""))
    else:
        lines.append("FAIL: " + "; ".join(report.reasons()))
    return "\n".join(lines)


def write_plot(report, path: Path, title: str) -> None:
    """phi of the log (solid) and the full model (dashed) per rod, and max_k |phi error| over
    time (log scale) with the tolerance."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for k in range(report.n):
        line, = ax1.plot(report.t, report.phi_log[:, k], lw=1.2, label=f"rod {k + 1}")
        ax1.plot(report.t, report.phi_ref[:, k], "--", lw=1.0, color=line.get_color())
    ax1.set_ylabel("phi [rad]")
    ax1.set_title(f"{title}\nsolid: log, dashed: full model (reference)")
    ax1.legend(fontsize=7, ncol=4)
    err = np.max(report.quantities["phi"].err, axis=1)
    ax2.semilogy(report.t, np.where(err > 0, err, np.nan), label="max over rods |phi error|")
    ax2.axhline(report.tolerance, color="r", ls=":", label=f"tolerance {report.tolerance:g} rad")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("|phi_log - phi_full| [rad]")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def validity_messages(scene, model_name: str, report) -> list[str]:
    """Warnings of the validity monitor (rod_sim.core.validity) that apply to a compared log:
    loads near the first bending mode (reduced logs) and end slopes of the full-model
    reference beyond the small-bending range (where neither model is right)."""
    from ..core.validity import SMALL_BENDING_RAD, frequency_findings

    out = [f.message for f in frequency_findings(scene, model_name)]
    slopes = [report.quantities[k].ref for k in ("alpha", "beta") if k in report.quantities]
    worst = max((float(abs(r).max()) for r in slopes if r.size), default=0.0)
    if worst > SMALL_BENDING_RAD:
        out.append(f"the full model's end slopes reach {worst:.3g} rad (> {SMALL_BENDING_RAD} "
                   "rad): outside the small-bending range of both models")
    return out


def run(args) -> int:
    from ..io.log_source import read_log
    from ..io.mcap_log import LogFormatError
    from .common import new_output_path
    from .comparison import DEFAULT_TOLERANCE, CompareInputError, compare_log

    plot = new_output_path(args.plot, "--plot") if args.plot else None
    try:
        log = read_log(args.log)
    except LogFormatError as exc:
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"{args.log}: {exc.strerror or exc}") from None
    scene, scene_source, note = _scene_for(log, args.scene)
    meta = log.metadata or {}
    info = {"log": str(args.log), "files": [str(f) for f in log.files], "scene": scene.name,
            "scene_source": scene_source, "model": meta.get("model", "unknown"),
            "integrator": meta.get("integrator", "unknown"),
            "source": meta.get("source", "unknown"), "version": meta.get("version", "unknown")}
    try:
        tolerance = DEFAULT_TOLERANCE if args.tolerance is None else args.tolerance
        report = compare_log(log, scene, tolerance, rate_hz=_rate(meta))
    except CompareInputError as exc:
        raise UsageError(str(exc)) from None
    if note:
        report.notes.insert(0, note)
    validity = validity_messages(scene, info["model"], report)
    report.notes.extend(f"validity: {m}" for m in validity)
    report.info = info
    if plot is not None:
        try:
            write_plot(report, plot, f"{info['log']}: {info['model']} model vs full")
        except ImportError:
            print("rod-sim compare: --plot needs matplotlib (pip install 'rod_sim[plot]'); "
                  f"{plot} was not written", file=sys.stderr)
            plot = None
        except OSError as exc:
            raise UsageError(f"--plot: cannot write {plot}: {exc.strerror or exc}") from None
    if args.json:
        out = report.as_json()
        out["plot"] = str(plot) if plot else None
        out["validity"] = validity
        print(json.dumps(out, indent=1))
    else:
        print(format_report(report, info))
        if plot is not None:
            print(f"plot: {plot}")
    sys.stdout.flush()
    return EXIT_OK if report.passed else EXIT_CHECK_FAILED
