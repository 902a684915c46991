"""``rod-sim compare LOG``: can this logged run be trusted? Checks every logged sample against a
converged re-run of the full model with the logged applied forces (docs/interface.md section 2).

Exit 0: PASS (max |phi error| <= --tolerance, no gap in the states, reference converged), or
PASS up to the predictability horizon and INCONCLUSIVE beyond it (chaotic motion: only
statistics are meaningful there); 1: FAIL; 2: the log cannot be compared, e.g. a corrupt log
(one line on stderr naming the byte offset, no traceback, no verdict). The report fits 100
columns. The numbers are computed by :mod:`rod_sim.compare.comparison`; docs/compare.md explains
them.
"""
from __future__ import annotations

import json
import math
import sys
import textwrap
from pathlib import Path

from rod_sim.io.quote import quote

from rod_sim.app.common import EXIT_CHECK_FAILED, EXIT_OK, UsageError, largest, positive_float
from .verdict import Cause, Verdict

HELP = "check a log against a converged re-run of the full model (predictability horizon)"


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
    parser.add_argument("--namespace", default=None, metavar="NS",
                        help="read the topics recorded under namespace NS (e.g. /arm1); "
                             "needed only when the log holds two nodes' topics (by default "
                             "rod_states, applied_forces, ... are found under any namespace)")
    parser.add_argument("--scene", default=None, metavar="SCENE.yaml",
                        help="scene file, for logs without rod_sim metadata (overrides the "
                             "log's scene when given)")


def _scene_for(log, scene_path: str | None):
    """(scene, where it came from, note or None)."""
    from rod_sim.io.log_source import metadata_scene
    from rod_sim.io.log_format import LogFormatError
    from rod_sim.io.scene_yaml import load_scene, scene_to_yaml

    if scene_path is None:
        logged, where = log.scene()
        if logged is None:
            raise UsageError(f"{log.path} has no rod_sim metadata and no /scene topic with a "
                             "scene; pass --scene SCENE.yaml")
        return logged, "log metadata" if where == "the log's metadata" else where, None
    scene = load_scene(scene_path)
    note = None
    try:
        logged = metadata_scene(log.metadata, str(log.path))
    except LogFormatError as exc:
        logged, note = None, f"{exc}; using --scene"
    if logged is not None and scene_to_yaml(logged) != scene_to_yaml(scene):
        note = f"--scene {scene_path} differs from the scene in the log's metadata; using --scene"
    return scene, f"--scene {scene_path}", note


def _rate(metadata) -> float | None:
    try:
        rate = float((metadata or {}).get("rate_hz", "nan"))
    except ValueError:
        return None
    return rate if math.isfinite(rate) and rate > 0 else None


WIDTH = 100
"""Columns the text report fits in."""
COLUMNS = [("phi", "rad"), ("phi_rate", "rad/s"), ("node_position", "m"), ("alpha", "rad"),
           ("beta", "rad")]


def _wrap(text: str, indent: str = "  ") -> list[str]:
    return textwrap.wrap(text, WIDTH, subsequent_indent=indent, break_on_hyphens=False) or [""]


def verdict_line(report) -> str:
    """PASS ..., PASS up to t = X s, then INCONCLUSIVE: chaotic ..., or FAIL: reasons."""
    q = report.quantities["phi"]
    cut = (f" -- TRUNCATED LOG: only t = {report.t_start:g}..{report.t_end:g} s was checked"
           if report.truncated else "")
    judgement = report.judgement
    if judgement.verdict is Verdict.FAIL:
        return "FAIL: " + "; ".join(judgement.sentences())
    if judgement.verdict is Verdict.PASS:
        rod, t = q.argmax()
        return (f"PASS: max |phi error| {q.max:.3g} rad (rod {rod}, t = {t:.6g} s) <= tolerance "
                f"{report.tolerance:g} rad{cut}")
    chaos, beyond = report.chaos, report.chaos["beyond_horizon"]
    rod, t = report.within["where"]
    why = ("an error of the log's size before the onset grows past the tolerance"
           if chaos["horizon_cause"] == "log_precision" else
           "two converged full-model runs separate by more than 1 % of the tolerance")
    kind = "chaotic" if (chaos["lyapunov_exponent"] or 0) > 0 else "perturbations amplified"
    return (f"PASS up to t = {report.horizon:.6g} s (max |phi error| "
            f"{report.within['max_phi_error']:.3g} rad, rod {rod}, t = {t:.6g} s), then "
            f"INCONCLUSIVE: {kind} (predictability horizon: {why}; beyond it max |phi error| "
            f"{q.max:.3g} rad, {beyond['max_deamplified_phi_error']:.3g} rad divided by the "
            f"gain){cut}")


def chaos_lines(report) -> list[str]:
    """The predictability summary: gain, Lyapunov exponent, horizon and beyond-horizon checks."""
    c = report.chaos
    lam = c["lyapunov_exponent"]
    twin = report.reference.get("twin_integrator")
    ref = report.reference["integrator"]
    lines = [f"chaos: a {c['twin_perturbation']:g} rad perturbation of the full model is "
             f"amplified at most {c['gain']:.3g}x over t = {report.t_start:g}..{report.t_end:g} s"
             f" (largest finite-time Lyapunov exponent {lam:.3g} 1/s"
             + (f", Lyapunov time {1 / lam:.3g} s" if lam and lam > 0 else "")
             + (f"; the twin run with {twin}" if twin and twin.split()[0] != ref.split()[0]
                else "") + ")"]
    if report.horizon is None:
        lines.append("predictability horizon: none within the log (judged sample by sample "
                     "to the end)" if c["onset"] is None else
                     f"predictability horizon: beyond the log (onset of growth at t = "
                     f"{c['onset']:.6g} s; the log's error {c['log_precision_before_onset']:.2g}"
                     " rad stays below the tolerance when amplified)")
        return [w for line in lines for w in _wrap(line)]
    b = c["beyond_horizon"]
    lines.append(f"predictability horizon: t = {report.horizon:.6g} s (onset of growth at t = "
                 f"{c['onset']:.6g} s, log error before it {c['log_precision_before_onset']:.2g}"
                 " rad)")
    if b:
        lines.append(f"beyond the horizon (t = {b['t_start']:.6g}..{b['t_end']:.6g} s, "
                     f"{b['samples']} samples): per-rod mean phi differs from the full model's by"
                     f" at most {b['max_mean_difference']:.3g} rad, std by "
                     f"{b['max_std_difference']:.3g} rad; the log leaves the full model's phi "
                     f"range by at most {b['max_outside_reference_range']:.3g} rad")
    return [w for line in lines for w in _wrap(line)]


TABLE_ROWS = 20
"""Rods the text report's table lists at most: a longer chain shows the rods of the largest
phi error (every rod is in the JSON report)."""


PLOT_RODS = 12
"""Rods the plot draws at most (the rods of the largest phi error)."""


def rows_shown(phi_max, n: int, most: int = TABLE_ROWS) -> list[int]:
    """The rods (1-based, ascending) the table (or the plot) shows: all of them up to
    ``most``, else the ``most`` of the largest ``phi_max`` (n,) [rad] (a NaN counts as the
    largest; ties go to the lower rod)."""
    if n <= most:
        return list(range(1, n + 1))
    return [k + 1 for k in largest(phi_max, most)]


def format_report(report, info: dict) -> str:
    """The human-readable report (lines of at most WIDTH columns): header, per-rod table,
    predictability, notes, verdict."""
    q = report.quantities
    ref = report.reference
    head = [f"log: {info['log']} ({info['model']} model, {info['integrator']}, "
            f"source {info['source']})",
            f"scene: {info['scene']} (n = {report.n}, from {info['scene_source']}); "
            f"{report.samples} samples, t = {report.t_start:g}..{report.t_end:g} s"
            + (" [TRUNCATED LOG: readable part only]" if report.truncated else ""),
            f"reference: full model, {ref['integrator']} ({ref['segments']} segment(s)); "
            f"check run {ref.get('check_integrator', '-')} differs by "
            + (f"{ref['phi_change']:.1e}" if ref["phi_change"] is not None else "-")
            + " rad in phi" + (f" ({report.within['phi_change']:.1e} before the horizon)"
                               if report.horizon is not None else "")
            + f" -> {'converged' if ref['converged'] else 'NOT converged'}",
            f"forces: {report.forces['messages']} /applied_forces messages, "
            f"{report.forces['segments']} held-command segment(s), max |held| "
            f"{report.forces['max_abs_held']:.3g} N"
            + (f"; torques: {report.forces['torque_messages']} /applied_torques messages, "
               f"max |T| {report.forces['max_abs_torque']:.3g} N m"
               if report.forces.get("torque_messages") else "")]
    lines = [w for line in head for w in _wrap(line)] + [""]
    shown = rows_shown(q["phi"].col_max, report.n)
    lines += _wrap("max |log - full| per rod (node_position: node k, the end of rod k)"
                   + (":" if len(shown) == report.n else
                      f"; the {len(shown)} rods of the largest phi error of {report.n} "
                      "(--json has every rod):"))
    lines.append(f"{'rod':>3}  " + "".join(f"{name:>14}" for name, _ in COLUMNS)
                 + f"{'t of max':>14}")
    lines.append(f"{'':>3}  " + "".join(f"{'[' + unit + ']':>14}" for _, unit in COLUMNS)
                 + f"{'phi err [s]':>14}")
    for k in shown:
        cells = []
        for name, _ in COLUMNS:
            if name in q and k in q[name].labels:
                cells.append(f"{q[name].col_max[q[name].labels.index(k)]:>14.3e}")
            else:
                cells.append(f"{'-':>14}")
        lines.append(f"{k:>3}  " + "".join(cells) + f"{q['phi'].col_t[k - 1]:>14.6g}")
    lines.append(f"{'max':>3}  " + "".join(f"{q[name].max:>14.3e}" if name in q else f"{'-':>14}"
                                          for name, _ in COLUMNS))
    lines.append(f"{'scd':>3}  " + "".join(f"{q[name].scd:>14.2f}" if name in q else f"{'-':>14}"
                                          for name, _ in COLUMNS))
    lines.append("     (scd: significant correct digits, see docs/compare.md)")
    lines += chaos_lines(report)
    for line in report.spacecraft_lines:
        lines += _wrap(line)
    for note in report.notes:
        lines += _wrap(f"note: {note}")
    lines.append("")
    lines += _wrap(verdict_line(report))
    for step in next_steps(report, info):
        lines += _wrap(f"next: {step}")
    return "\n".join(lines)


def next_steps(report, info: dict) -> list[str]:
    """What to try after a FAIL (empty when the log passed), one suggestion a line; ``info``
    as for :func:`format_report` (``scene_file``: the --scene given, if any)."""
    if report.passed:
        return []
    scene = info.get("scene_file") or "SCENE.yaml"
    steps = []
    reasons = {r.cause: r for r in report.judgement.reasons}
    if Cause.NON_FINITE in reasons:
        steps.append("the logged run diverged: run it again with a tighter rtol or a smaller "
                     "command (the node pauses with the cause on diagnostics)")
    elif Cause.TOLERANCE_EXCEEDED in reasons:
        r = reasons[Cause.TOLERANCE_EXCEEDED]
        if info.get("model") != "full":
            steps.append(f"this {info.get('model')} model is not accurate enough here: run the "
                         f"full model (rod-sim simulate {scene} --model full, or the node with "
                         "-p model:=full)")
            steps.append(f"or ask rod-sim advise {scene} --tolerance {r.limit:g} for "
                         "the cheapest model and integrator that meets this tolerance")
        else:
            steps.append("a full-model log that departs from the full model: check the scene "
                         "(--scene) and the logged forces, or log with a tighter rtol")
        steps.append(f"or use a shorter horizon: the error first exceeds the tolerance at t = "
                     f"{r.first_t:.6g} s (a run ending before that passes at this tolerance), "
                     f"or a looser --tolerance if {r.value:.3g} rad is acceptable")
    if Cause.STATE_GAPS in reasons:
        steps.append("states are missing: record in lockstep (-p sync_mode:=true), where no "
                     "period is dropped, or at a lower rate_hz")
    if Cause.REFERENCE_NOT_CONVERGED in reasons:
        steps.append("the full-model reference did not converge: compare a shorter log")
    return steps


def write_plot(report, path: Path, title: str) -> None:
    """phi of the log (solid) and the full model (dashed) per rod, and max_k |phi error| over
    time (log scale) with the tolerance, the predictability horizon and the chaos envelope
    (the log's error before the onset times the gain). Long logs are decimated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows, n = report.series.rows, report.n
    t, err, gain = rows[:, 0], rows[:, 1], rows[:, -1]
    phi_log, phi_ref = rows[:, 2:2 + n], rows[:, 2 + n:2 + 2 * n]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    shown = rows_shown(report.quantities["phi"].col_max, n, PLOT_RODS)
    for k in shown:
        line, = ax1.plot(t, phi_log[:, k - 1], lw=1.2, label=f"rod {k}")
        ax1.plot(t, phi_ref[:, k - 1], "--", lw=1.0, color=line.get_color())
    ax1.set_ylabel("phi [rad]")
    ax1.set_title(f"{title}\nsolid: log, dashed: full model (reference)"
                  + ("" if len(shown) == n else
                     f"; the {len(shown)} of {n} rods of the largest phi error"))
    ax1.legend(fontsize=7, ncol=4)
    ax2.semilogy(t, np.where(err > 0, err, np.nan), label="max over rods |phi error|")
    ax2.axhline(report.tolerance, color="r", ls=":", label=f"tolerance {report.tolerance:g} rad")
    eps = report.chaos["log_precision_before_onset"]
    if eps:
        ax2.semilogy(t, eps * gain, color="0.5", lw=0.8,
                     label="log error before onset x gain (chaos envelope)")
    for ax in (ax1, ax2):
        if report.horizon is not None:
            ax.axvspan(report.horizon, report.t_end, color="0.9", zorder=0)
    if report.horizon is not None:
        ax2.axvline(report.horizon, color="k", lw=0.8,
                    label=f"predictability horizon t = {report.horizon:.3g} s (grey: "
                          "inconclusive)")
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
    from rod_sim.core.validity import SMALL_BENDING_RAD, frequency_findings

    out = [f.message for f in frequency_findings(scene, model_name)]
    worst = max((report.quantities[k].ref_max for k in ("alpha", "beta")
                 if k in report.quantities), default=0.0)
    if worst > SMALL_BENDING_RAD:
        out.append(f"the full model's end slopes reach {worst:.3g} rad (> {SMALL_BENDING_RAD} "
                   "rad): outside the small-bending range of both models")
    return out


PROGRESS_FIRST_S = 2.0
"""[s] of wall time before the first progress line (a short compare prints none)."""
PROGRESS_EVERY_S = 10.0
"""[s] of wall time between the next ones."""


def _progress(runs, end_s: float | None):
    """The progress lines of a compare: how far the full-model re-runs are (``runs()`` ->
    :class:`~rod_sim.compare.comparison.Reached`; first the stiffness probe's) out of the
    log's ``end_s`` [s] (None: not known, e.g. a truncated log), and the wall time left
    (:class:`~rod_sim.app.progress.Pace`)."""
    from rod_sim.app.progress import Pace, Progress, left_text, run_state, steps_text
    from rod_sim.app.stiff_probe import probe_label
    from .runs import COMPARE_CHECK_RTOL, COMPARE_REFERENCE_RTOL

    pace: Pace | None = None
    of = "of the log" if end_s is None else f"of {end_s:g} s"

    def line(elapsed: float) -> str:
        nonlocal pace
        t, sim, integrator, since, twin = runs()
        _, steps, h = run_state(sim) if sim is not None else (t, 0, 0.0)
        if integrator is None:
            return (f"rod-sim compare: {probe_label()} at t = {t:.6g} s {of} after "
                    f"{elapsed:.0f} s ({steps_text(steps, h)})")
        twin_text = "chaos twin" if twin == integrator else f"chaos twin {twin}"
        which = (f"{integrator}: reference rtol {COMPARE_REFERENCE_RTOL:g}, check "
                 f"{COMPARE_CHECK_RTOL:g}, {twin_text}; the reference at "
                 f"{steps_text(steps, h)}")
        if end_s is None:
            return (f"rod-sim compare: full-model re-runs at t = {t:.6g} s {of} after "
                    f"{elapsed:.0f} s ({which})")
        if pace is None:                            # the re-runs' pace from their start
            pace = Pace(end_s, 0.0, 0, wall=since)
        return (f"rod-sim compare: full-model re-runs at t = {t:.6g} {of} after "
                f"{elapsed:.0f} s ({which}; {left_text(pace.left(t, steps, h))})")

    return Progress(line, PROGRESS_FIRST_S, PROGRESS_EVERY_S, "rod-sim-compare-progress")


def run(args) -> int:
    from rod_sim.io.log_format import LogFormatError
    from rod_sim.io.log_source import read_log
    from rod_sim.app.common import new_output_path
    from rod_sim.app.signals import done
    from .comparison import DEFAULT_TOLERANCE, CompareInputError, compare_log

    plot = new_output_path(args.plot, "--plot") if args.plot else None
    try:
        with read_log(args.log, args.namespace) as log:
            scene, scene_source, note = _scene_for(log, args.scene)
            meta = log.metadata or {}
            info = {"log": str(args.log), "files": [str(f) for f in log.files],
                    "scene": scene.name, "scene_source": scene_source,
                    **{k: quote(meta.get(k, "unknown"), 80, plain=True)
                       for k in ("model", "integrator", "source", "version")}}
            tolerance = DEFAULT_TOLERANCE if args.tolerance is None else args.tolerance
            end_s = log.end_ns / 1e9 if log.metadata and log.end_ns is not None else None
            report = compare_log(log, scene, tolerance, rate_hz=_rate(meta),
                                 progress=lambda reached: _progress(reached, end_s),
                                 plot=plot is not None)
    except LogFormatError as exc:
        raise UsageError(str(exc)) from None
    except CompareInputError as exc:
        raise UsageError(str(exc)) from None
    except MemoryError:
        raise UsageError(f"{args.log}: ran out of memory while comparing (the log is not known "
                         "to be corrupt; see docs/compare.md for the memory used)") from None
    except OSError as exc:
        raise UsageError(f"{args.log}: {exc.strerror or exc}") from None
    if note:
        report.notes.insert(0, note)
    validity = validity_messages(scene, info["model"], report)
    report.notes.extend(f"validity: {m}" for m in validity)
    report.info = info
    if plot is not None:
        try:
            write_plot(report, plot, f"{info['log']}: {info['model']} model vs full")
            done(plot)
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
        out["next_steps"] = next_steps(report, {**info, "scene_file": args.scene})
        print(json.dumps(out, indent=1))
    else:
        print(format_report(report, {**info, "scene_file": args.scene}))
        if plot is not None:
            print(f"plot: {plot}")
    sys.stdout.flush()
    return EXIT_OK if report.passed else EXIT_CHECK_FAILED
