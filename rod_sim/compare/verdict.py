"""The verdict of ``rod-sim compare`` as data: :class:`Verdict` (PASS, PASS then INCONCLUSIVE,
FAIL) and the :class:`Reason` records that make a FAIL, each a :class:`Cause` with the numbers
it was decided on. :func:`judge` decides from the comparison's figures; the sentences of the
text report and of the JSON ``reasons`` are formatted from the records (:meth:`Reason.text`),
so both say the same.

Units: errors, separations and the tolerance [rad], times [s].
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass


class Verdict(enum.Enum):
    """PASS: the whole log within the tolerance (no horizon); PASS_THEN_INCONCLUSIVE: within it
    up to the predictability horizon, chaotic beyond; FAIL: some :class:`Reason`."""

    PASS = "PASS"
    PASS_THEN_INCONCLUSIVE = "PASS_THEN_INCONCLUSIVE"
    FAIL = "FAIL"


class Cause(enum.Enum):
    """Why a log fails, in the order the reasons are listed."""

    NON_FINITE = "non_finite"                   # the log holds non-finite phi
    TOLERANCE_EXCEEDED = "tolerance_exceeded"   # max |phi error| (before the horizon) > tol
    STATE_GAPS = "state_gaps"                   # /rod_states samples are missing
    REFERENCE_NOT_CONVERGED = "reference_not_converged"   # the two re-runs differ too much
    DEPARTS_BEYOND_HORIZON = "departs_beyond_horizon"     # max |phi error| / gain > tol
    SPACECRAFT_EXCEEDED = "spacecraft_exceeded"   # a chain's hinge or the base's error > tol


@dataclass(frozen=True)
class Reason:
    """One cause of a FAIL and its numbers: ``value`` is what was judged (phi error [rad] for
    TOLERANCE_EXCEEDED, the number of gaps for STATE_GAPS, the reference's estimated phi error
    [rad] for REFERENCE_NOT_CONVERGED, the de-amplified phi error [rad] for
    DEPARTS_BEYOND_HORIZON; nan for NON_FINITE), ``limit`` the tolerance [rad]; ``horizon`` [s]
    (None: no horizon), ``rod`` and ``t`` [s] where the error is largest, ``first_t`` [s] the
    first sample over the tolerance, ``interval`` the first gap (from, to) [s]."""

    cause: Cause
    value: float = math.nan
    limit: float = math.nan
    horizon: float | None = None
    rod: int | None = None
    t: float | None = None
    first_t: float | None = None
    interval: tuple[float, float] | None = None
    detail: str | None = None
    """SPACECRAFT_EXCEEDED: the sentence of :mod:`rod_sim.compare.spacecraft`."""

    def text(self) -> str:
        """The reason as one sentence (the text report's FAIL line and JSON ``reasons``)."""
        upto = "" if self.horizon is None else f" before the horizon t = {self.horizon:.6g} s"
        if self.cause is Cause.NON_FINITE:
            return "the log holds non-finite phi values"
        if self.cause is Cause.TOLERANCE_EXCEEDED:
            return (f"max |phi error|{upto} {self.value:.3g} rad (rod {self.rod}, t = "
                    f"{self.t:.6g} s) exceeds the tolerance {self.limit:g} rad (first at t = "
                    f"{self.first_t:.6g} s)")
        if self.cause is Cause.STATE_GAPS:
            a, b = self.interval
            return (f"/rod_states has {int(self.value)} gap(s) (first {a:.6g} s to {b:.6g} s): "
                    "the missing samples were not checked")
        if self.cause is Cause.SPACECRAFT_EXCEEDED:
            return str(self.detail)
        if self.cause is Cause.REFERENCE_NOT_CONVERGED:
            return (f"the reference is not converged{upto} (estimated phi error "
                    f"{self.value:.2g} rad)")
        return (f"beyond the horizon the log departs faster than the dynamics amplify "
                f"perturbations (max |phi error| / gain {self.value:.3g} rad > tolerance)")


@dataclass(frozen=True)
class Judgement:
    """The verdict and the reasons of a FAIL (none for PASS and PASS_THEN_INCONCLUSIVE)."""

    verdict: Verdict
    reasons: tuple[Reason, ...] = ()

    @property
    def passed(self) -> bool:
        """True for PASS and PASS_THEN_INCONCLUSIVE (exit status 0)."""
        return self.verdict is not Verdict.FAIL

    def sentences(self) -> list[str]:
        return [r.text() for r in self.reasons]


def judge(*, tolerance: float, max_error: float, horizon: float | None,
          within_max: float, within_where: tuple[int, float], first_exceeded: float | None,
          gap_count: int, first_gap: tuple[float, float] | None, converged: bool,
          reference_error: float, deamplified_beyond: float | None,
          spacecraft: tuple[str, ...] = ()) -> Judgement:
    """The verdict of a comparison at ``tolerance`` [rad] from: the largest phi error over the
    whole log ``max_error`` (non-finite: the log is), the ``horizon`` [s] (None: none), the
    largest error before it ``within_max`` at ``within_where`` = (rod, t [s]), the first time
    the tolerance is exceeded, the number of state gaps and the first one (s, s), whether the
    reference ``converged`` and its estimated error before the horizon ``reference_error``,
    and beyond the horizon the largest error divided by the gain (None: no sample there);
    ``spacecraft``: the sentences of the chains and the base over their tolerances."""
    finite = math.isfinite(max_error)
    reasons = []
    if not finite:
        reasons.append(Reason(Cause.NON_FINITE, limit=tolerance, horizon=horizon))
    elif within_max > tolerance:
        rod, t = within_where
        reasons.append(Reason(Cause.TOLERANCE_EXCEEDED, within_max, tolerance, horizon, rod, t,
                              first_exceeded))
    if gap_count:
        reasons.append(Reason(Cause.STATE_GAPS, float(gap_count), tolerance, horizon,
                              interval=first_gap))
    if not converged:
        reasons.append(Reason(Cause.REFERENCE_NOT_CONVERGED, reference_error, tolerance,
                              horizon))
    if deamplified_beyond is not None and deamplified_beyond > tolerance and finite:
        reasons.append(Reason(Cause.DEPARTS_BEYOND_HORIZON, deamplified_beyond, tolerance,
                              horizon))
    reasons.extend(Reason(Cause.SPACECRAFT_EXCEEDED, limit=tolerance, horizon=horizon,
                          detail=text) for text in spacecraft)
    if reasons:
        return Judgement(Verdict.FAIL, tuple(reasons))
    return Judgement(Verdict.PASS if horizon is None else Verdict.PASS_THEN_INCONCLUSIVE)
