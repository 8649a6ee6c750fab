"""The shared records: EventBlock's constructors and joins, GroundTruth.label, message readers."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from ext_sense_runtime.records import (
    Estimate,
    EventBlock,
    GroundTruth,
    estimate_of,
    truth_of,
)
from ext_sense_runtime.stamps import MS, S


def _block(t_ns, taxel=None) -> EventBlock:
    n = len(t_ns)
    return EventBlock.of(
        t_ns,
        np.arange(1, n + 1) if taxel is None else taxel,
        np.where(np.arange(n) % 2 == 0, 1, -1),
        np.arange(100, 100 + n),
    )


def _stamp(ns: int) -> SimpleNamespace:
    return SimpleNamespace(sec=ns // S, nanosec=ns % S)


def test_of_casts_to_the_record_dtypes_and_defaults_polarity_and_value():
    block = EventBlock.of([3, 1, 2], [80, 1, 40])
    assert [a.dtype for a in block] == [np.int64, np.uint16, np.int8, np.uint16]
    assert block.size == 3
    assert block.taxel.tolist() == [80, 1, 40]
    assert block.polarity.tolist() == [0, 0, 0]
    assert block.value.tolist() == [0, 0, 0]


def test_of_rejects_float_times():
    with pytest.raises(ValueError, match="'t_ns' parameter must be integer nanoseconds"):
        EventBlock.of(np.array([0.5, 1.0]), [1, 2])


@pytest.mark.parametrize(
    ("t_ns", "taxel", "polarity", "value"),
    [
        ([1, 2], [1], None, None),  # taxel too short
        ([1, 2], [1, 2], [1], None),  # polarity too short
        ([1, 2], [1, 2], None, [5, 6, 7]),  # value too long
        ([[1, 2]], [[1, 2]], None, None),  # not 1-D
        (5, [1], None, None),  # a scalar time
    ],
)
def test_of_rejects_arrays_of_other_shapes(t_ns, taxel, polarity, value):
    with pytest.raises(ValueError, match="must be 1-D of one length"):
        EventBlock.of(t_ns, taxel, polarity, value)


def test_empty_and_concat():
    empty = EventBlock.empty()
    assert empty.size == 0
    assert [a.dtype for a in empty] == [np.int64, np.uint16, np.int8, np.uint16]
    assert EventBlock.concat([]).size == 0
    a, b = _block([10, 20]), _block([5])
    both = EventBlock.concat([a, empty, b])
    assert both.size == 3
    assert both.t_ns.tolist() == [10, 20, 5]
    assert both.value.tolist() == [100, 101, 100]
    assert [x.dtype for x in both] == [np.int64, np.uint16, np.int8, np.uint16]


def test_select_with_a_mask_or_indices():
    block = _block([10, 20, 30, 40])
    picked = block.select(block.t_ns >= 25)
    assert isinstance(picked, EventBlock)
    assert picked.t_ns.tolist() == [30, 40]
    assert picked.taxel.tolist() == [3, 4]
    by_index = block.select(np.array([3, 0]))
    assert by_index.t_ns.tolist() == [40, 10]
    assert by_index.polarity.tolist() == [-1, 1]
    assert block.select(np.zeros(4, bool)).size == 0


def test_sorted_by_time_is_stable_and_keeps_sorted_blocks():
    block = _block([30, 10, 30, 20], taxel=[1, 2, 3, 4])
    ordered = block.sorted_by_time()
    assert ordered.t_ns.tolist() == [10, 20, 30, 30]
    assert ordered.taxel.tolist() == [2, 4, 1, 3]  # the two events at 30 keep their order
    assert ordered.value.tolist() == [101, 103, 100, 102]
    already = _block([1, 1, 2])
    assert already.sorted_by_time() is already
    assert EventBlock.empty().sorted_by_time().size == 0


def test_ground_truth_label_is_the_position_when_there_is_one():
    tap = GroundTruth(0, 5 * S, "tap_localization", tap_position_m=0.12, rod_length_m=0.3)
    assert tap.label == 0.12
    grasp = GroundTruth(1, 6 * S, "handover_stability", class_label="stable")
    assert grasp.label == "stable"
    assert math.isnan(grasp.tap_position_m)
    assert math.isnan(grasp.rod_length_m)
    assert GroundTruth(2, 0).label == ""


def test_estimate_of_reads_every_field_of_a_message():
    onset = 1_700_000_000 * S + 123_456_789
    msg = SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(onset)),
        task="food_identification",
        sensor="nuskin",
        model_id="food-1",
        provisional=1,
        post_contact_used=_stamp(1 * S + 250 * MS),
        compute_latency=_stamp(3 * MS + 7),
        tap_position_m=np.float32(0.5),
        tap_position_std_m=float("nan"),
        class_index=np.int32(1),
        class_label="apple",
        class_names=["tofu", "apple"],
        class_probabilities=np.array([0.25, 0.75], np.float32),
        stability_probability=float("nan"),
    )
    est = estimate_of(msg)
    assert isinstance(est, Estimate)
    assert est.onset_ns == onset
    assert est.post_contact_used_ns == 1 * S + 250 * MS
    assert est.compute_latency_ns == 3 * MS + 7
    assert est.provisional is True
    assert est.class_index == 1
    assert est.class_names == ("tofu", "apple")
    assert est.class_probabilities == (0.25, 0.75)
    assert type(est.tap_position_m) is float
    assert (est.task, est.sensor, est.model_id, est.class_label) == (
        "food_identification",
        "nuskin",
        "food-1",
        "apple",
    )
    assert math.isnan(est.stability_probability)


def test_truth_of_reads_a_ground_truth_message():
    onset = 1_700_000_001 * S + 5
    msg = SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(onset)),
        trial=np.int32(7),
        task="tap_localization",
        tap_position_m=0.2,
        class_label="",
        rod_length_m=0.3,
    )
    assert truth_of(msg) == GroundTruth(7, onset, "tap_localization", 0.2, "", 0.3)
    assert truth_of(msg).label == 0.2
    assert type(truth_of(msg).trial) is int


def test_event_block_concat_and_empty():
    e = EventBlock.empty()
    assert e.size == 0
    assert EventBlock.concat([]).size == 0
    one = EventBlock(
        np.array([5], np.int64),
        np.array([3], np.uint16),
        np.array([1], np.int8),
        np.array([9], np.uint16),
    )
    both = EventBlock.concat([one, e, one])
    assert both.size == 2
    assert both.taxel.dtype == np.uint16
    assert both.t_ns.tolist() == [5, 5]
