"""``rod-sim advise SCENE --tolerance X``: the cheapest fidelity and integrator settings that
meet a tolerance on a short trial.

Every candidate (rigid, reduced, full model; dop853-jit at a few tolerances) is run over the
trial [0, T] and compared, at 100 Hz samples, with a full-model reference at rtol 1e-11
(itself checked against rtol 1e-10: if the two differ by more than a tenth of the tolerance
the reference is not converged and the command fails). The error is max over rods and samples
of |phi - phi_ref| [rad] (docs/bench.md); on a free base (SPEC section 8) the base's angle psi
counts as one more angle (|psi - psi_ref|; a prescribed base's angle is exact).

A stiff scene (docs/hard_cases.md) gets the implicit radau-jit too: a candidate whose
dop853-jit run was stiff (Hairer's test, :func:`~rod_sim.app.progress.stiffness_hint`) is run
with radau-jit as well, and the reference is computed with radau-jit when a probe of the full
model's first :data:`~rod_sim.app.progress.STIFF_MIN_STEPS` dop853-jit steps is stiff.

Among the candidates whose error is at most :data:`MARGIN` x tolerance, the cheapest fidelity
wins (rigid, then reduced, then full), and within it the dop853-jit setting with the fewest
right-hand side evaluations (deterministic), unless a radau-jit setting took at most
:data:`RADAU_WALL_SHARE` of its wall time (integrators compare by wall time only, the minimum
of the repeats; the share leaves room for a busy machine's noise). The speed-up is against the
full model at the default settings. Exit 0 with a recommendation, 1 when none meets the
tolerance. The advice holds for the trial's loads and duration only.
"""
from __future__ import annotations

import json
import math
import time
from typing import NamedTuple

import numpy as np

HELP = "recommend the cheapest model and integrator settings that meet a tolerance"
MARGIN = 0.5
"""A candidate must be within MARGIN x tolerance on the trial (room for longer runs)."""
CANDIDATES = (("rigid", 1e-4), ("rigid", 1e-6), ("rigid", 1e-8),
              ("reduced", 1e-4), ("reduced", 1e-6), ("reduced", 1e-8), ("reduced", 1e-10),
              ("full", 1e-6), ("full", 1e-8), ("full", 1e-10))
FIDELITY = ("rigid", "reduced", "full")
DEFAULT_RTOL = 1e-8
ADVISE_REFERENCE_RTOL = 1e-11
"""advise's full-model reference (compiled DOP853) that the candidates are judged against."""
ADVISE_CHECK_RTOL = 1e-10
"""advise's looser check of that reference: it is converged if the two differ by at most a
tenth of the tolerance."""
RATE_HZ = 100.0
RADAU_WALL_SHARE = 0.5
"""A radau-jit candidate beats the fidelity's best dop853-jit one when its wall time is at
most this share of that one's."""


def configure(parser) -> None:
    from rod_sim.app.common import positive_float, positive_int

    parser.add_argument("scene", help="scene YAML file")
    parser.add_argument("--tolerance", type=positive_float, required=True,
                        help="largest acceptable max |phi - phi_full_ref| [rad]")
    parser.add_argument("--t-end", type=positive_float, default=1.0,
                        help="length of the trial [s of simulated time] (default 1)")
    parser.add_argument("--repeats", type=positive_int, default=3,
                        help="timing repeats, 1 .. 1000 (minimum taken; default 3)")
    parser.add_argument("--json", action="store_true", help="machine-readable output")


class Watch:
    """What :func:`advise` is running now, for its progress lines: ``label`` (e.g. "the
    full-model reference (rtol 1e-11)"), its :class:`~rod_sim.core.simulator.Simulator`
    ``sim`` (None between runs) and how many of the ``total`` runs have ended (``done``)."""

    def __init__(self):
        self.label, self.sim, self.done = "setting up", None, 0
        self.total = 2 + len(CANDIDATES)

    def running(self, label: str, sim) -> None:
        self.label, self.sim = label, sim

    def finished(self) -> None:
        """A run ended (or failed)."""
        self.done += 1
        self.label, self.sim = "setting up the next run", None


class Trial(NamedTuple):
    """One run of :func:`_run`: ``angles`` (N, n) or on a free base (N, n + 1), phi and then
    psi [rad]; ``wall`` the best wall time [s]; ``nfev`` right-hand side evaluations;
    ``stiff`` whether dop853-jit found the run stiff (False for radau-jit)."""

    angles: np.ndarray
    wall: float
    nfev: int
    stiff: bool


def _run(scene, model_name: str, rtol: float, t_end: float, repeats: int = 1,
         watch: Watch | None = None, label: str = "",
         integrator: str = "dop853-jit") -> Trial:
    """One model/integrator/tolerance over [0, t_end] (:class:`Trial`); each repeat's
    Simulator is handed to ``watch`` (:meth:`Watch.running`) under ``label``."""
    from ..api import Simulator, make_integrator, make_model
    from ..app.progress import stiffness_hint

    model = make_model(model_name, scene)
    settings = make_integrator(integrator, rtol=rtol)
    Simulator(model, settings).advance(1e-4)                 # compile outside timing
    best, phi, sim = np.inf, None, None
    repeats = max(1, repeats)
    for k in range(repeats):
        sim = Simulator(model, settings)
        if watch is not None:
            watch.running(label + (f", repeat {k + 1} of {repeats}" if repeats > 1 else ""),
                          sim)
        start = time.perf_counter()
        traj = sim.run(t_end, RATE_HZ)
        best = min(best, time.perf_counter() - start)
        phi = traj.phi
        if model.nb:                                 # a free base: its angle psi too
            phi = np.column_stack([phi, traj.y[:, model.base_index + 2]])
    if watch is not None:
        watch.finished()
    return Trial(phi, best, sim.stats.nfev, stiffness_hint(settings, sim.stats) is not None)


def reference_integrator(scene, t_end: float, watch: Watch | None = None) -> str:
    """The integrator of the full-model reference (:mod:`rod_sim.app.stiff_probe` at the
    check's tolerance); ``watch`` is told of the probe (not counted as a run)."""
    from ..api import make_model
    from ..app.stiff_probe import probe_label, reference_integrator as probe

    def running(sim):
        if watch is not None:
            watch.running(probe_label(), sim)

    chosen = probe(make_model("full", scene), ADVISE_CHECK_RTOL, t_end, running=running)
    if watch is not None:
        watch.label, watch.sim = "setting up the next run", None
    return chosen


def advise(scene, tolerance: float, t_end: float = 1.0, repeats: int = 3,
           watch: Watch | None = None) -> dict:
    """The recommendation and every trial as a dict (see the module docstring); ``watch``
    (:class:`Watch`) is told what runs. Raises IntegrationError if the reference cannot be
    computed."""
    ref_integrator = reference_integrator(scene, t_end, watch)
    ref_loose = _run(scene, "full", ADVISE_CHECK_RTOL, t_end, watch=watch,
                     label=f"the full-model reference's check ({ref_integrator} rtol "
                           f"{ADVISE_CHECK_RTOL:g})", integrator=ref_integrator).angles
    ref = _run(scene, "full", ADVISE_REFERENCE_RTOL, t_end, watch=watch,
               label=f"the full-model reference ({ref_integrator} rtol "
                     f"{ADVISE_REFERENCE_RTOL:g})", integrator=ref_integrator).angles
    ref_check = float(np.max(np.abs(ref - ref_loose)))
    trials = []
    for model_name, rtol in CANDIDATES:
        row = _candidate(scene, model_name, "dop853-jit", rtol, t_end, repeats, watch, ref,
                         tolerance)
        trials.append(row)
        if row.get("stiff"):                        # dop853-jit was stiff: radau-jit too
            if watch is not None:
                watch.total += 1
            trials.append(_candidate(scene, model_name, "radau-jit", rtol, t_end, repeats,
                                     watch, ref, tolerance))
    full_default_wall = next(r["wall_s"] for r in trials if r["model"] == "full"
                             and r["rtol"] == DEFAULT_RTOL and r["integrator"] == "dop853-jit")
    best = choose(trials)
    out = {"scene": scene.name, "n": scene.n, "t_end": t_end, "tolerance": tolerance,
           "margin": MARGIN, "reference": {"model": "full", "integrator": ref_integrator,
                                           "rtol": ADVISE_REFERENCE_RTOL,
                                           "self_check_rtol_1e-10": ref_check},
           "reference_converged": ref_check <= 0.1 * tolerance,
           "full_default_wall_s": full_default_wall, "trials": trials, "recommendation": None}
    if best is not None and out["reference_converged"]:
        rec = dict(best)
        rec["speedup_vs_full"] = (full_default_wall / best["wall_s"]
                                  if full_default_wall and best["wall_s"] > 0 else None)
        rec["simulate_args"] = ["--model", best["model"], "--integrator", best["integrator"],
                                "--rtol", f"{best['rtol']:g}"]
        out["recommendation"] = rec
    return out


def _candidate(scene, model_name: str, integrator: str, rtol: float, t_end: float,
               repeats: int, watch: Watch | None, ref: np.ndarray, tolerance: float) -> dict:
    """One candidate's row: model, integrator, rtol, max_phi_error against ``ref`` [rad],
    wall_s, nfev, ok (within :data:`MARGIN` x ``tolerance``), ``stiff`` when dop853-jit found
    the run stiff; ``error`` (and ok False) when the integration failed."""
    from ..core.integrators import IntegrationError

    row = {"model": model_name, "integrator": integrator, "rtol": rtol}
    try:
        trial = _run(scene, model_name, rtol, t_end, repeats, watch,
                     f"candidate {model_name} {integrator} rtol {rtol:.0e}", integrator)
    except IntegrationError as exc:
        if watch is not None:
            watch.finished()
        row.update(error=str(exc), max_phi_error=None, wall_s=None, nfev=None, ok=False)
        return row
    err = float(np.max(np.abs(trial.angles - ref)))
    row.update(max_phi_error=err, wall_s=trial.wall, nfev=trial.nfev,
               ok=err <= MARGIN * tolerance)
    if trial.stiff:
        row["stiff"] = True
    return row


def choose(trials: list[dict]) -> dict | None:
    """The recommended trial among those that met the criterion (``ok``): the cheapest
    fidelity (rigid < reduced < full: fewer or cheaper equations); within it the dop853-jit
    trial with the fewest right-hand side evaluations (deterministic, unlike wall times on a
    busy machine), unless the fastest radau-jit trial took at most :data:`RADAU_WALL_SHARE`
    of its wall time (or no dop853-jit trial met it). None when no trial met it."""
    ok = [r for r in trials if r["ok"]]
    if not ok:
        return None
    fidelity = min(FIDELITY.index(r["model"]) for r in ok)
    same = [r for r in ok if FIDELITY.index(r["model"]) == fidelity]
    explicit = min((r for r in same if r["integrator"] == "dop853-jit"),
                   key=lambda r: r["nfev"], default=None)
    implicit = min((r for r in same if r["integrator"] == "radau-jit"),
                   key=lambda r: r["wall_s"], default=None)
    if explicit is None or (implicit is not None
                            and implicit["wall_s"] <= RADAU_WALL_SHARE * explicit["wall_s"]):
        return implicit
    return explicit


def format_text(res: dict) -> str:
    """The human-readable table: trial, criterion, one row per candidate, recommendation."""
    criterion = res["margin"] * res["tolerance"]
    ref = res["reference"]
    lines = [f"{res['scene']} (n = {res['n']}): trial 0..{res['t_end']:g} s, tolerance "
             f"{res['tolerance']:g} rad on max |phi - phi_ref| (full model, {ref['integrator']} "
             f"rtol 1e-11; reference self-check {ref['self_check_rtol_1e-10']:.2g} rad)",
             f"criterion: max phi error <= {res['margin']:g} x tolerance = {criterion:g} rad "
             "(room for runs longer than the trial)",
             f"{'model':8} {'integrator':10} {'rtol':>7} {'max phi error':>14} {'wall [s]':>10} "
             f"{'nfev':>9}  meets (<= {criterion:g} rad)"]
    for r in res["trials"]:
        head = f"{r['model']:8} {r['integrator']:10} {r['rtol']:7.0e}"
        if r.get("error"):
            lines.append(f"{head}  failed: {r['error']}")
            continue
        lines.append(f"{head} {r['max_phi_error']:14.3g} {r['wall_s']:10.4f} {r['nfev']:9d}  "
                     f"{'yes' if r['ok'] else 'no'}"
                     + ("  (stiff for dop853-jit: radau-jit tried)" if r.get("stiff") else ""))
    rec = res["recommendation"]
    if rec is None:
        why = ("the reference is not converged to a tenth of the tolerance"
               if not res["reference_converged"] else
               f"no candidate is within {res['margin']:g} x the tolerance")
        lines.append(f"no recommendation: {why}")
    else:
        sp = rec["speedup_vs_full"]
        lines.append(f"recommended: {' '.join(rec['simulate_args'])} (error "
                     f"{rec['max_phi_error']:.3g} rad"
                     + (f", {sp:.3g}x faster than the full model at rtol 1e-8)" if sp else ")"))
    return "\n".join(lines)


PROGRESS_FIRST_S = 2.0
"""[s] of wall time before the first progress line (a short advise prints none)."""
PROGRESS_EVERY_S = 10.0
"""[s] of wall time between the next ones."""


def _progress(watch: Watch, t_end: float):
    """The progress lines of an advise (:class:`~rod_sim.app.progress.Progress`): the run
    under way, its simulated time and steps, the runs done, and the wall time left for this
    run at the pace of the last interval."""
    from rod_sim.app.progress import Pace, Progress, left_text, run_state, steps_text

    seen = [None, None]             # the run last described and its Pace

    def line(elapsed: float) -> str:
        sim = watch.sim
        head = f"rod-sim advise: {watch.done} of {watch.total} runs done after {elapsed:.0f} s"
        if sim is None:
            return f"{head}; {watch.label}"
        t, steps, h = run_state(sim)
        if seen[0] is not sim:      # a run first seen now: its pace from the next line on
            seen[:] = sim, Pace(t_end, t, steps)
            left = math.inf
        else:
            left = seen[1].left(t, steps, h)
        return (f"{head}; now {watch.label}: t = {t:.6g} of {t_end:g} s, "
                f"{steps_text(steps, h)} ({left_text(left, 'more for it at this pace')})")

    return Progress(line, PROGRESS_FIRST_S, PROGRESS_EVERY_S, "rod-sim-advise-progress")


def run(args) -> int:
    from rod_sim.app.common import EXIT_CHECK_FAILED, EXIT_OK, UsageError, load_scene

    if args.t_end > 100.0:
        raise UsageError("--t-end: a trial longer than 100 s is not a short trial")
    scene = load_scene(args.scene)
    watch = Watch()
    with _progress(watch, args.t_end):
        res = advise(scene, args.tolerance, args.t_end, args.repeats, watch)
    print(json.dumps(res, indent=1) if args.json else format_text(res))
    return EXIT_OK if res["recommendation"] is not None else EXIT_CHECK_FAILED
