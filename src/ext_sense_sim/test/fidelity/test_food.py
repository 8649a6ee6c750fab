import numpy as np
import pytest

from ext_sense_sim.fidelity.captures import Capture
from ext_sense_sim.fidelity.food import SPAN_BINS, SPAN_S, food_trials


def _capture(name: str, bins: list[int], taxels: list[int], values: list[int], span: int):
    n = len(bins)
    return Capture(
        name,
        name.split("_zero_")[0],
        np.array(bins, np.int64),
        np.array(taxels, np.uint16),
        np.zeros(n, np.int8),
        np.array(values, np.uint16),
        span_bins=span,
        mark_bin=50,
    )


def test_only_the_span_after_the_motion_start_counts():
    inside = list(range(50, 50 + SPAN_BINS, 10))  # 23 events from the motion start on
    bins = [0, 10, 49, *inside, 50 + SPAN_BINS, 50 + SPAN_BINS + 5]
    taxels = [80, 80, 80, *([1, 2, 41] * 8)[: len(inside)], 80, 80]
    values = [1000, 1000, 1000, *range(100, 100 + len(inside)), 1000, 1000]
    t = food_trials([_capture("tofu_zero_1", bins, taxels, values, span=400)])
    assert t.labels == ["tofu"]
    assert t.stats["events"].tolist() == [23]
    assert t.stats["events_per_s"][0] == pytest.approx(23 / SPAN_S)
    assert t.stats["active_taxels"].tolist() == [3]
    assert t.stats["value_p50"][0] == pytest.approx(111)
    assert t.values.tolist() == list(range(100, 123))
    assert t.cut_short == []


def test_a_trial_ending_early_is_rated_over_what_it_covers():
    t = food_trials([_capture("apple_zero_2", [60, 70], [5, 6], [90, 110], span=150)])
    assert t.cut_short == ["apple_zero_2"]
    assert t.stats["events_per_s"][0] == pytest.approx(2 / 1.0)  # 100 bins after the start
