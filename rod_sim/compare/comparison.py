"""The numbers behind ``rod-sim compare``: a logged run against a converged full-model re-run.

Pure computation (numpy + rod_sim.core) on the stream of :mod:`rod_sim.io.log_source`; the
report is printed by :mod:`rod_sim.compare.command`. A small pipeline, one part a module: the
logged inputs and sample times (:mod:`.inputs`), the reference runs
(:mod:`.runs`), the chaos tracker (:mod:`.chaos`), the per-quantity statistics
(:mod:`.stats`) and the verdict as data (:mod:`.verdict`); :class:`_Comparison`
feeds them window by window and :class:`Report` holds what they found.

Streaming. The log is compared in windows of at most :data:`WINDOW_SAMPLES` states or
:data:`WINDOW_S` of log time: the full-model runs are continued from window to window and
only running statistics (maxima and where they occur, significant-digit frontiers, a decimated
series for the plot) are kept, so memory does not grow with the log's length.

Chaos. A twin full-model run, started with phi perturbed by :data:`TWIN_DELTA` and
renormalised (Benettin), measures how much the dynamics amplify a small perturbation up to
each time: the gain G(t) (running maximum, >= 1) and the largest finite-time Lyapunov exponent
ln(G)/t. Once perturbations have grown :data:`ONSET_GAIN`-fold (chaos onset), the log's error
so far, eps (its precision while the dynamics did not amplify), is followed forward: the
**predictability horizon** is the first time eps * G(t) exceeds the tolerance (an error the
log already had is then expected to exceed the tolerance), or the first time the two reference
runs (rtol 1e-10 and 1e-12) separate by more than :data:`CONVERGED_FRACTION` of the tolerance.
Before the horizon the log is judged sample by sample; beyond it only what stays meaningful is
compared (the error divided by the gain, per-rod bounds and statistics) and the verdict is
INCONCLUSIVE, unless the log is non-finite or its error grows faster than the gain explains.
A run whose perturbations never grow ``ONSET_GAIN``-fold has no horizon (a plain verdict).

Applied-force history. A ``/applied_forces`` message at t_i holds the forces acting from t_i
on: the scene's scripted loads (continuous functions of t, re-evaluated by the model) plus the
held command, a zero-order hold. So the held part on [t_i, t_{i+1}) is
``held_i = applied(t_i) - scripted(t_i)``; the re-run applies the scripted loads continuously
and ``held_i`` piecewise constant, restarting the integrator wherever ``held`` changes. This
covers ``rod-sim simulate`` logs (a message at every sample, held = 0) and node logs (a message
at the start of every control period). Hinge torques: an ``/applied_torques`` message at t_i
holds the motor moments T (n,) [N m] from t_i on (the node records one per period; a log
without the topic had none); they join the held input as its third column, held (n, 3) =
[X, Y, T], and a change of either starts a new segment. A log with the topic must cover the
states with it as for the forces (from t = 0, no gaps).

Units: angles [rad], rates [rad/s], positions [m], forces [N], times [s] (integer ns where
named ``*_ns``).
"""
from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from rod_sim.core.integrators import IntegrationError
from rod_sim.core.kinematics import node_positions
from rod_sim.core.scene import Scene
from rod_sim.core.units import NS_PER_S

from .chaos import CONVERGED_FRACTION, ChaosTracker, twin_start
from .chaos import ONSET_GAIN, TWIN_DELTA  # noqa: F401  (documented constants)
from .inputs import CompareInputError, HeldInputs, SampleTimeline
from .spacecraft import SpacecraftCheck
from .runs import (COMPARE_CHECK_RTOL, COMPARE_REFERENCE_RTOL, References,
                   reference_model)
from .stats import (QUANTITIES, BeyondHorizon, Decimated, QuantityStats,
                    WithinHorizon)
from .verdict import Judgement, judge

if TYPE_CHECKING:
    from rod_sim.io.log_source import LogStream

DEFAULT_TOLERANCE = 1e-2
"""[rad] default limit on max |phi_log - phi_full| (see docs/compare.md for why)."""
WINDOW_SAMPLES = 2000
"""Largest number of /rod_states samples compared in one window."""
PROBE_SPAN_S = 3600.0
"""[s] the stiffness probe's span when the log's end is not known (it stops after its steps)."""
WINDOW_S = 1.0
"""[s] longest log time of one window (also the twin run's renormalisation interval)."""
PLOT_POINTS = 4000
"""Samples kept for the plot (decimated evenly, the error panel keeps each bucket's maximum),
at most; fewer for a long chain (:data:`PLOT_BYTES`)."""
PLOT_BYTES = 64 << 20
"""[bytes] the plot's series may take at most (phi of the log and of the reference, every
rod, at up to 2 x the points kept, and half of that again while it is thinned out): a long
chain keeps fewer points (at least :data:`PLOT_POINTS_MIN`)."""
PLOT_POINTS_MIN = 250
"""Samples the plot keeps at least, however long the chain."""


def plot_points(n: int) -> int:
    """Samples the plot keeps for a chain of ``n`` rods (:data:`PLOT_POINTS`, fewer within
    :data:`PLOT_BYTES`)."""
    return max(PLOT_POINTS_MIN, min(PLOT_POINTS, PLOT_BYTES // (3 * 8 * (3 + 2 * n))))


@dataclass
class Report:
    """The comparison's result; :meth:`as_json` is the ``--json`` output (docs/compare.md).

    ``horizon``: the predictability horizon [s] (None: the run has none, the whole log is
    judged sample by sample); ``chaos``: gain, Lyapunov exponent, onset, the log's precision
    before the onset, what set the horizon, and beyond-horizon comparisons. ``series``:
    decimated (t, max |phi error|, phi_log (n,), phi_ref (n,), gain) rows for the plot.
    ``judgement``: the verdict and its reasons as data; the JSON ``verdict``, ``pass`` and
    ``reasons`` and the text report's verdict line are formatted from it."""

    n: int
    tolerance: float
    samples: int
    t_start: float
    t_end: float
    quantities: dict[str, QuantityStats]
    reference: dict[str, Any]
    forces: dict[str, Any]
    gaps: list[tuple[float, float]]
    gap_count: int
    truncated: bool
    horizon: float | None
    chaos: dict[str, Any]
    within: dict[str, Any]
    series: Decimated
    judgement: Judgement
    info: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    spacecraft: dict[str, Any] | None = None
    """A spacecraft scene's per-chain and base errors (:mod:`.spacecraft`), else None."""
    spacecraft_lines: list[str] = field(default_factory=list)

    @property
    def within_tolerance(self) -> bool:
        e = self.quantities["phi"].max
        return bool(math.isfinite(e) and e <= self.tolerance)

    def first_exceeded(self) -> float | None:
        """The first sample time [s] at which some rod's |phi error| exceeds the tolerance
        (None if none does): before it, the log agrees with the full model."""
        return self.within["first_exceeded"]

    def reasons(self) -> list[str]:
        """Why the verdict is not a pass (empty for a pass, also for PASS then INCONCLUSIVE):
        the sentences of :attr:`judgement`'s reasons."""
        return self.judgement.sentences()

    @property
    def passed(self) -> bool:
        return self.judgement.passed

    @property
    def verdict(self) -> str:
        """'PASS', 'PASS_THEN_INCONCLUSIVE' (pass up to the horizon, chaotic beyond) or 'FAIL'
        (the value of :attr:`judgement`'s :class:`Verdict`)."""
        return self.judgement.verdict.value

    def as_json(self) -> dict[str, Any]:
        def num(x):
            return None if x is None or not math.isfinite(x) else float(x)

        def where(q):
            label, t = self.quantities[q].argmax()
            return {"node" if q == "node_position" else "rod": label, "t": t}

        present = [q for q in QUANTITIES if q in self.quantities and self.quantities[q].count]
        per_rod = []
        for k in range(1, self.n + 1):
            row: dict[str, Any] = {"rod": k}
            for q in present:
                qs = self.quantities[q]
                if k in qs.labels:
                    j = qs.labels.index(k)
                    row[q] = num(float(qs.col_max[j]))
                    row[q + "_t"] = float(qs.col_t[j])
            per_rod.append(row)
        return {
            **self.info,
            "n": self.n,
            "samples_compared": self.samples,
            "t_start": self.t_start,
            "t_end": self.t_end,
            "tolerance": self.tolerance,
            "tolerance_applies_to": "phi",
            "pass": self.passed,
            "verdict": self.judgement.verdict.value,
            "within_tolerance": self.within_tolerance,
            "reasons": self.reasons(),
            "tolerance_first_exceeded_at": self.first_exceeded(),
            "horizon": num(self.horizon),
            "max_abs_error_within_horizon": {"phi": num(self.within["max_phi_error"])},
            "chaos": self.chaos,
            "max_abs_error": {q: (num(self.quantities[q].max) if q in present else None)
                              for q in QUANTITIES},
            "where": {q: (where(q) if q in present else None) for q in QUANTITIES},
            "significant_digits": {q: (num(self.quantities[q].scd) if q in present else None)
                                   for q in QUANTITIES},
            "per_rod": per_rod,
            "reference": self.reference,
            "forces": self.forces,
            "gaps": {"rod_states": [list(g) for g in self.gaps], "count": self.gap_count},
            "truncated": self.truncated,
            "notes": list(self.notes),
            "spacecraft": self.spacecraft,
        }


class Reached(NamedTuple):
    """How far a compare's full-model re-runs are: ``t`` the simulated time [s] all of them
    have reached, ``sim`` the reference's :class:`~rod_sim.core.simulator.Simulator`,
    ``integrator`` its integrator's name (None while the stiffness probe runs: ``t`` and
    ``sim`` are then the probe's, or 0 and None before it), ``since`` the
    ``time.perf_counter()`` reading at which the re-runs started, ``twin`` the chaos twin's
    integrator's name."""

    t: float
    sim: Any
    integrator: str | None
    since: float
    twin: str | None = None


class _Comparison:
    """Window-by-window state of :func:`compare_log` (see the module docstring): the buffered
    messages of the current window and the parts of the pipeline they are fed to."""

    def __init__(self, log: "LogStream", scene: Scene, tolerance: float, rtol: float,
                 check_rtol: float | None, rate_hz: float | None, keep: bool,
                 plot: bool = True):
        self.log, self.scene, self.tol = log, scene, tolerance
        self.n = n = scene.n
        self.model = reference_model(scene)
        self.rtol, self.check_rtol = rtol, check_rtol
        self.probe = None           # the stiffness probe's Simulator while it runs
        self.refs: References | None = None      # the re-runs, from start()
        self.chaos: ChaosTracker | None = None
        self.started = 0.0          # time.perf_counter() when the re-runs started
        self.inputs = HeldInputs(
            log, n, self.model.forces,
            (lambda t: scene.scripted_load_table(t)[n:n + 2])
            if scene.base.mode == "free" else None)
        self.timeline = SampleTimeline(rate_hz)
        rods = list(range(1, n + 1))
        self.spacecraft = SpacecraftCheck(scene, self.model, tolerance) \
            if scene.is_spacecraft else None
        rows = n + 1 if self.spacecraft is None else n + len(scene.chains) + 1
        self.q = {"phi": QuantityStats("phi", rods, keep),
                  "phi_rate": QuantityStats("phi_rate", rods, keep),
                  "node_position": QuantityStats("node_position", list(range(rows)), keep),
                  "alpha": QuantityStats("alpha", rods, keep),
                  "beta": QuantityStats("beta", rods, keep)}
        self.within = WithinHorizon()
        self.beyond = BeyondHorizon(n)
        self.series = Decimated(plot_points(n) if plot else PLOT_POINTS, angles=plot)
        # messages of the window being filled: (t_ns, values...)
        self.states: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.bending: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.nodes: list[tuple[int, np.ndarray]] = []
        self.bases: list[tuple[int, np.ndarray]] = []

    def start(self, integrator: str | None = None) -> None:
        """Make the full-model re-runs with ``integrator``; None: the stiffness probe's choice
        (:func:`rod_sim.app.stiff_probe.reference_integrator` at the reference's tolerance,
        over the log's span when known), dop853-jit unless the scene is stiff for it. The
        reference and its check take the probe's choice from the scene's initial state; when
        that is radau-jit, the chaos twin is probed from its own start (its perturbation
        excites the fastest modes, which then limit an implicit method's steps as much)."""
        y0 = self.model.initial_state()
        twin_integrator = integrator
        if integrator is None:
            from rod_sim.app.stiff_probe import PROBED, reference_integrator

            end = self.log.end_ns / NS_PER_S if self.log.end_ns else PROBE_SPAN_S

            def chosen_from(start):
                return reference_integrator(self.model, self.rtol, end, self.rtol * 1e-2,
                                            running=self._probing, y0=start)

            integrator = chosen_from(y0)
            twin_integrator = (PROBED if integrator == PROBED
                               else chosen_from(twin_start(self.model, y0)))
            self.probe = None
        self.refs = References(self.model, self.rtol, self.check_rtol, y0, integrator)
        self.chaos = ChaosTracker(self.model, self.rtol, y0, twin_integrator)
        self.started = time.perf_counter()

    def _probing(self, sim) -> None:
        self.probe = sim

    def reached(self) -> "Reached":
        """How far the full-model re-runs (reference, check, twin) are (:class:`Reached`):
        what is left to compare starts there. While the stiffness probe runs (before the
        re-runs exist): its time and Simulator, integrator None."""
        probe, refs = self.probe, self.refs
        if refs is None or probe is not None:
            return Reached(0.0 if probe is None else probe.t, probe, None, 0.0)
        runs = [refs.ref, refs.check, self.chaos.twin]
        return Reached(min(r.sim.t for r in runs if r is not None), refs.ref.sim,
                       refs.ref.integ.name, self.started, self.chaos.twin.integ.name)

    # ----- input -----

    def add(self, g) -> None:
        if g.state is not None:
            if self.log.n != self.n:
                raise CompareInputError(f"the log has {self.log.n} rods but the scene "
                                        f"{self.scene.name!r} has {self.n}: wrong scene")
            self.states.append((g.t_ns, *g.state))
        if g.bending is not None:
            self.bending.append((g.t_ns, *g.bending))
        if g.nodes is not None:
            self.nodes.append((g.t_ns, g.nodes))
        if g.base is not None:
            self.bases.append((g.t_ns, g.base))
        if g.applied is not None:
            self.inputs.applied.append((g.t_ns, g.applied))
        if g.torques is not None:
            self.inputs.torque_msgs.append((g.t_ns, g.torques))
        if g.applied_base is not None:
            self.inputs.base_msgs.append((g.t_ns, g.applied_base))
        if g.state is not None and self.states and (
                len(self.states) >= WINDOW_SAMPLES
                or g.t_ns - self.states[0][0] >= WINDOW_S * NS_PER_S):
            self.window(g.t_ns)

    def finish(self) -> None:
        if self.states:
            self.window(self.states[-1][0])
        count = self.timeline.count
        if count == 0:
            raise CompareInputError(f"{self.log.path}: no /rod_states messages"
                                    + (" in the readable part of a truncated log"
                                       if self.log.truncated else ""))
        if count < 2:
            raise CompareInputError(f"only {count} /rod_states sample: nothing to "
                                    "compare over time")
        self.inputs.check_end(self.timeline.last, self.timeline.period)

    # ----- one window -----

    def window(self, t_cut: int) -> None:
        n = self.n
        states = [s for s in self.states if s[0] <= t_cut]
        self.states = [s for s in self.states if s[0] > t_cut]
        t_st = np.array([s[0] for s in states], dtype=np.int64)
        self.timeline.add(t_st)
        bounds, helds = self.inputs.take(t_cut, self.timeline.period)
        bend = [b for b in self.bending if b[0] <= t_cut]
        self.bending = [b for b in self.bending if b[0] > t_cut]
        poses = [p for p in self.nodes if p[0] <= t_cut]
        self.nodes = [p for p in self.nodes if p[0] > t_cut]
        t_out = np.unique(np.concatenate([t_st] + [np.array([x[0] for x in lst], dtype=np.int64)
                                                   for lst in (bend, poses) if lst]))
        try:
            y, yc = self.refs.advance(t_out, bounds, helds)
            yt = self.chaos.twin.advance(t_out, bounds, helds)
        except IntegrationError as exc:
            raise CompareInputError(f"the full-model re-run failed: {exc}") from None
        rows = np.searchsorted(t_out, t_st)
        ts = t_st / NS_PER_S
        phi_ref, rate_ref = self.model.phi(y[rows]), self.model.phi_rate(y[rows])
        phi_log = np.array([s[1] for s in states])
        err = np.abs(phi_log - phi_ref)
        self.q["phi"].add(ts, err, phi_ref)
        self.q["phi_rate"].add(ts, np.abs(np.array([s[2] for s in states]) - rate_ref), rate_ref)
        if self.spacecraft is not None:
            bases = dict(b for b in self.bases if b[0] <= t_cut)
            self.bases = [b for b in self.bases if b[0] > t_cut]
            base_log = np.array([bases.get(int(t), (np.nan,) * 3) for t in t_st], dtype=float)
            self.spacecraft.add(ts, phi_log, y[rows], base_log.reshape(-1, 3))
        if poses:
            r = np.searchsorted(t_out, [p[0] for p in poses])
            p_ref = self._reference_nodes(t_out[r] / NS_PER_S, y[r])
            logged = np.array([p[1] for p in poses])
            if logged.shape[1:] != p_ref.shape[1:]:
                raise CompareInputError(f"/node_poses has {logged.shape[1]} poses but the "
                                        f"scene {self.scene.name!r} has {p_ref.shape[1]}: "
                                        "wrong scene")
            d = np.linalg.norm(logged - p_ref, axis=2)
            self.q["node_position"].add(np.array([p[0] for p in poses]) / NS_PER_S, d,
                                        np.linalg.norm(p_ref, axis=2))
        if bend:
            r = np.searchsorted(t_out, [b[0] for b in bend])
            tb = np.array([b[0] for b in bend]) / NS_PER_S
            a_ref, b_ref = y[r, n:2 * n], y[r, 2 * n:3 * n]
            self.q["alpha"].add(tb, np.abs(np.array([b[1] for b in bend]) - a_ref), a_ref)
            self.q["beta"].add(tb, np.abs(np.array([b[2] for b in bend]) - b_ref), b_ref)
        ref_sep = self.refs.separation(y, yc, rows, n)
        gain = self.chaos.gains(yt[rows], phi_ref)
        self._judge(ts, np.where(np.isfinite(err), err, np.inf), gain, ref_sep, phi_log, phi_ref)
        self.chaos.renormalise(self.refs.ref.y)

    def _reference_nodes(self, ts: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(N, rows, 2) [m] the full model's ``node_poses`` positions: nodes 0..n of the plain
        chain, or every chain's nodes and then the base frame's origin."""
        n = self.n
        if self.spacecraft is None:
            return np.array([node_positions(np.asarray(self.scene.length, dtype=float), p)
                             for p in y[:, :n]])
        base = self.spacecraft.reference_base(ts, y)
        return np.array([np.concatenate([self.model.node_positions(float(t), yi), b[None, :2]])
                         for t, yi, b in zip(ts, y, base)])

    def _judge(self, ts, err, gain, ref_sep, phi_log, phi_ref) -> None:
        """Sample by sample: the horizon (chaos tracker), then the within / beyond-horizon
        statistics and the plot series."""
        e = np.max(err, axis=1)
        beyond_from = self.chaos.find_horizon(ts, e, gain, ref_sep, self.tol)
        self.within.add(ts, err, e, ref_sep, beyond_from, self.tol)
        self.beyond.add(e[beyond_from:], gain[beyond_from:], phi_log[beyond_from:],
                        phi_ref[beyond_from:])
        for i in range(ts.size):
            self.series.add(float(ts[i]), float(e[i]), phi_log[i], phi_ref[i], float(gain[i]))

    # ----- result -----

    def report(self) -> Report:
        tol = self.tol
        refs, line, chaos = self.refs, self.timeline, self.chaos
        reference: dict[str, Any] = {"model": self.model.name,
                                     "integrator": refs.ref.integ.describe(),
                                     "segments": self.inputs.segments,
                                     "rhs_evaluations": refs.ref.sim.stats.nfev,
                                     "twin_integrator": chaos.twin.integ.describe()}
        converged = False
        if refs.check is not None:
            converged = bool(self.within.ref_separation <= CONVERGED_FRACTION * tol)
            reference["check_integrator"] = refs.check.integ.describe()
            reference["phi_change"] = refs.phi_change
            reference["phi_rate_change"] = refs.rate_change
            reference["phi_change_within_horizon"] = self.within.ref_separation
            reference["converged"] = converged
        else:
            reference["phi_change"] = None
            reference["converged"] = converged
        t_end = line.last / NS_PER_S
        summary = chaos.summary((line.last - line.first) / NS_PER_S)
        if chaos.horizon is not None:
            summary["beyond_horizon"] = self.beyond.summary(chaos.horizon, t_end)
        within = self.within.summary()
        notes = list(self.log.notes)
        for s in ("alpha", "node_position"):
            if 0 < self.q[s].count < line.count:
                notes.append(f"{s}: {self.q[s].count} samples for {line.count} "
                             "/rod_states samples")
        for topic, missing in (("/bending", "alpha, beta"), ("/node_poses", "node positions")):
            if not self.log.counts[topic]:
                notes.append(f"no {topic} messages: {missing} not compared")
        if line.gap_count > len(line.gaps):
            notes.append(f"only the first {len(line.gaps)} of {line.gap_count} /rod_states "
                         "gaps are listed")
        beyond = summary["beyond_horizon"]
        judgement = judge(
            tolerance=float(tol), max_error=self.q["phi"].max, horizon=chaos.horizon,
            within_max=self.within.max_error, within_where=self.within.where,
            first_exceeded=self.within.first_exceeded, gap_count=line.gap_count,
            first_gap=line.gaps[0] if line.gaps else None, converged=converged,
            reference_error=self.within.ref_separation,
            deamplified_beyond=beyond["max_deamplified_phi_error"] if beyond else None,
            spacecraft=tuple(self.spacecraft.failures()) if self.spacecraft else ())
        if self.spacecraft is not None and self.spacecraft.moving and \
                not self.spacecraft.base_samples:
            notes.append("no /base_odometry messages: the base was not compared")
        return Report(
            n=self.n, tolerance=float(tol), samples=line.count,
            t_start=line.first / NS_PER_S, t_end=t_end,
            quantities={k: v for k, v in self.q.items() if v.count},
            reference=reference, forces=self.inputs.summary(),
            gaps=line.gaps, gap_count=line.gap_count, truncated=bool(self.log.truncated),
            horizon=chaos.horizon, chaos=summary, within=within, series=self.series,
            judgement=judgement, notes=notes,
            spacecraft=self.spacecraft.summary() if self.spacecraft else None,
            spacecraft_lines=self.spacecraft.lines() if self.spacecraft else [])


def compare_log(log: "LogStream", scene: Scene, tolerance: float = DEFAULT_TOLERANCE, *,
                rtol: float = COMPARE_REFERENCE_RTOL,
                check_rtol: float | None = COMPARE_CHECK_RTOL,
                rate_hz: float | None = None, keep_samples: bool = False,
                progress=None, plot: bool = True, integrator: str | None = None) -> Report:
    """Compare a log opened by :func:`rod_sim.io.log_source.read_log` with the full model of
    ``scene``, window by window (memory independent of the log's length; ``keep_samples``
    also keeps every sample's errors, for tests). ``progress``: None, or a function that takes
    a function giving how far the re-runs are (:class:`Reached`) and returns a context
    manager, held while the log is compared (the command's progress lines). ``integrator``:
    the re-runs' (``"dop853-jit"`` or ``"radau-jit"``); None: dop853-jit unless a probe finds
    the scene stiff for it (:mod:`rod_sim.app.stiff_probe`). Raises CompareInputError when it cannot
    be compared honestly, LogFormatError for a log that turns out unreadable."""
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise CompareInputError(f"--tolerance must be > 0 (got {tolerance!r})")
    run = _Comparison(log, scene, float(tolerance), rtol, check_rtol, rate_hz, keep_samples,
                      plot)
    with (contextlib.nullcontext() if progress is None else progress(run.reached)):
        run.start(integrator)
        for group in log.groups():
            run.add(group)
        run.finish()
    return run.report()
