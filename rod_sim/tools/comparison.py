"""The numbers behind ``rod-sim compare``: a logged run against a converged full-model re-run.

Pure computation on arrays (numpy + rod_sim.core); the log is read by
:mod:`rod_sim.io.log_source` and the report printed by :mod:`rod_sim.tools.compare`.

Applied-force history. A ``/applied_forces`` message at t_i holds the forces acting from t_i
on: the scene's scripted loads (continuous functions of t, re-evaluated by the model) plus the
held command, a zero-order hold. So the held part on [t_i, t_{i+1}) is
``held_i = applied(t_i) - scripted(t_i)``; the re-run applies the scripted loads continuously
and ``held_i`` piecewise constant, restarting the integrator wherever ``held`` changes. This
covers ``rod-sim simulate`` logs (a message at every sample, held = 0) and node logs (a message
at the start of every control period).

Units: angles [rad], rates [rad/s], positions [m], forces [N], times [s] (integer ns where
named ``*_ns``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.kinematics import node_positions
from rod_sim.core.models import FullModel, make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator

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


class CompareInputError(ValueError):
    """The log cannot be compared (wrong scene size, incomplete force history, ...): one line."""


@dataclass(frozen=True)
class ForceHistory:
    """The applied forces as the re-run uses them: on [t_ns[i], t_ns[i+1]) the scripted loads
    plus ``held[i]`` (n, 2) [N]. ``messages``: /applied_forces messages read; ``max_residual``
    [N]: largest |held| (0 for a log whose commands were all zero)."""

    t_ns: np.ndarray
    held: np.ndarray
    messages: int
    max_residual: float


def force_history(scene: Scene, t_ns: np.ndarray, applied: np.ndarray) -> ForceHistory:
    """Held commands from logged applied forces ``applied`` (K, n, 2) at ``t_ns`` (K,) [ns];
    consecutive equal commands are merged into one segment."""
    model = FullModel(scene)
    held = np.array([applied[i] - model.forces(t / NS_PER_S) for i, t in enumerate(t_ns)])
    keep = [0] + [i for i in range(1, len(t_ns)) if not np.array_equal(held[i], held[i - 1])]
    return ForceHistory(np.asarray(t_ns, dtype=np.int64)[keep], held[keep], int(len(t_ns)),
                        float(np.max(np.abs(held))) if held.size else 0.0)


def find_gaps(t_ns: np.ndarray, period_ns: float) -> list[tuple[float, float]]:
    """Intervals (t_a, t_b) [s] between consecutive times more than GAP_FACTOR periods apart."""
    d = np.diff(t_ns)
    idx = np.flatnonzero(d > GAP_FACTOR * period_ns)
    return [(t_ns[i] / NS_PER_S, t_ns[i + 1] / NS_PER_S) for i in idx]


def sampling_period_ns(t_ns: np.ndarray, rate_hz: float | None) -> float:
    """The sampling period [ns]: 1/rate_hz when known, else the median step of ``t_ns``."""
    if rate_hz is not None and math.isfinite(rate_hz) and rate_hz > 0:
        return NS_PER_S / rate_hz
    d = np.diff(t_ns)
    d = d[d > 0]
    if d.size == 0:
        raise CompareInputError("only one /rod_states sample: nothing to compare over time")
    return float(np.median(d))


def check_force_coverage(applied_t_ns: np.ndarray, last_state_ns: int,
                         period_ns: float) -> None:
    """Refuse (CompareInputError) a force history with a hole: it must start at t = 0, have no
    step over GAP_FACTOR periods, and reach to within GAP_FACTOR periods of the last state."""
    if applied_t_ns.size == 0 or applied_t_ns[0] != 0:
        first = applied_t_ns[0] / NS_PER_S if applied_t_ns.size else float("nan")
        raise CompareInputError(f"/applied_forces starts at t = {first:.9g} s, not 0: the forces "
                                "before it are unknown")
    gaps = find_gaps(applied_t_ns[applied_t_ns <= last_state_ns], period_ns)
    if gaps:
        a, b = gaps[0]
        raise CompareInputError(
            f"/applied_forces has {len(gaps)} gap(s) longer than {GAP_FACTOR:g} sampling periods "
            f"(first: {a:.9g} s to {b:.9g} s): messages are missing, so the force history "
            "cannot be rebuilt")
    last = applied_t_ns[applied_t_ns <= last_state_ns]
    if last_state_ns - last[-1] > GAP_FACTOR * period_ns:
        raise CompareInputError(f"/applied_forces ends at t = {last[-1] / NS_PER_S:.9g} s but the "
                                f"states go on to {last_state_ns / NS_PER_S:.9g} s: messages "
                                "are missing")


@dataclass
class Reference:
    """The full model sampled at ``t_ns`` (N,) [ns]: states ``y`` (N, 6n)."""

    t_ns: np.ndarray
    y: np.ndarray
    integrator: str
    nfev: int
    segments: int


def reference_run(scene: Scene, history: ForceHistory, t_out_ns: np.ndarray,
                  rtol: float = REFERENCE_RTOL) -> Reference:
    """Integrate the full model from the scene's initial state at t = 0 through ``history``
    (integrator restarted at every change of the held command) and sample it at the sorted,
    unique times ``t_out_ns`` [ns] (all >= 0). Raises IntegrationError."""
    integ = make_integrator("dop853-jit", rtol=rtol, atol=rtol * 1e-2)
    sim = Simulator(make_model("full", scene), integ)    # the logged scene, hinge features included
    out = np.empty((t_out_ns.size, sim.model.state_size))
    starts = history.t_ns
    t_end = int(t_out_ns[-1])
    done = 0
    while done < t_out_ns.size and t_out_ns[done] == 0:
        out[done] = sim.y
        done += 1
    segments = 0
    for i, a in enumerate(starts):
        if a >= t_end:
            break
        b = int(starts[i + 1]) if i + 1 < starts.size else t_end
        b = min(b, t_end)
        stop = done
        while stop < t_out_ns.size and t_out_ns[stop] <= b:
            stop += 1
        sim.set_forces(history.held[i])
        Y = sim.sample(np.concatenate([t_out_ns[done:stop], [b]]))
        out[done:stop] = Y[:-1]
        done = stop
        segments += 1
    return Reference(t_out_ns, out, integ.describe(), integ.stats.nfev, segments)


def significant_digits(err: np.ndarray, ref: np.ndarray) -> float:
    """Significant correct digits: -log10 of the largest relative error |err| / max(|ref|,
    floor), floor = SCD_FLOOR_FRACTION * max |ref| over all of ``ref`` (any shape). Capped at
    SCD_MAX; 0 for an infinite error or a nonzero error on an all-zero reference; negative when
    the error exceeds the value."""
    err = np.abs(np.asarray(err, dtype=float))
    ref = np.abs(np.asarray(ref, dtype=float))
    if err.size == 0:
        return float("nan")
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


@dataclass
class QuantityError:
    """One compared quantity: errors (N, m) at times ``t`` (N,) [s] for m rods or nodes
    (``labels`` their numbers), and the reference values (N, m) for significant digits."""

    name: str
    t: np.ndarray
    err: np.ndarray
    ref: np.ndarray
    labels: list[int]

    @property
    def max(self) -> float:
        return float(np.max(self.err)) if self.err.size else float("nan")

    def argmax(self) -> tuple[int, float]:
        """(rod or node number, time [s]) of the largest error."""
        i, k = np.unravel_index(int(np.argmax(self.err)), self.err.shape)
        return self.labels[int(k)], float(self.t[int(i)])

    def per_column(self) -> list[float]:
        return [float(v) for v in np.max(self.err, axis=0)]

    @property
    def scd(self) -> float:
        return significant_digits(self.err, self.ref)


@dataclass
class Report:
    """The comparison's result; :meth:`as_json` is the ``--json`` output (docs/compare.md)."""

    n: int
    tolerance: float
    samples: int
    t_start: float
    t_end: float
    quantities: dict[str, QuantityError]
    phi_log: np.ndarray
    phi_ref: np.ndarray
    t: np.ndarray
    reference: dict[str, Any]
    forces: dict[str, Any]
    gaps: list[tuple[float, float]]
    truncated: bool
    info: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def within_tolerance(self) -> bool:
        e = self.quantities["phi"].max
        return bool(math.isfinite(e) and e <= self.tolerance)

    def first_exceeded(self) -> float | None:
        """The first sample time [s] at which some rod's |phi error| exceeds the tolerance
        (None if none does): before it, the log agrees with the full model."""
        bad = np.flatnonzero(~(np.max(self.quantities["phi"].err, axis=1) <= self.tolerance))
        return float(self.t[bad[0]]) if bad.size else None

    def reasons(self) -> list[str]:
        """Why the verdict is not a pass (empty for a pass)."""
        out = []
        e = self.quantities["phi"].max
        if not math.isfinite(e):
            out.append("the log holds non-finite phi values")
        elif e > self.tolerance:
            rod, t = self.quantities["phi"].argmax()
            out.append(f"max |phi error| {e:.3g} rad (rod {rod}, t = {t:.6g} s) exceeds the "
                       f"tolerance {self.tolerance:g} rad (first at t = "
                       f"{self.first_exceeded():.6g} s)")
        if self.gaps:
            a, b = self.gaps[0]
            out.append(f"/rod_states has {len(self.gaps)} gap(s) (first {a:.6g} s to {b:.6g} s): "
                       "the missing samples were not checked")
        if not self.reference["converged"]:
            out.append(f"the reference is not converged (estimated phi error "
                       f"{self.reference['phi_change']:.2g} rad)")
        return out

    @property
    def passed(self) -> bool:
        return not self.reasons()

    def as_json(self) -> dict[str, Any]:
        def where(q):
            if not self.quantities[q].err.size:
                return None
            label, t = self.quantities[q].argmax()
            return {"node" if q == "node_position" else "rod": label, "t": t}

        def num(x):
            return None if x is None or not math.isfinite(x) else float(x)

        present = [q for q in QUANTITIES if q in self.quantities]
        per_rod = []
        for k in range(1, self.n + 1):
            row: dict[str, Any] = {"rod": k}
            for q in present:
                qe = self.quantities[q]
                if k in qe.labels and qe.err.size:
                    j = qe.labels.index(k)
                    row[q] = num(float(np.max(qe.err[:, j])))
                    row[q + "_t"] = float(qe.t[int(np.argmax(qe.err[:, j]))])
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
            "within_tolerance": self.within_tolerance,
            "reasons": self.reasons(),
            "tolerance_first_exceeded_at": self.first_exceeded(),
            "max_abs_error": {q: (num(self.quantities[q].max) if q in self.quantities else None)
                              for q in QUANTITIES},
            "where": {q: (where(q) if q in self.quantities else None) for q in QUANTITIES},
            "significant_digits": {q: (num(self.quantities[q].scd) if q in self.quantities
                                       else None) for q in QUANTITIES},
            "per_rod": per_rod,
            "reference": self.reference,
            "forces": self.forces,
            "gaps": {"rod_states": [list(g) for g in self.gaps]},
            "truncated": self.truncated,
            "notes": list(self.notes),
        }


def _rows(t_ns: np.ndarray, ref_t_ns: np.ndarray) -> np.ndarray:
    return np.searchsorted(ref_t_ns, t_ns)


def compare_log(log, scene: Scene, tolerance: float = DEFAULT_TOLERANCE, *,
                rtol: float = REFERENCE_RTOL, check_rtol: float | None = CHECK_RTOL,
                rate_hz: float | None = None) -> Report:
    """Compare a read log (:class:`rod_sim.io.log_source.LogData`) with the full model of
    ``scene``. Raises CompareInputError when it cannot be compared honestly."""
    if log.n != scene.n:
        raise CompareInputError(f"the log has {log.n} rods but the scene {scene.name!r} has "
                                f"{scene.n}: wrong scene")
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise CompareInputError(f"--tolerance must be > 0 (got {tolerance!r})")
    t_states = log.phi.t_ns
    if t_states.size < 2:
        raise CompareInputError(f"only {t_states.size} /rod_states sample: nothing to compare "
                                "over time")
    period = sampling_period_ns(t_states, rate_hz)
    last = int(t_states[-1])
    check_force_coverage(log.applied.t_ns, last, period)
    use = log.applied.t_ns <= last
    history = force_history(scene, log.applied.t_ns[use], log.applied.values[use])
    gaps = find_gaps(t_states, period)
    if t_states[0] > GAP_FACTOR * period:
        gaps.insert(0, (0.0, t_states[0] / NS_PER_S))

    wanted = [t_states]
    for s in (log.alpha, log.nodes):
        if s is not None:
            wanted.append(s.t_ns[s.t_ns <= last])
    t_ref = np.unique(np.concatenate(wanted))
    try:
        ref = reference_run(scene, history, t_ref, rtol)
        check = reference_run(scene, history, t_ref, check_rtol) if check_rtol else None
    except IntegrationError as exc:
        raise CompareInputError(f"the full-model re-run failed: {exc}") from None
    model = FullModel(scene)
    n = scene.n
    y = ref.y
    phi_ref, rate_ref = y[:, :n], y[:, 3 * n:4 * n]
    rows = _rows(t_states, t_ref)
    t_s = t_states / NS_PER_S
    bad = lambda e: np.where(np.isfinite(e), e, np.inf)  # noqa: E731 - NaN in the log = infinite error
    q: dict[str, QuantityError] = {}
    labels = list(range(1, n + 1))
    q["phi"] = QuantityError("phi", t_s, bad(np.abs(log.phi.values - phi_ref[rows])),
                             phi_ref[rows], labels)
    q["phi_rate"] = QuantityError("phi_rate", t_s,
                                  bad(np.abs(log.phi_rate.values - rate_ref[rows])),
                                  rate_ref[rows], labels)
    l = np.asarray(scene.length, dtype=float)
    if log.nodes is not None:
        keep = log.nodes.t_ns <= last
        r = _rows(log.nodes.t_ns[keep], t_ref)
        p_ref = np.array([node_positions(l, p) for p in phi_ref[r]])
        d = np.linalg.norm(log.nodes.values[keep] - p_ref, axis=2)
        q["node_position"] = QuantityError("node_position", log.nodes.t_ns[keep] / NS_PER_S,
                                           bad(d), np.linalg.norm(p_ref, axis=2),
                                           list(range(0, n + 1)))
    if log.alpha is not None:
        keep = log.alpha.t_ns <= last
        r = _rows(log.alpha.t_ns[keep], t_ref)
        tb = log.alpha.t_ns[keep] / NS_PER_S
        a_ref, b_ref = y[r, n:2 * n], y[r, 2 * n:3 * n]
        q["alpha"] = QuantityError("alpha", tb, bad(np.abs(log.alpha.values[keep] - a_ref)),
                                   a_ref, labels)
        q["beta"] = QuantityError("beta", tb, bad(np.abs(log.beta.values[keep] - b_ref)),
                                  b_ref, labels)

    reference: dict[str, Any] = {"model": model.name, "integrator": ref.integrator,
                                 "segments": ref.segments, "rhs_evaluations": ref.nfev}
    if check is not None:
        reference["check_integrator"] = check.integrator
        reference["phi_change"] = float(np.max(np.abs(check.y[:, :n] - phi_ref)))
        reference["phi_rate_change"] = float(np.max(np.abs(check.y[:, 3 * n:4 * n] - rate_ref)))
        reference["converged"] = bool(reference["phi_change"] <= CONVERGED_FRACTION * tolerance)
    else:
        reference["phi_change"] = None
        reference["converged"] = False
    forces = {"messages": history.messages, "segments": int(history.t_ns.size),
              "max_abs_held": history.max_residual}
    notes = list(log.notes)
    extra_states = [s for s in ("alpha", "node_position") if s in q and q[s].t.size < t_s.size]
    for s in extra_states:
        notes.append(f"{s}: {q[s].t.size} samples for {t_s.size} /rod_states samples")
    return Report(n=n, tolerance=float(tolerance), samples=int(t_s.size), t_start=float(t_s[0]),
                  t_end=float(t_s[-1]), quantities=q, phi_log=log.phi.values,
                  phi_ref=phi_ref[rows], t=t_s, reference=reference, forces=forces, gaps=gaps,
                  truncated=bool(log.truncated), notes=notes)
