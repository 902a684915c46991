"""The verdict of rod-sim compare as data (rod_sim.compare.verdict): the enum and the
numbers decide, the sentences of the text report and of the JSON come from the same records."""
from __future__ import annotations

import math

import pytest

from rod_sim.compare.verdict import Cause, Judgement, Reason, Verdict, judge

CLEAN = dict(tolerance=1e-2, max_error=1e-4, horizon=None, within_max=1e-4,
             within_where=(3, 0.25), first_exceeded=None, gap_count=0, first_gap=None,
             converged=True, reference_error=1e-9, deamplified_beyond=None)


def test_a_clean_log_passes_and_with_a_horizon_is_inconclusive_beyond_it():
    assert judge(**CLEAN) == Judgement(Verdict.PASS)
    chaotic = judge(**{**CLEAN, "horizon": 2.5, "max_error": 3.0, "deamplified_beyond": 1e-3})
    assert chaotic.verdict is Verdict.PASS_THEN_INCONCLUSIVE and chaotic.passed
    assert chaotic.reasons == () and chaotic.sentences() == []


def test_every_cause_carries_its_numbers_in_order():
    j = judge(**{**CLEAN, "within_max": 0.05, "first_exceeded": 0.2, "gap_count": 4,
                 "first_gap": (0.5, 0.61), "converged": False, "reference_error": 3e-4,
                 "horizon": 1.5, "deamplified_beyond": 0.2})
    assert j.verdict is Verdict.FAIL and not j.passed
    assert [r.cause for r in j.reasons] == [Cause.TOLERANCE_EXCEEDED, Cause.STATE_GAPS,
                                            Cause.REFERENCE_NOT_CONVERGED,
                                            Cause.DEPARTS_BEYOND_HORIZON]
    tol, gaps, ref, beyond = j.reasons
    assert (tol.value, tol.limit, tol.rod, tol.t, tol.first_t, tol.horizon) == (
        0.05, 1e-2, 3, 0.25, 0.2, 1.5)
    assert gaps.value == 4 and gaps.interval == (0.5, 0.61)
    assert ref.value == 3e-4 and beyond.value == 0.2


def test_a_non_finite_log_is_one_reason_and_never_judged_beyond_the_horizon():
    j = judge(**{**CLEAN, "max_error": math.inf, "within_max": math.inf, "horizon": 1.0,
                 "deamplified_beyond": math.inf})
    assert [r.cause for r in j.reasons] == [Cause.NON_FINITE]
    assert j.sentences() == ["the log holds non-finite phi values"]


def test_sentences_are_formatted_from_the_numbers():
    assert Reason(Cause.TOLERANCE_EXCEEDED, 0.0123456, 0.01, 1.25, 2, 0.5, 0.375).text() == (
        "max |phi error| before the horizon t = 1.25 s 0.0123 rad (rod 2, t = 0.5 s) exceeds "
        "the tolerance 0.01 rad (first at t = 0.375 s)")
    assert Reason(Cause.STATE_GAPS, 3.0, interval=(0.5, 0.61)).text() == (
        "/rod_states has 3 gap(s) (first 0.5 s to 0.61 s): the missing samples were not checked")
    assert Reason(Cause.REFERENCE_NOT_CONVERGED, 0.0).text() == (
        "the reference is not converged (estimated phi error 0 rad)")
    assert Reason(Cause.DEPARTS_BEYOND_HORIZON, 0.25).text().endswith(
        "(max |phi error| / gain 0.25 rad > tolerance)")


@pytest.mark.parametrize("tolerance, causes", [(1e-2, [Cause.REFERENCE_NOT_CONVERGED]),
                                               (1e-7, [Cause.TOLERANCE_EXCEEDED,
                                                       Cause.REFERENCE_NOT_CONVERGED])])
def test_the_json_and_the_report_come_from_the_same_judgement(tmp_path, tolerance, causes):
    """A log of a chain at rest, 1e-6 rad off, compared without the check run (so the
    reference counts as not converged): the JSON's verdict, pass and reasons are the
    judgement's enum and sentences, and the numbers are the comparison's."""
    from test_compare_chaos import REST, synthetic_log

    from rod_sim.core.scene import Scene
    from rod_sim.io.log_source import read_log
    from rod_sim.compare.command import verdict_line
    from rod_sim.compare.comparison import compare_log

    log = synthetic_log(tmp_path / "rest.mcap", 0.05)
    with read_log(log) as source:
        report = compare_log(source, Scene.from_dict(REST), tolerance, check_rtol=None)
    j = report.judgement
    assert [r.cause for r in j.reasons] == causes and j.verdict is Verdict.FAIL
    out = report.as_json()
    assert out["verdict"] == "FAIL" and out["pass"] is False
    assert out["reasons"] == [r.text() for r in j.reasons] == report.reasons()
    assert verdict_line(report) == "FAIL: " + "; ".join(out["reasons"])
    if Cause.TOLERANCE_EXCEEDED in causes:
        r = j.reasons[0]
        assert r.value == pytest.approx(1e-6, rel=1e-6) == out["max_abs_error"]["phi"]
        assert r.first_t == 0.0 == out["tolerance_first_exceeded_at"] and r.limit == 1e-7
