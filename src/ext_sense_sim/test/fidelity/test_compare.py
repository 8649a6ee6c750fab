import numpy as np
import pytest

from ext_sense_sim.fidelity.compare import TAP_TARGETS, Target, summarise, two_sample_auc


def test_the_two_sample_test_cannot_tell_one_distribution_from_itself():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(40, 4)), rng.normal(size=(40, 4))
    assert 0.3 < two_sample_auc(a, b) < 0.7


def test_the_two_sample_test_tells_shifted_distributions_apart():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(40, 4))
    b = rng.normal(size=(60, 4)) + np.array([4.0, 0.0, 0.0, 0.0])  # one statistic moved 4 sd
    assert two_sample_auc(a, b) > 0.9


def test_the_two_sample_test_needs_two_rows_a_side():
    assert np.isnan(two_sample_auc(np.zeros((1, 3)), np.ones((5, 3))))


def test_targets_are_the_issue_tolerances():
    by_stat = {t.stat: t for t in TAP_TARGETS}
    events = by_stat["events"]
    assert events.holds(10_000, 7_000)
    assert events.holds(10_000, 14_000)
    assert not events.holds(10_000, 6_900)
    assert not events.holds(10_000, 14_100)
    assert events.measure(10_000, 5_000) == pytest.approx(0.5)
    first = by_stat["first_30ms"]
    assert first.holds(0.26, 0.32)
    assert not first.holds(0.26, 0.18)
    assert first.measure(0.26, 0.20) == pytest.approx(-0.06)
    assert by_stat["busiest_10"].holds(0.49, 0.58)
    assert not by_stat["last_100ms"].holds(0.12, 0.01)
    assert Target("x", "diff", -0.1, 0.1).allowed() == "+-0.1"
    assert events.allowed() == "x0.7-1.4"


def test_summaries_leave_nans_out():
    s = summarise({"a": np.array([1.0, 2.0, 3.0, np.nan]), "b": np.array([np.nan])})
    assert s["a"] == {"median": 2.0, "p25": 1.5, "p75": 2.5, "n": 3}
    assert s["b"]["n"] == 0
    assert np.isnan(s["b"]["median"])
