"""Per-quantity statistics of ``rod-sim compare``, kept while the log streams by (memory does
not grow with its length): the largest error per column and where it occurs with the
significant-digit frontier (:class:`QuantityStats`), per-column moments of a series
(:class:`ColumnSummary`) and an evenly decimated series for the plot (:class:`Decimated`).

Units: errors and values in the quantity's unit (rad, rad/s, m), times [s].
"""
from __future__ import annotations

import math

import numpy as np

SCD_FLOOR_FRACTION = 1e-2
"""Relative errors for significant digits use max(|ref|, floor), floor = this fraction of the
quantity's largest |ref| over the whole run (near-zero references would otherwise divide by ~0)."""
SCD_MAX = 16.0
"""Significant digits are capped here (float64 has ~16); an exact match reports SCD_MAX."""
QUANTITIES = ("phi", "phi_rate", "node_position", "alpha", "beta")
"""The compared quantities, in the order of the report."""


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
    """At most ``2 * points`` samples of a long series, evenly spaced (the stride doubles when
    full), in one preallocated array: per kept sample its time [s], the maximum of ``peak``
    over the samples it stands for, phi of the log and of the reference (n,) [rad] each, and
    the gain."""

    def __init__(self, points: int, angles: bool = True):
        self.points = points
        self.angles = angles
        """False: no phi kept (rows of t, peak, gain only)."""
        self.stride = 1
        self._seen = 0
        self._rows = 0
        self._data: np.ndarray | None = None
        self._peak = -np.inf

    def add(self, t: float, peak: float, phi_log: np.ndarray, phi_ref: np.ndarray,
            gain: float) -> None:
        self._peak = max(self._peak, peak)
        if self._seen % self.stride == 0:
            n = phi_log.size if self.angles else 0
            if self._data is None:
                self._data = np.empty((2 * self.points, 3 + 2 * n))
            row = self._data[self._rows]
            row[0], row[1], row[-1] = t, self._peak, gain
            if n:
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
        """(kept samples, 3 + 2n): t, peak, phi_log (n), phi_ref (n), gain (n = 0 without
        ``angles``)."""
        return self._data[:self._rows] if self._data is not None else np.empty((0, 3))


class ColumnSummary:
    """Per-column count, mean, standard deviation, min and max of a streamed (N, m) series
    (e.g. phi [rad] of the log beyond the predictability horizon)."""

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


class WithinHorizon:
    """Before the predictability horizon (the whole log when there is none): the largest max
    phi error [rad] over rods, where it occurs (rod, t [s]), the largest separation of the two
    reference runs [rad]; and over the whole log, the first time [s] the tolerance is
    exceeded."""

    def __init__(self):
        self.max_error = -np.inf
        self.where = (1, 0.0)
        self.ref_separation = 0.0
        self.first_exceeded: float | None = None

    def add(self, ts: np.ndarray, err: np.ndarray, e: np.ndarray, ref_sep: np.ndarray,
            upto: int, tolerance: float) -> None:
        """Samples at ``ts`` (N,) [s]: errors ``err`` (N, n), their max over rods ``e`` (N,),
        reference separations ``ref_sep`` (N,); the first ``upto`` are before the horizon."""
        over = np.flatnonzero(~(e <= tolerance))
        if over.size and self.first_exceeded is None:
            self.first_exceeded = float(ts[over[0]])
        if upto:
            ew = e[:upto]
            k = int(np.argmax(ew))
            if ew[k] > self.max_error:
                self.max_error = float(ew[k])
                self.where = (int(np.argmax(err[k])) + 1, float(ts[k]))
            self.ref_separation = max(self.ref_separation, float(np.max(ref_sep[:upto])))

    def summary(self) -> dict:
        """The ``within`` part of the report."""
        return {"max_phi_error": self.max_error, "where": self.where,
                "first_exceeded": self.first_exceeded, "phi_change": self.ref_separation}


class BeyondHorizon:
    """Beyond the predictability horizon, what stays meaningful: the largest max phi error
    divided by the gain [rad] and per-rod moments of phi [rad] of the log and the reference."""

    def __init__(self, n: int):
        self.deamplified = 0.0
        self.log = ColumnSummary(n)
        self.ref = ColumnSummary(n)

    def add(self, e: np.ndarray, gain: np.ndarray, phi_log: np.ndarray,
            phi_ref: np.ndarray) -> None:
        """Samples beyond the horizon: max phi error ``e`` (N,) [rad], ``gain`` (N,), phi of the
        log and the reference (N, n) [rad]."""
        if not e.size:
            return
        self.deamplified = max(self.deamplified, float(np.max(e / gain)))
        self.log.add(phi_log)
        self.ref.add(phi_ref)

    def summary(self, t_start: float, t_end: float) -> dict | None:
        """The ``beyond_horizon`` part of the report over [t_start, t_end] [s] (None: no
        sample)."""
        if not self.log.count:
            return None
        lg, rf = self.log, self.ref
        return {
            "t_start": t_start, "t_end": t_end,
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
