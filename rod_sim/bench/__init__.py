"""Speed against error (docs/bench.md): wall time, work counters and max phi error of each
scene, model and integrator setting, against verified converged references.

``rod-sim bench [--quick] [--json] [--out DIR]``. For each scene the converged reference of
every model (compiled DOP853 at ``BENCH_REFERENCE_RTOL``) is first checked against a run
at ``BENCH_CHECK_RTOL``; a model whose reference fails the check gets no timed rows (its rows
are listed with the failure). Then every setting is timed: the integration alone (``Simulator.run``
sampling at 100 Hz, as the log does), the median of several repeats after a JIT warm-up.
Errors are max |phi - phi_ref| [rad] over rods and samples, against the reference of the same
model (``max_phi_error``) and against the full model's reference (``error_vs_full``; for the
full model both are the same). Runs that fail, diverge or would exceed the per-run wall-time
cap are listed with their status, not dropped.

``--out DIR`` writes ``bench.json``, ``results.md`` (tables), one work-precision plot per scene
(``wp_<scene>.png``, error against wall time, log-log) and the cost-per-rhs scaling plot
(``scaling.png``, n = 8 ... 512, with the fitted exponents).

The package, one job a module:

- :mod:`.config`: what is measured (spans, references, target, scenes, settings grids; the
  row, reference and option types). A new scene is an entry of ``SCENES``.
- :mod:`.runs`: references and timed rows per scene; peers' rows (:func:`peer_rows`).
- :mod:`.micro`: micro-benchmarks (cost per rhs against n, hinge features, the full model's
  stability bound).
- :mod:`.summary`: the run as data (targets met, environment, the JSON).
- :mod:`.report`, :mod:`.plots`: stdout text, results.md and the PNG plots.
- :mod:`.long_chains`: n = 8 ... 4096 beside Pinocchio (:mod:`.pinocchio_peer`), start-up,
  long chains and the stiff tether; :mod:`.mujoco_peer`: MuJoCo's rigid chain.
- :mod:`.command`: ``rod-sim bench`` (options, order of the measurements, output).

The names below are the bench's API (tests, notebooks).
"""
from __future__ import annotations

from .config import (BENCH_CHECK_RTOL, BENCH_REFERENCE_RTOL, HINGE_COST_LIMIT, MODELS,
                     QUICK_SCENES, RADAU_RTOLS, RADAU_RTOLS_QUICK, RATE_HZ, REFERENCE_GAP,
                     SCENE_T_END, SCENES, T_END, TARGET_ERROR, BenchConfig, BenchRow, Reference,
                     describe_setting, load_bench_scene, settings_grid, simulate_args)
from .micro import full_model_bound, hinge_rhs_cost, paper_chain, rhs_cost, scaling
from .report import (TARGET_TABLE, _bound_lines, format_rows, format_targets, markdown,
                     write_report)
from .plots import plots
from .runs import (RunTimeout, bench_scene, measure_setting, mujoco_rows, peer_rows, reference,
                   run_phi, time_run)
from .summary import as_json, best_at, environment, targets

__all__ = ["BENCH_CHECK_RTOL", "BENCH_REFERENCE_RTOL", "HINGE_COST_LIMIT", "MODELS",
           "QUICK_SCENES", "RADAU_RTOLS", "RADAU_RTOLS_QUICK", "RATE_HZ", "REFERENCE_GAP",
           "SCENE_T_END", "SCENES", "T_END", "TARGET_ERROR", "BenchConfig", "BenchRow",
           "Reference", "describe_setting", "load_bench_scene", "settings_grid", "simulate_args",
           "full_model_bound", "hinge_rhs_cost", "paper_chain", "rhs_cost", "scaling",
           "TARGET_TABLE", "_bound_lines", "format_rows", "format_targets", "markdown",
           "write_report", "plots", "RunTimeout", "bench_scene", "measure_setting", "mujoco_rows",
           "peer_rows", "reference", "run_phi", "time_run", "as_json", "best_at", "environment",
           "targets"]
