"""``rod-sim bench [--quick] [--json] [--out DIR]``: the command line of the bench (options,
the order of the measurements, the output); see :mod:`rod_sim.bench`."""
from __future__ import annotations

import json
import os
from pathlib import Path

from rod_sim.core.names import INTEGRATOR_NAMES
from rod_sim.app.common import EXIT_CHECK_FAILED, EXIT_OK, UsageError
from .config import MODELS, QUICK_SCENES, SCENES, BenchConfig
from .micro import full_model_bound, hinge_rhs_cost, scaling
from .report import format_rows, format_targets, write_report
from .runs import bench_scene
from .summary import as_json

HELP = "speed against error of every model and integrator (docs/bench.md)"


def configure(parser) -> None:
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument("--quick", action="store_true",
                        help="the paper's example (n = 8) only, fewer settings (< 2 min)")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (median)")
    parser.add_argument("--cap", type=float, default=None,
                        help="per-run wall-time cap [s] (default 10 quick, 45 otherwise)")
    parser.add_argument("--scene", action="append", choices=sorted(SCENES), default=None,
                        help="bench only this scene (repeatable)")
    parser.add_argument("--model", action="append", choices=MODELS, default=None,
                        help="time only this model (repeatable; references of the others "
                             "are skipped too)")
    parser.add_argument("--integrator", action="append", choices=INTEGRATOR_NAMES,
                        default=None, help="time only this integrator (repeatable)")
    parser.add_argument("--no-mujoco", action="store_true", help="skip the MuJoCo peer")
    parser.add_argument("--no-scaling", action="store_true",
                        help="skip the cost-per-rhs scaling (n = 8 ... 512)")
    parser.add_argument("--no-long", action="store_true",
                        help="skip the long chains (n = 8 ... 4096 beside Pinocchio, start-up, "
                             "chain n = 256/1024, stiff tether n = 512; ~10 min)")
    parser.add_argument("--spacecraft", action="store_true",
                        help="only the spacecraft bench (free vs fixed base rhs, two-wing "
                             "deployment RTF, radau-jit O(n) on a free base, Basilisk peer; "
                             "~10 min; rod_sim.bench.spacecraft)")
    parser.add_argument("--out", default=None,
                        help="directory for bench.json, results.md and the PNG plots")


def run(args) -> int:
    import sys

    if args.repeats < 1:
        raise UsageError(f"--repeats: must be >= 1 (got {args.repeats})")
    out_dir = Path(args.out) if args.out else None
    if out_dir is not None and out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"--out: {out_dir} is not a directory")
    if args.spacecraft:
        from . import spacecraft

        res = spacecraft.run_all(log=lambda s: print(s, file=sys.stderr, flush=True))
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
            (out_dir / "spacecraft.json").write_text(json.dumps(res, indent=1, default=float))
        print(json.dumps(res, indent=1, default=float) if args.json
              else spacecraft.format_text(res))
        return EXIT_OK
    scenes = tuple(args.scene) if args.scene else (QUICK_SCENES if args.quick else tuple(SCENES))
    cap = args.cap if args.cap is not None else (10.0 if args.quick else 45.0)
    cfg = BenchConfig(quick=args.quick, repeats=args.repeats, cap_s=cap, scenes=scenes,
                      models=tuple(args.model) if args.model else MODELS,
                      integrators=tuple(args.integrator or ()),
                      mujoco=not args.no_mujoco,
                      log=lambda s: print(s, file=sys.stderr, flush=True))
    rows, refs = [], {}
    cfg.extra["load_average_at_start"] = (list(os.getloadavg()) if hasattr(os, "getloadavg")
                                          else None)
    for key in scenes:
        r, summary = bench_scene(key, cfg)
        rows += r
        refs[key] = summary
    scale = None
    if out_dir is not None and not args.no_scaling and not args.quick:
        scale = scaling(log=cfg.log)
    long = None
    if out_dir is not None and not args.no_long and not args.quick:
        from . import long_chains

        long = long_chains.run_all(log=cfg.log)
    hinge_cost = bound = None
    if "deployment" in scenes:
        hinge_cost = hinge_rhs_cost(cfg.models)
        for m, c in hinge_cost.items():
            cfg.log(f"deployment: {m} rhs {c['hinge_s'] * 1e6:.3g} us with hinge features, "
                    f"{c['plain_s'] * 1e6:.3g} us without: ratio {c['ratio']:.2f}")
    if "paper_example" in scenes and "full" in cfg.models:
        bound = full_model_bound(rows)
        if bound:
            cfg.log(f"paper_example: full model |lambda|max {bound['max_abs_lambda']:.4g} rad/s, "
                    f"dop853-jit needs >= {bound['dop853_min_rhs']} rhs: RTF <= "
                    f"{bound['dop853_rtf_bound']:.3g}")
    data = as_json(rows, refs, cfg, scale, hinge_cost, bound)
    data["long_chains"] = long
    if out_dir is not None:
        for path in write_report(out_dir, data):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        print(json.dumps(data, indent=1))
    else:
        print(format_rows(rows))
        print(format_targets(data["targets"]))
    bad_refs = [f"{s}/{m}" for s, per in refs.items() for m, r in per.items() if not r["ok"]]
    if bad_refs:
        print(f"rod-sim bench: reference check failed for {', '.join(bad_refs)}", file=sys.stderr)
        return EXIT_CHECK_FAILED
    return EXIT_OK
