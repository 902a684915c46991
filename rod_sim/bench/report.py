"""The text of ``rod-sim bench``: the rows and targets printed to stdout, ``results.md`` (tables
of every row, the targets, the references, the scaling and the long chains) and the files of
``--out`` (:func:`write_report`: bench.json, results.md and the plots of :mod:`.plots`).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from .config import HINGE_COST_LIMIT, BenchRow, cell
from .plots import plots


def format_rows(rows) -> str:
    lines = [f"{'scene':14s} {'model':8s} {'integrator':17s} {'setting':12s} {'wall [s]':>10s} "
             f"{'RTF':>9s} {'phi err':>9s} {'vs full':>9s} {'nfev':>8s} {'steps':>7s} "
             f"{'rej':>5s}  status"]
    for r in rows:
        lines.append(f"{r.scene:14s} {r.model:8s} {r.integrator:17s} {r.setting:12s} "
                     f"{r.wall_s:10.4g} {r.rtf:9.4g} {r.max_phi_error:9.3g} "
                     f"{r.error_vs_full:9.3g} {r.nfev:8d} {r.steps:7d} {r.rejected:5d}  "
                     f"{r.status}")
    return "\n".join(lines)


def write_report(out_dir: Path, data: dict) -> list[Path]:
    """results.md, bench.json, wp_<scene>.png, scaling.png into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "bench.json"]
    written[0].write_text(json.dumps(data, indent=1))
    floats = ("wall_s", "rtf", "max_phi_error", "error_vs_full", "model_error", "cpu_s",
              "rtf_cpu", "max_hinge_error")
    rows = [BenchRow(**{k: (math.nan if v is None and k in floats else v)
                        for k, v in r.items()}) for r in data["rows"]]
    md = out_dir / "results.md"
    md.write_text(markdown(rows, data))
    written.append(md)
    written += plots(out_dir, rows, data.get("scaling"))
    return written


TARGET_TABLE = (
    # (label, key of targets(), check in targets()["met"] or None, error field)
    ("paper example, reduced >= 1000x", "paper_example_reduced", "reduced >= 1000x",
     "max_phi_error"),
    ("paper example, reduced >= 1300x (issue 12: no regression)", "paper_example_reduced",
     "reduced >= 1300x", "max_phi_error"),
    ("paper example, full >= 5x", "paper_example_full", "full >= 5x", "max_phi_error"),
    ("paper example, full >= 120x (issue 12, best integrator)", "paper_example_full",
     "full >= 120x", "max_phi_error"),
    ("n = 128, reduced >= 5x", "chain_n128_reduced", "n=128 reduced >= 5x", "max_phi_error"),
    ("deployment 0..10 s, reduced >= 1000x (hinge-angle error)", "deployment_reduced",
     "deployment reduced >= 1000x", "max_hinge_error"),
    ("deployment 0..10 s, full >= 20x (hinge-angle error)", "deployment_full",
     "deployment full >= 20x", "max_hinge_error"),
    ("paper example, rigid (no target)", "paper_example_rigid", None, "max_phi_error"),
    ("paper example, MuJoCo rigid peer (no target)", "paper_example_mujoco_rigid", None,
     "max_phi_error"),
)


def _met(tt, check):
    if check is None:
        return "-"
    if check not in tt["met"]:
        return "not run"
    return "yes" if tt["met"][check] else "**no**"


def _target_lines(t, tw) -> list[str]:
    """Rows of the targets table (CPU figures ``t``, wall figures ``tw``)."""
    lines = []
    for label, key, check, error in TARGET_TABLE:
        b, bw = t.get(key), tw.get(key)
        lines.append(f"| {label} | {cell(b and b['rtf'], '.4g')}x | "
                     f"{b['integrator'] + ' ' + b['setting'] if b else '-'} | "
                     f"{cell(b and b[error], '.2g')} | {_met(t, check)} | "
                     f"{cell(bw and bw['rtf'], '.4g')}x | {_met(tw, check)} |")
    lines.append(f"| reduced/full >= 100x (paper example) | "
                 f"{cell(t['reduced_over_full_speedup'], '.3g')}x | - | - | "
                 f"{_met(t, 'reduced/full >= 100x')} | "
                 f"{cell(tw['reduced_over_full_speedup'], '.3g')}x | "
                 f"{_met(tw, 'reduced/full >= 100x')} |")
    lines.append(f"| our rigid / MuJoCo rigid (no target) | "
                 f"{cell(t['rigid_over_mujoco_speedup'], '.3g')}x | - | - | - | "
                 f"{cell(tw['rigid_over_mujoco_speedup'], '.3g')}x | - |")
    return lines


def _hinge_cost_lines(cost, t) -> list[str]:
    """The per-rhs cost of the deployment scene's hinge features (issue 12)."""
    if not cost:
        return []
    check = f"hinge rhs cost <= {HINGE_COST_LIMIT:g}x plain"
    any_ = next(iter(cost.values()))
    lines = ["", f"Cost per rhs with the deployment scene's hinge features against the same "
                 f"chain without them (compiled rk4 loop over 0..{any_['span_s']:g} s, the two "
                 f"timed alternately {any_['rounds']} times, minimum of each; target <= "
                 f"{HINGE_COST_LIMIT:g}x: {_met(t, check)}):", "",
             "| model | with hinge features [us] | without [us] | ratio |", "|---|---|---|---|"]
    for m, c in cost.items():
        lines.append(f"| {m} | {c['hinge_s'] * 1e6:.3g} | {c['plain_s'] * 1e6:.3g} | "
                     f"{c['ratio']:.2f} |")
    return lines


def _bound_lines(b) -> list[str]:
    """Why the full model's speed is what it is (:func:`full_model_bound`), in words."""
    if not b:
        return []
    d = b["dop853_best"]
    lines = ["", f"### Why the full model is slower: the numbers of this run", "",
             f"- The linearised full model of `{b['scene']}` has max |lambda| = "
             f"{b['max_abs_lambda']:.4g} rad/s (lambda = {b['lambda_real']:.3g} "
             f"{b['lambda_imag']:+.4g}i: a bending vibration, nearly undamped; the largest "
             f"over {b['states_sampled']} states of the run).",
             f"- DOP853 is stable for h |lambda| <= {b['dop853_stability_limit']:.4g} on that "
             f"ray (from its tableau), so h <= {b['h_max_s'] * 1e3:.3g} ms: over "
             f"{b['t_end_s']:g} s at least {b['dop853_min_steps']} steps of "
             f"{b['dop853_stages']} rhs = {b['dop853_min_rhs']} rhs at **any** tolerance.",
             f"- This run's best dop853-jit row ({d['setting']}, phi error "
             f"{d['max_phi_error']:.2g} rad): {d['steps']} steps + {d['rejected']} rejected, "
             f"{d['rhs']} rhs, {d['cpu_per_rhs_s'] * 1e6:.3g} us CPU per rhs, "
             f"{d['rtf']:.3g}x. With no rejected step and the largest stable step it would "
             f"reach at most **{b['dop853_rtf_bound']:.3g}x**; 120x would need "
             f"<= {b['cpu_per_rhs_for_120x_at_min_rhs_s'] * 1e6:.3g} us per rhs at that "
             f"minimum."]
    r = b.get("radau_best")
    if r:
        lines.append(f"- radau-jit (implicit, not bound by stability) is bound by accuracy on "
                     f"the same vibrations: best row {r['setting']} (phi error "
                     f"{r['max_phi_error']:.2g} rad): {r['steps']} steps + {r['rejected']} "
                     f"rejected, {r['rhs']} rhs ({r['rhs_per_step']:.3g} per step, "
                     f"{r['jacobians']} Jacobians), {r['cpu_per_step_s'] * 1e6:.3g} us CPU per "
                     f"step: {r['rtf']:.3g}x. docs/bench.md splits that cost.")
    return lines


def markdown(rows, data) -> str:
    env = data["environment"]
    t = data["targets"]
    spans = "".join(f" ({k}: 0..{v:g} s)" for k, v in (env.get("scene_t_end_s") or {}).items())
    lines = ["# Benchmark results (generated by `rod-sim bench --out docs/bench`)", "",
             f"Generated {env['date_utc']} UTC on {env['cpu']} ({env['cpu_count']} cores, "
             f"load average {', '.join(f'{x:.1f}' for x in env['load_average_1_5_15'] or [])} "
             "at the end of the run: the machine is shared, timings are noisy). "
             f"rod_sim {env['rod_sim']}, Python {env['python']}, numpy {env['numpy']}, scipy "
             f"{env['scipy']}, numba {env['numba']}, mujoco {env['mujoco']}. "
             f"Each run: 0..{env['t_end_s']:g} s{spans}, "
             f"output at {env['sample_rate_hz']:g} Hz, "
             f"{env['timing']}; repeats {env.get('repeats')}, per-run cap {env.get('cap_s')} s. "
             f"Errors: max |phi - phi_ref| over rods and samples [rad] against the same model "
             f"at rtol {env['reference_rtol']:g} (checked against rtol "
             f"{env['reference_check_rtol']:g}: gap <= {env['reference_max_gap_rad']:g} rad); "
             "'hinge err' the same for the hinge angles (phi_1, phi_k+1 - phi_k); "
             "'vs full' against the full model's reference. RTF = simulated s / wall s.", "",
             f"## Targets (max phi error <= {t['max_phi_error']:g} rad, one run)", "",
             "RTF per CPU second of the process (one core; what other processes on the shared "
             "machine take is not counted) and per wall second (counted). The deployment "
             "targets are at max hinge-angle error <= the same bound (issue 12).", "",
             "| target | RTF (CPU) | best setting (CPU) | error [rad] | met (CPU) | RTF (wall) | "
             "met (wall) |", "|---|---|---|---|---|---|---|"]
    lines += _target_lines(t, data.get("targets_wall") or t)
    lines += _hinge_cost_lines(data.get("hinge_rhs_cost"), t)
    lines += _bound_lines(data.get("full_model_bound"))
    refs = data.get("references") or {}
    if refs:
        lines += ["", "## References", "", "| scene | model | gap rtol 1e-11 vs 1e-12 [rad] | "
                  "wall [s] | ok |", "|---|---|---|---|---|"]
        for scene, per in refs.items():
            for m, r in per.items():
                lines.append(f"| {scene} | {m} | {cell(r['gap_rad'], '.2g')} | "
                             f"{cell(r['wall_s'], '.3g')} | {'yes' if r['ok'] else r['message']} |")
    if data.get("long_chains"):
        from .long_chains import markdown_lines

        lines += markdown_lines(data["long_chains"])
    sc = data.get("scaling")
    if sc:
        lines += ["", "## Cost per right-hand side against n", "",
                  "| n | " + " | ".join(f"{m} [us]" for m in sc["per_rhs_s"]) + " |",
                  "|---" * (len(sc["per_rhs_s"]) + 1) + "|"]
        for i, n in enumerate(sc["n"]):
            lines.append(f"| {n} | " + " | ".join(cell(v[i] * 1e6, ".4g")
                                                  for v in sc["per_rhs_s"].values()) + " |")
        lines.append("")
        lines.append("Fitted exponent p (cost ~ n^p, n >= 64): " + ", ".join(
            f"{m} {p:.2f}" for m, p in sc["exponent_n_ge_64"].items()) + ".")
        lines.append("")
        lines.append("![cost per rhs](scaling.png)")
    for scene in dict.fromkeys(r.scene for r in rows):
        sub = [r for r in rows if r.scene == scene]
        lines += ["", f"## {scene} (n = {sub[0].n}, `{sub[0].scene_file}`)", "",
                  f"![work-precision {scene}](wp_{scene}.png)", "",
                  "| model | integrator | setting | wall [s] | RTF | CPU [s] | RTF (CPU) | "
                  "phi err | hinge err | vs full | model err | rhs evals | steps | rejected | "
                  "repeats | status |", "|---" * 16 + "|"]
        for r in sub:
            lines.append(f"| {r.model} | {r.integrator} | {r.setting} | "
                         f"{cell(r.wall_s, '.3g')} | {cell(r.rtf, '.4g')} | "
                         f"{cell(r.cpu_s, '.3g')} | {cell(r.rtf_cpu, '.4g')} | "
                         f"{cell(r.max_phi_error, '.2g')} | {cell(r.max_hinge_error, '.2g')} | "
                         f"{cell(r.error_vs_full, '.2g')} | {cell(r.model_error, '.2g')} | "
                         f"{r.nfev} | {r.steps} | {r.rejected} | {r.repeats} | {r.status} |")
    return "\n".join(lines) + "\n"


def format_targets(cpu: dict) -> str:
    """The speed targets of :func:`targets` as text (``--json`` gives every figure)."""
    lines = [f"speed targets at max |phi error| <= {cpu['max_phi_error']:g} rad "
             "(simulated s per CPU s):"]
    lines += [f"  {name}: {'met' if met else 'NOT met'}" for name, met in cpu["met"].items()]
    for key in ("reduced_over_full_speedup", "rigid_over_mujoco_speedup"):
        if cpu.get(key):
            lines.append(f"  {key.replace('_', ' ')}: {cpu[key]:.0f}x")
    return "\n".join(lines)
