"""The numbers behind ``rod-sim compare``: a logged run against a converged full-model re-run.

Pure computation (numpy + rod_sim.core) on the stream of :mod:`rod_sim.io.log_source`; the
report is printed by :mod:`rod_sim.tools.compare`.

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

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.kinematics import node_positions
from rod_sim.core.models import FullModel, make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator

if TYPE_CHECKING:
    from rod_sim.io.log_source import LogStream

NS_PER_S = 1_000_000_000

DEFAULT_TOLERANCE = 1e-2
"""[rad] default limit on max |phi_log - phi_full| (see docs/compare.md for why)."""
REFERENCE_RTOL = 1e-10
"""Relative tolerance of the full-model reference (compiled DOP853); atol = rtol * 1e-2."""
CHECK_RTOL = 1e-12
"""Tighter second reference run: their difference estimates the reference's own error."""
CONVERGED_FRACTION = 1e-2
"""The reference counts as converged when its estimated phi error is below this fraction of
the tolerance (so it cannot move the verdict)."""
GAP_FACTOR = 1.5
"""A time step larger than GAP_FACTOR sampling periods between consecutive messages is a gap."""
SCD_FLOOR_FRACTION = 1e-2
"""Relative errors for significant digits use max(|ref|, floor), floor = this fraction of the
quantity's largest |ref| over the whole run (near-zero references would otherwise divide by ~0)."""
SCD_MAX = 16.0
"""Significant digits are capped here (float64 has ~16); an exact match reports SCD_MAX."""
QUANTITIES = ("phi", "phi_rate", "node_position", "alpha", "beta")
WINDOW_SAMPLES = 2000
"""Largest number of /rod_states samples compared in one window."""
WINDOW_S = 1.0
"""[s] longest log time of one window (also the twin run's renormalisation interval)."""
TWIN_DELTA = 1e-7
"""[rad] initial (and renormalised) phi separation of the twin run measuring the gain."""
ONSET_GAIN = 2.0
"""Chaos onset: the twin run's perturbation has grown this many times."""
PLOT_POINTS = 4000
"""Samples kept for the plot (decimated evenly, the error panel keeps each bucket's maximum)."""
MAX_LISTED_GAPS = 100
"""State gaps listed in the report (all are counted)."""


class CompareInputError(ValueError):
    """The log cannot be compared (wrong scene size, incomplete force history, ...): one line."""


def reference_model(scene: Scene) -> FullModel:
    """The model every reference run of compare integrates (one place to build it): the full
    model of the logged scene, hinge features included."""
    return make_model("full", scene)


class Run:
    """A full-model run from the scene's initial state, continued window by window through the
    one driver (a :class:`Simulator`: hinge features, latches and stop contacts included) with
    the compiled DOP853 at ``rtol`` (atol = rtol * 1e-2). ``y`` (6n,) is the state at ``t_ns``;
    setting ``y`` (the twin's renormalisation) keeps the mode and re-derives the contacts."""

    def __init__(self, model: FullModel, rtol: float, y0: np.ndarray):
        self.model = model
        self.integ = make_integrator("dop853-jit", rtol=rtol, atol=rtol * 1e-2)
        self.sim = Simulator(model, self.integ)
        self.y = y0

    @property
    def y(self) -> np.ndarray:
        return self.sim.y

    @y.setter
    def y(self, value) -> None:
        self.sim.y = np.array(value, dtype=float)
        self.sim.contact = self.model.contact_state(self.sim.y)

    @property
    def t_ns(self) -> int:
        return self.sim.t_ns

    def advance(self, t_out: np.ndarray, bounds: list[int], helds: list[np.ndarray]) -> np.ndarray:
        """States (len(t_out), 6n) at the sorted times ``t_out`` [ns] (all >= ``t_ns``, the
        last <= ``bounds[-1]``); the held input ``helds[i]`` (n, 3) = forces X, Y [N] and hinge
        torques T [N m] (or (n, 2): forces, zero torques) applies up to
        ``bounds[i]`` [ns] (the integrator restarts there). Raises IntegrationError."""
        out = np.empty((t_out.size, self.y.size))
        k = 0
        while k < t_out.size and t_out[k] <= self.t_ns:
            out[k] = self.y
            k += 1
        for b, held in zip(bounds, helds):
            if b <= self.t_ns:
                continue
            j = k
            while j < t_out.size and t_out[j] <= b:
                j += 1
            held = np.asarray(held, dtype=float).reshape(self.model.n, -1)
            self.sim.set_forces(held[:, :2])
            self.sim.set_hinge_torques(held[:, 2] if held.shape[1] == 3
                                       else np.zeros(self.model.n))
            Y = self.sim.sample(np.concatenate([t_out[k:j], [int(b)]]))
            out[k:j] = Y[:-1]
            k = j
        return out


def significant_digits(err: np.ndarray, ref: np.ndarray, scale: float | None = None) -> float:
    """Significant correct digits: -log10 of the largest relative error |err| / max(|ref|,
    floor), floor = SCD_FLOOR_FRACTION * ``scale`` (default: max |ref| over all of ``ref``, any
    shape). Capped at SCD_MAX; 0 for an infinite error or a nonzero error on an all-zero
    reference; negative when the error exceeds the value."""
    err = np.abs(np.asarray(err, dtype=float))
    ref = np.abs(np.asarray(ref, dtype=float))
    if err.size == 0:
        return float("nan")
    if scale is None:
        scale = float(np.max(ref)) if ref.size else 0.0
    if scale == 0.0:                     # a zero reference: no digit of a nonzero value is right
        return SCD_MAX if float(np.max(err)) == 0.0 else 0.0
    floor = SCD_FLOOR_FRACTION * scale
    rel = float(np.max(err / np.maximum(ref, floor)))
    if not math.isfinite(rel):
        return 0.0
    if rel == 0.0:
        return SCD_MAX
    return float(min(SCD_MAX, -math.log10(rel))) + 0.0


class QuantityStats:
    """Running statistics of one compared quantity over m columns (rods, or nodes 0..n:
    ``labels``): per column the largest error and its time [s], the largest |reference|, and
    the (|ref|, error) pairs that can still decide the significant digits (a Pareto frontier:
    a pair is dropped once another has no larger |ref| and no smaller error). With ``keep``
    the per-sample errors are kept too (``t``, ``err``; for tests and short logs)."""

    def __init__(self, name: str, labels: list[int], keep: bool = False):
        self.name = name
        self.labels = labels
        m = len(labels)
        self.col_max = np.full(m, -np.inf)
        self.col_t = np.zeros(m)
        self.ref_max = 0.0
        self.count = 0
        self._r = np.empty(0)
        self._e = np.empty(0)
        self.keep = keep
        self._t: list[np.ndarray] = []
        self._err: list[np.ndarray] = []

    def add(self, t: np.ndarray, err: np.ndarray, ref: np.ndarray) -> None:
        """Samples at ``t`` (N,) [s]: errors (N, m) (non-finite: infinite) and reference
        values (N, m)."""
        if not t.size:
            return
        err = np.where(np.isfinite(err), err, np.inf)
        ref = np.abs(ref)
        i = np.argmax(err, axis=0)
        best = err[i, np.arange(err.shape[1])]
        better = best > self.col_max
        self.col_max[better] = best[better]
        self.col_t[better] = t[i[better]]
        self.ref_max = max(self.ref_max, float(np.max(ref)))
        self.count += t.size
        floor = SCD_FLOOR_FRACTION * self.ref_max
        r = np.concatenate([self._r, ref.ravel()])
        e = np.concatenate([self._e, err.ravel()])
        r = np.where(r <= floor, 0.0, r)     # below the floor: the floor divides (exactly)
        order = np.argsort(r, kind="stable")
        r, e = r[order], e[order]
        keep = e > np.concatenate([[-np.inf], np.maximum.accumulate(e)[:-1]])
        self._r, self._e = r[keep], e[keep]
        if self.keep:
            self._t.append(t.copy())
            self._err.append(err.copy())

    @property
    def t(self) -> np.ndarray:
        return np.concatenate(self._t) if self._t else np.empty(0)

    @property
    def err(self) -> np.ndarray:
        return np.concatenate(self._err) if self._err else np.empty((0, len(self.labels)))

    @property
    def max(self) -> float:
        return float(np.max(self.col_max)) if self.count else float("nan")

    def argmax(self) -> tuple[int, float]:
        """(rod or node number, time [s]) of the largest error."""
        k = int(np.argmax(self.col_max))
        return self.labels[k], float(self.col_t[k])

    def per_column(self) -> list[float]:
        return [float(v) for v in self.col_max]

    @property
    def scd(self) -> float:
        return significant_digits(self._e, self._r, self.ref_max) if self.count else float("nan")


class Decimated:
    """At most ``2 * points`` (default :data:`PLOT_POINTS`) samples of a long series, evenly
    spaced (the stride doubles when full), in one preallocated array: per kept sample its
    time [s], the maximum of ``peak`` over the samples it stands for, phi of the log and of
    the reference (n,) [rad] each, and the gain."""

    def __init__(self, points: int | None = None):
        self.points = points or PLOT_POINTS
        self.stride = 1
        self._seen = 0
        self._rows = 0
        self._data: np.ndarray | None = None
        self._peak = -np.inf

    def add(self, t: float, peak: float, phi_log: np.ndarray, phi_ref: np.ndarray,
            gain: float) -> None:
        self._peak = max(self._peak, peak)
        if self._seen % self.stride == 0:
            if self._data is None:
                self._data = np.empty((2 * self.points, 3 + 2 * phi_log.size))
            n = phi_log.size
            row = self._data[self._rows]
            row[0], row[1], row[-1] = t, self._peak, gain
            row[2:2 + n], row[2 + n:2 + 2 * n] = phi_log, phi_ref
            self._rows += 1
            self._peak = -np.inf
            if self._rows == self._data.shape[0]:
                kept = self._data[0::2].copy()
                kept[:, 1] = np.maximum(self._data[0::2, 1], self._data[1::2, 1])
                self._data[:self.points] = kept
                self._rows = self.points
                self.stride *= 2
        self._seen += 1

    @property
    def rows(self) -> np.ndarray:
        """(kept samples, 3 + 2n): t, peak, phi_log (n), phi_ref (n), gain."""
        return self._data[:self._rows] if self._data is not None else np.empty((0, 3))


class Stats:
    """Per-column count, mean, standard deviation, min and max of a streamed (N, m) series."""

    def __init__(self, m: int):
        self.count = 0
        self.sum = np.zeros(m)
        self.sumsq = np.zeros(m)
        self.min = np.full(m, np.inf)
        self.max = np.full(m, -np.inf)

    def add(self, x: np.ndarray) -> None:
        self.count += x.shape[0]
        self.sum += x.sum(axis=0)
        self.sumsq += (x * x).sum(axis=0)
        self.min = np.minimum(self.min, x.min(axis=0))
        self.max = np.maximum(self.max, x.max(axis=0))

    @property
    def mean(self) -> np.ndarray:
        return self.sum / max(self.count, 1)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.sumsq / max(self.count, 1) - self.mean ** 2, 0.0))


@dataclass
class Report:
    """The comparison's result; :meth:`as_json` is the ``--json`` output (docs/compare.md).

    ``horizon``: the predictability horizon [s] (None: the run has none, the whole log is
    judged sample by sample); ``chaos``: gain, Lyapunov exponent, onset, the log's precision
    before the onset, what set the horizon, and beyond-horizon comparisons. ``series``:
    decimated (t, max |phi error|, phi_log (n,), phi_ref (n,), gain) rows for the plot."""

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
    info: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def within_tolerance(self) -> bool:
        e = self.quantities["phi"].max
        return bool(math.isfinite(e) and e <= self.tolerance)

    def first_exceeded(self) -> float | None:
        """The first sample time [s] at which some rod's |phi error| exceeds the tolerance
        (None if none does): before it, the log agrees with the full model."""
        return self.within["first_exceeded"]

    def reasons(self) -> list[str]:
        """Why the verdict is not a pass (empty for a pass, also for PASS then INCONCLUSIVE)."""
        out = []
        e = self.within["max_phi_error"]
        upto = "" if self.horizon is None else f" before the horizon t = {self.horizon:.6g} s"
        if not math.isfinite(self.quantities["phi"].max):
            out.append("the log holds non-finite phi values")
        elif e > self.tolerance:
            rod, t = self.within["where"]
            out.append(f"max |phi error|{upto} {e:.3g} rad (rod {rod}, t = {t:.6g} s) exceeds "
                       f"the tolerance {self.tolerance:g} rad (first at t = "
                       f"{self.first_exceeded():.6g} s)")
        if self.gap_count:
            a, b = self.gaps[0]
            out.append(f"/rod_states has {self.gap_count} gap(s) (first {a:.6g} s to {b:.6g} s): "
                       "the missing samples were not checked")
        if not self.reference["converged"]:
            out.append(f"the reference is not converged{upto} (estimated phi error "
                       f"{self.within['phi_change']:.2g} rad)")
        beyond = self.chaos.get("beyond_horizon")
        if beyond and beyond["max_deamplified_phi_error"] > self.tolerance \
                and math.isfinite(self.quantities["phi"].max):
            out.append(f"beyond the horizon the log departs faster than the dynamics amplify "
                       f"perturbations (max |phi error| / gain "
                       f"{beyond['max_deamplified_phi_error']:.3g} rad > tolerance)")
        return out

    @property
    def passed(self) -> bool:
        return not self.reasons()

    @property
    def verdict(self) -> str:
        """'PASS', 'PASS_THEN_INCONCLUSIVE' (pass up to the horizon, chaotic beyond) or 'FAIL'."""
        if not self.passed:
            return "FAIL"
        return "PASS" if self.horizon is None else "PASS_THEN_INCONCLUSIVE"

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
            "verdict": self.verdict,
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
        }


class _Comparison:
    """Window-by-window state of :func:`compare_log` (see the module docstring)."""

    def __init__(self, log: "LogStream", scene: Scene, tolerance: float, rtol: float,
                 check_rtol: float | None, rate_hz: float | None, keep: bool):
        self.log, self.scene, self.tol = log, scene, tolerance
        self.n = n = scene.n
        self.model = reference_model(scene)
        y0 = self.model.initial_state()
        self.ref = Run(self.model, rtol, y0)
        self.check = Run(self.model, check_rtol, y0) if check_rtol else None
        twin0 = y0.copy()
        twin0[:n] += TWIN_DELTA * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
        self.twin = Run(self.model, rtol, twin0)
        self.log_gain = 0.0                 # ln of the twin's renormalisations so far
        self.gain = 1.0                     # running max of the amplification
        self.rate_hz = rate_hz
        self.period: float | None = None
        rods = list(range(1, n + 1))
        self.q = {"phi": QuantityStats("phi", rods, keep),
                  "phi_rate": QuantityStats("phi_rate", rods, keep),
                  "node_position": QuantityStats("node_position", list(range(n + 1)), keep),
                  "alpha": QuantityStats("alpha", rods, keep),
                  "beta": QuantityStats("beta", rods, keep)}
        self.states: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.bending: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.nodes: list[tuple[int, np.ndarray]] = []
        self.applied: list[tuple[int, np.ndarray]] = []
        self.held: np.ndarray | None = None
        self.last_applied: int | None = None
        self.applied_messages = 0
        self.segments = 0
        self.max_held = 0.0
        self.torque_msgs: list[tuple[int, np.ndarray]] = []
        self.held_force = np.zeros((n, 2))
        self.held_torque = np.zeros(n)
        self.last_torque: int | None = None
        self.torque_messages = 0
        self.max_torque = 0.0
        self.state_count = 0
        self.first_state: int | None = None
        self.last_state: int | None = None
        self.gaps: list[tuple[float, float]] = []
        self.gap_count = 0
        self.phi_change = 0.0
        self.rate_change = 0.0
        self.phi_change_within = 0.0
        # chaos and horizon
        self.onset: float | None = None
        self.eps = 0.0
        self.horizon: float | None = None
        self.horizon_cause = None
        self.within_max = -np.inf
        self.within_where = (1, 0.0)
        self.first_exceeded: float | None = None
        self.deamplified = 0.0
        self.beyond_log = Stats(n)
        self.beyond_ref = Stats(n)
        self.series = Decimated()

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
        if g.applied is not None:
            self.applied.append((g.t_ns, g.applied))
        if g.torques is not None:
            self.torque_msgs.append((g.t_ns, g.torques))
        if g.state is not None and self.states and (
                len(self.states) >= WINDOW_SAMPLES
                or g.t_ns - self.states[0][0] >= WINDOW_S * NS_PER_S):
            self.window(g.t_ns)

    def finish(self) -> None:
        if self.states:
            self.window(self.states[-1][0])
        if self.state_count == 0:
            raise CompareInputError(f"{self.log.path}: no /rod_states messages"
                                    + (" in the readable part of a truncated log"
                                       if self.log.truncated else ""))
        if self.state_count < 2:
            raise CompareInputError(f"only {self.state_count} /rod_states sample: nothing to "
                                    "compare over time")
        if self.last_state - self.last_applied > GAP_FACTOR * self.period:
            raise CompareInputError(
                f"/applied_forces ends at t = {self.last_applied / NS_PER_S:.9g} s but the "
                f"states go on to {self.last_state / NS_PER_S:.9g} s: messages are missing")
        if (self.log.has_torques and self.last_torque is not None
                and self.last_state - self.last_torque > GAP_FACTOR * self.period):
            raise CompareInputError(
                f"/applied_torques ends at t = {self.last_torque / NS_PER_S:.9g} s but the "
                f"states go on to {self.last_state / NS_PER_S:.9g} s: messages are missing")

    # ----- one window -----

    def _period(self, t: np.ndarray) -> float:
        rate = self.rate_hz
        if rate is not None and math.isfinite(rate) and rate > 0:
            return NS_PER_S / rate
        d = np.diff(t)
        d = d[d > 0]
        if d.size == 0:
            raise CompareInputError("only one /rod_states sample: nothing to compare over time")
        return float(np.median(d))

    def _forces(self, t_cut: int) -> tuple[list[int], list[np.ndarray]]:
        """Integration bounds and held commands up to ``t_cut`` from the buffered applied
        forces (held = applied - scripted loads; consecutive equal commands merged); refuses
        a force history with a hole."""
        use = [(t, a) for t, a in self.applied if t <= t_cut]
        self.applied = [(t, a) for t, a in self.applied if t > t_cut]
        if self.last_applied is None:
            if not use:
                raise CompareInputError(
                    f"no /applied_forces messages up to t = {t_cut / NS_PER_S:.9g} s, so the "
                    "applied-force history cannot be rebuilt")
            if use[0][0] != 0:
                raise CompareInputError(f"/applied_forces starts at t = {use[0][0] / NS_PER_S:.9g}"
                                        " s, not 0: the forces before it are unknown")
        torques = [(t, v) for t, v in self.torque_msgs if t <= t_cut]
        self.torque_msgs = [(t, v) for t, v in self.torque_msgs if t > t_cut]
        if self.log.has_torques and self.last_torque is None:
            if not torques:
                raise CompareInputError(
                    f"no /applied_torques messages up to t = {t_cut / NS_PER_S:.9g} s, so the "
                    "hinge-torque history cannot be rebuilt")
            if torques[0][0] != 0:
                raise CompareInputError(f"/applied_torques starts at t = "
                                        f"{torques[0][0] / NS_PER_S:.9g} s, not 0: the torques "
                                        "before it are unknown")
        changes: dict[int, dict[str, np.ndarray]] = {}
        for t, applied in use:
            changes.setdefault(t, {})["forces"] = applied
        for t, value in torques:
            changes.setdefault(t, {})["torques"] = value
        bounds, helds = [], []
        for t in sorted(changes):
            change = changes[t]
            if "forces" in change:
                applied = change["forces"]
                if applied.ndim == 1:
                    applied = self.log.applied_array(t, applied)
                if (self.last_applied is not None
                        and t - self.last_applied > GAP_FACTOR * self.period):
                    raise CompareInputError(
                        f"/applied_forces has a gap longer than {GAP_FACTOR:g} sampling periods "
                        f"({self.last_applied / NS_PER_S:.9g} s to {t / NS_PER_S:.9g} s): "
                        "messages are missing, so the force history cannot be rebuilt")
                self.last_applied = t
                self.applied_messages += 1
                self.held_force = applied - self.model.forces(t / NS_PER_S)
                self.max_held = max(self.max_held, float(np.max(np.abs(self.held_force))))
            if "torques" in change:
                value = self.log.torque_array(t, change["torques"])
                if (self.last_torque is not None
                        and t - self.last_torque > GAP_FACTOR * self.period):
                    raise CompareInputError(
                        f"/applied_torques has a gap longer than {GAP_FACTOR:g} sampling "
                        f"periods ({self.last_torque / NS_PER_S:.9g} s to "
                        f"{t / NS_PER_S:.9g} s): messages are missing, so the hinge-torque "
                        "history cannot be rebuilt")
                self.last_torque = t
                self.torque_messages += 1
                self.held_torque = value
                self.max_torque = max(self.max_torque, float(np.max(np.abs(value))))
            held = np.column_stack([self.held_force, self.held_torque])
            if self.held is None or not np.array_equal(held, self.held):
                bounds.append(t)
                helds.append(self.held)
                self.held = held
                self.segments += 1
        bounds.append(t_cut)
        helds.append(self.held)
        return bounds, helds

    def window(self, t_cut: int) -> None:
        n = self.n
        states = [s for s in self.states if s[0] <= t_cut]
        self.states = [s for s in self.states if s[0] > t_cut]
        t_st = np.array([s[0] for s in states], dtype=np.int64)
        if self.period is None:
            self.period = self._period(t_st)
            if t_st[0] > GAP_FACTOR * self.period:
                self._gap(0, int(t_st[0]))
        prev = self.last_state
        steps = np.diff(np.concatenate([[prev], t_st])) if prev is not None else np.diff(t_st)
        base = [prev] + list(t_st) if prev is not None else list(t_st)
        for i in np.flatnonzero(steps > GAP_FACTOR * self.period):
            self._gap(int(base[i]), int(base[i + 1]))
        if self.first_state is None:
            self.first_state = int(t_st[0])
        self.last_state = int(t_st[-1])
        self.state_count += t_st.size
        bounds, helds = self._forces(t_cut)
        bend = [b for b in self.bending if b[0] <= t_cut]
        self.bending = [b for b in self.bending if b[0] > t_cut]
        poses = [p for p in self.nodes if p[0] <= t_cut]
        self.nodes = [p for p in self.nodes if p[0] > t_cut]
        t_out = np.unique(np.concatenate([t_st] + [np.array([x[0] for x in lst], dtype=np.int64)
                                                   for lst in (bend, poses) if lst]))
        try:
            y = self.ref.advance(t_out, bounds, helds)
            yc = self.check.advance(t_out, bounds, helds) if self.check else None
            yt = self.twin.advance(t_out, bounds, helds)
        except IntegrationError as exc:
            raise CompareInputError(f"the full-model re-run failed: {exc}") from None
        rows = np.searchsorted(t_out, t_st)
        ts = t_st / NS_PER_S
        phi_ref, rate_ref = y[rows, :n], y[rows, 3 * n:4 * n]
        phi_log = np.array([s[1] for s in states])
        err = np.abs(phi_log - phi_ref)
        self.q["phi"].add(ts, err, phi_ref)
        self.q["phi_rate"].add(ts, np.abs(np.array([s[2] for s in states]) - rate_ref), rate_ref)
        if poses:
            r = np.searchsorted(t_out, [p[0] for p in poses])
            p_ref = np.array([node_positions(np.asarray(self.scene.length, dtype=float), p)
                              for p in y[r, :n]])
            d = np.linalg.norm(np.array([p[1] for p in poses]) - p_ref, axis=2)
            self.q["node_position"].add(np.array([p[0] for p in poses]) / NS_PER_S, d,
                                        np.linalg.norm(p_ref, axis=2))
        if bend:
            r = np.searchsorted(t_out, [b[0] for b in bend])
            tb = np.array([b[0] for b in bend]) / NS_PER_S
            a_ref, b_ref = y[r, n:2 * n], y[r, 2 * n:3 * n]
            self.q["alpha"].add(tb, np.abs(np.array([b[1] for b in bend]) - a_ref), a_ref)
            self.q["beta"].add(tb, np.abs(np.array([b[2] for b in bend]) - b_ref), b_ref)
        ref_sep = np.zeros(t_st.size)
        if yc is not None:
            ref_sep = np.max(np.abs(yc[rows, :n] - phi_ref), axis=1)
            self.phi_change = max(self.phi_change, float(np.max(ref_sep)))
            self.rate_change = max(self.rate_change, float(np.max(
                np.abs(yc[rows, 3 * n:4 * n] - rate_ref))))
        sep = np.max(np.abs(yt[rows, :n] - phi_ref), axis=1)
        with np.errstate(over="ignore"):     # beyond ~240 s of chaos the gain is inf: no
            gain = np.maximum.accumulate(np.maximum(np.exp(self.log_gain) * sep / TWIN_DELTA,
                                                    self.gain))     # numpy warnings for it
        self.gain = float(gain[-1])
        self._judge(ts, np.where(np.isfinite(err), err, np.inf), gain, ref_sep, phi_log, phi_ref)
        self._renormalise()

    def _gap(self, a: int, b: int) -> None:
        self.gap_count += 1
        if len(self.gaps) < MAX_LISTED_GAPS:
            self.gaps.append((a / NS_PER_S, b / NS_PER_S))

    def _renormalise(self) -> None:
        """Scale the twin's separation back to TWIN_DELTA (Benettin) and book the growth."""
        n = self.n
        d = self.twin.y - self.ref.y
        sep = float(np.max(np.abs(d[:n])))
        if sep > 0 and math.isfinite(sep):
            self.log_gain += math.log(sep / TWIN_DELTA)
            self.twin.y = self.ref.y + d * (TWIN_DELTA / sep)

    def _judge(self, ts, err, gain, ref_sep, phi_log, phi_ref) -> None:
        """Sample by sample: chaos onset, the log's precision before it, the horizon, and the
        within / beyond-horizon statistics."""
        e = np.max(err, axis=1)
        limit = CONVERGED_FRACTION * self.tol
        over = np.flatnonzero(~(e <= self.tol))
        if over.size and self.first_exceeded is None:
            self.first_exceeded = float(ts[over[0]])
        beyond_from = 0 if self.horizon is not None else ts.size
        for i in range(ts.size):
            if self.horizon is None:
                if self.onset is None:
                    self.eps = max(self.eps, float(e[i]))
                    if gain[i] >= ONSET_GAIN:
                        self.onset = float(ts[i])
                if self.onset is not None:
                    if self.eps * gain[i] > self.tol:
                        self.horizon, self.horizon_cause = float(ts[i]), "log_precision"
                    elif ref_sep[i] > limit:
                        self.horizon, self.horizon_cause = float(ts[i]), "reference_separation"
                if self.horizon is not None:
                    beyond_from = i
                    break
        within = slice(0, beyond_from)
        if beyond_from:
            ew = e[within]
            k = int(np.argmax(ew))
            if ew[k] > self.within_max:
                self.within_max = float(ew[k])
                self.within_where = (int(np.argmax(err[k])) + 1, float(ts[k]))
            self.phi_change_within = max(self.phi_change_within,
                                         float(np.max(ref_sep[within])))
        if beyond_from < ts.size:
            rest = slice(beyond_from, ts.size)
            self.deamplified = max(self.deamplified, float(np.max(e[rest] / gain[rest])))
            self.beyond_log.add(phi_log[rest])
            self.beyond_ref.add(phi_ref[rest])
        for i in range(ts.size):
            self.series.add(float(ts[i]), float(e[i]), phi_log[i], phi_ref[i], float(gain[i]))

    # ----- result -----

    def report(self) -> Report:
        tol = self.tol
        reference: dict[str, Any] = {"model": self.model.name,
                                     "integrator": self.ref.integ.describe(),
                                     "segments": self.segments,
                                     "rhs_evaluations": self.ref.sim.stats.nfev}
        if self.check is not None:
            reference["check_integrator"] = self.check.integ.describe()
            reference["phi_change"] = self.phi_change
            reference["phi_rate_change"] = self.rate_change
            reference["phi_change_within_horizon"] = self.phi_change_within
            reference["converged"] = bool(self.phi_change_within <= CONVERGED_FRACTION * tol)
        else:
            reference["phi_change"] = None
            reference["converged"] = False
        t_span = (self.last_state - self.first_state) / NS_PER_S
        chaos: dict[str, Any] = {
            "gain": self.gain,
            "lyapunov_exponent": (self.log_gain / t_span if t_span > 0 else None),
            "onset": self.onset,
            "log_precision_before_onset": self.eps if self.onset is not None else None,
            "horizon_cause": self.horizon_cause,
            "twin_perturbation": TWIN_DELTA,
            "twin_rhs_evaluations": self.twin.sim.stats.nfev,
            "beyond_horizon": None,
        }
        if self.horizon is not None and self.beyond_log.count:
            lg, rf = self.beyond_log, self.beyond_ref
            chaos["beyond_horizon"] = {
                "t_start": self.horizon, "t_end": self.last_state / NS_PER_S,
                "samples": lg.count,
                "max_deamplified_phi_error": self.deamplified,
                "phi_mean": {"log": lg.mean.tolist(), "reference": rf.mean.tolist()},
                "phi_std": {"log": lg.std.tolist(), "reference": rf.std.tolist()},
                "phi_min": {"log": lg.min.tolist(), "reference": rf.min.tolist()},
                "phi_max": {"log": lg.max.tolist(), "reference": rf.max.tolist()},
                "max_mean_difference": float(np.max(np.abs(lg.mean - rf.mean))),
                "max_std_difference": float(np.max(np.abs(lg.std - rf.std))),
                "max_outside_reference_range": float(max(0.0, np.max(rf.min - lg.min),
                                                         np.max(lg.max - rf.max))),
            }
        within = {"max_phi_error": self.within_max, "where": self.within_where,
                  "first_exceeded": self.first_exceeded, "phi_change": self.phi_change_within}
        notes = list(self.log.notes)
        for s in ("alpha", "node_position"):
            if 0 < self.q[s].count < self.state_count:
                notes.append(f"{s}: {self.q[s].count} samples for {self.state_count} "
                             "/rod_states samples")
        for topic, missing in (("/bending", "alpha, beta"), ("/node_poses", "node positions")):
            if not self.log.counts[topic]:
                notes.append(f"no {topic} messages: {missing} not compared")
        if self.gap_count > len(self.gaps):
            notes.append(f"only the first {len(self.gaps)} of {self.gap_count} /rod_states "
                         "gaps are listed")
        return Report(
            n=self.n, tolerance=float(tol), samples=self.state_count,
            t_start=self.first_state / NS_PER_S, t_end=self.last_state / NS_PER_S,
            quantities={k: v for k, v in self.q.items() if v.count},
            reference=reference,
            forces={"messages": self.applied_messages, "segments": self.segments,
                    "max_abs_held": self.max_held, "torque_messages": self.torque_messages,
                    "max_abs_torque": self.max_torque},
            gaps=self.gaps, gap_count=self.gap_count, truncated=bool(self.log.truncated),
            horizon=self.horizon, chaos=chaos, within=within, series=self.series, notes=notes)


def compare_log(log: "LogStream", scene: Scene, tolerance: float = DEFAULT_TOLERANCE, *,
                rtol: float = REFERENCE_RTOL, check_rtol: float | None = CHECK_RTOL,
                rate_hz: float | None = None, keep_samples: bool = False) -> Report:
    """Compare a log opened by :func:`rod_sim.io.log_source.read_log` with the full model of
    ``scene``, window by window (memory independent of the log's length; ``keep_samples``
    also keeps every sample's errors, for tests). Raises CompareInputError when it cannot be
    compared honestly, LogFormatError for a log that turns out unreadable."""
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise CompareInputError(f"--tolerance must be > 0 (got {tolerance!r})")
    run = _Comparison(log, scene, float(tolerance), rtol, check_rtol, rate_hz, keep_samples)
    for group in log.groups():
        run.add(group)
    run.finish()
    return run.report()
