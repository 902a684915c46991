"""The chaos tracker of ``rod-sim compare``: a twin full-model run, started with phi perturbed by
:data:`TWIN_DELTA` and renormalised every window (Benettin), measures how much the dynamics
amplify a small perturbation up to each time (the gain G(t) >= 1, a running maximum, and the
largest finite-time Lyapunov exponent ln(G)/t), and finds the predictability horizon: once
perturbations have grown :data:`ONSET_GAIN`-fold (the onset), the log's error so far eps is
followed forward; the horizon is the first time eps * G(t) exceeds the tolerance, or the first
time the two reference runs separate by more than :data:`CONVERGED_FRACTION` of it.

Units: phi [rad], times [s], gain dimensionless, Lyapunov exponent [1/s].
"""
from __future__ import annotations

import math

import numpy as np

from rod_sim.core.models import FullModel

from .runs import Run

TWIN_DELTA = 1e-7
"""[rad] initial (and renormalised) phi separation of the twin run measuring the gain."""
ONSET_GAIN = 2.0
"""Chaos onset: the twin run's perturbation has grown this many times."""
CONVERGED_FRACTION = 1e-2
"""The reference counts as converged when its estimated phi error is below this fraction of
the tolerance (so it cannot move the verdict); beyond a separation of the two reference runs
this large the horizon is reached."""


def twin_start(model: FullModel, y0: np.ndarray) -> np.ndarray:
    """The twin run's initial state: ``y0`` with phi of rod k turned by +TWIN_DELTA (k odd)
    or -TWIN_DELTA (k even) [rad]."""
    n = model.n
    twin0 = np.array(y0, dtype=float)
    twin0[:n] += TWIN_DELTA * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    return twin0


class ChaosTracker:
    """The twin run (``integrator`` at ``rtol``, from ``y0`` with phi perturbed by +-TWIN_DELTA
    alternately), the gain so far and the horizon search; see the module docstring."""

    def __init__(self, model: FullModel, rtol: float, y0: np.ndarray,
                 integrator: str = "dop853-jit"):
        self.n = model.n
        self.twin = Run(model, rtol, twin_start(model, y0), integrator)
        self.log_gain = 0.0                 # ln of the twin's renormalisations so far
        self.gain = 1.0                     # running max of the amplification
        self.onset: float | None = None     # [s] time the gain reached ONSET_GAIN
        self.eps = 0.0                      # [rad] the log's largest error before the onset
        self.horizon: float | None = None   # [s] the predictability horizon
        self.horizon_cause: str | None = None   # "log_precision" or "reference_separation"

    def gains(self, y_twin: np.ndarray, phi_ref: np.ndarray) -> np.ndarray:
        """The gain (N,) at the samples whose twin states are ``y_twin`` (N, state size) and
        reference phi ``phi_ref`` (N, n) [rad] (running maximum, continued from the last
        window)."""
        sep = np.max(np.abs(y_twin[:, :self.n] - phi_ref), axis=1)
        with np.errstate(over="ignore"):     # beyond ~240 s of chaos the gain is inf: no
            gain = np.maximum.accumulate(np.maximum(np.exp(self.log_gain) * sep / TWIN_DELTA,
                                                    self.gain))     # numpy warnings for it
        self.gain = float(gain[-1])
        return gain

    def renormalise(self, y_ref: np.ndarray) -> None:
        """Scale the twin's separation from the reference state ``y_ref`` (state size,) back to
        TWIN_DELTA (Benettin) and book the growth."""
        n = self.n
        d = self.twin.y - y_ref
        sep = float(np.max(np.abs(d[:n])))
        if sep > 0 and math.isfinite(sep):
            self.log_gain += math.log(sep / TWIN_DELTA)
            self.twin.y = y_ref + d * (TWIN_DELTA / sep)

    def find_horizon(self, ts: np.ndarray, e: np.ndarray, gain: np.ndarray,
                     ref_sep: np.ndarray, tolerance: float) -> int:
        """Sample by sample (times ``ts`` [s], the log's max phi error ``e`` [rad], ``gain``,
        reference separation ``ref_sep`` [rad]): the onset, the log's precision before it and
        the horizon. Returns the index of the first sample beyond the horizon (0 when it was
        reached in an earlier window, ``ts.size`` when not yet)."""
        if self.horizon is not None:
            return 0
        limit = CONVERGED_FRACTION * tolerance
        for i in range(ts.size):
            if self.onset is None:
                self.eps = max(self.eps, float(e[i]))
                if gain[i] >= ONSET_GAIN:
                    self.onset = float(ts[i])
            if self.onset is not None:
                if self.eps * gain[i] > tolerance:
                    self.horizon, self.horizon_cause = float(ts[i]), "log_precision"
                elif ref_sep[i] > limit:
                    self.horizon, self.horizon_cause = float(ts[i]), "reference_separation"
            if self.horizon is not None:
                return i
        return ts.size

    def summary(self, t_span: float) -> dict:
        """The ``chaos`` part of the report over a log of ``t_span`` [s] (beyond-horizon
        comparisons added by the caller)."""
        return {
            "gain": self.gain,
            "lyapunov_exponent": (self.log_gain / t_span if t_span > 0 else None),
            "onset": self.onset,
            "log_precision_before_onset": self.eps if self.onset is not None else None,
            "horizon_cause": self.horizon_cause,
            "twin_perturbation": TWIN_DELTA,
            "twin_rhs_evaluations": self.twin.sim.stats.nfev,
            "beyond_horizon": None,
        }
