"""One filled-in sample of every ext_sense message, for round-trip tests."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Duration

from ext_sense_msgs.msg import (
    BioTacFrame,
    ContactEstimate,
    ContactGroundTruth,
    ContactWindow,
    TaxelEventBatch,
)


def samples() -> dict[str, object]:
    """Messages keyed by type name, with distinctive values in every field kind."""
    frame = BioTacFrame()
    frame.header.stamp.sec, frame.header.stamp.nanosec = 1_700_000_000, 123_456_789
    frame.header.frame_id = "biotac_left"
    frame.sensor_id, frame.sequence, frame.pac_sample_period_ns = 3, 65535, 454_545
    frame.pac = np.arange(22, dtype=np.uint16) * 100 + 7
    frame.electrodes = np.arange(19, dtype=np.uint16) + 4000
    frame.pdc, frame.tac, frame.tdc = 2048, 1, 4095
    frame.invalid_word_mask = (1 << 43) | 1
    frame.dropped_frames, frame.parity_errors, frame.error_replies = 5, 6, 7

    batch = TaxelEventBatch()
    batch.header.frame_id = "nuskin"
    batch.taxel = [1, 40, 41, 80]
    batch.polarity = [1, -1, 0, 1]
    batch.value = [0, 1023, 512, 7]
    batch.offset_ns = [0, 250_000, 999_999, 2**40]
    batch.flag = [1, 0, 0, 1]  # the receiver words' flag bits, as received
    batch.words_total, batch.resyncs, batch.skipped_bytes, batch.bad_taxel_words = 10, 2, 3, 1

    window = ContactWindow()
    window.task, window.sensor = "tap_localization", "nuskin"
    window.pre_onset_ns, window.post_onset_ns, window.sample_period_ns = (
        50_000_000,
        250_000_000,
        250_000,
    )
    window.shape = [2, 3]
    window.channels = [1, 80]
    window.data = [0.0, 1.0, -1.0, 2.5, -3.5, 1e6]
    window.truncated = True

    estimate = ContactEstimate()
    estimate.task, estimate.sensor, estimate.model_id = "food_identification", "nuskin", "m-1"
    estimate.provisional = True
    estimate.post_contact_used = Duration(sec=0, nanosec=100_000_000)
    estimate.compute_latency = Duration(sec=0, nanosec=1_500_000)
    estimate.tap_position_m = float("nan")
    estimate.tap_position_std_m = float("nan")
    estimate.class_index = 1
    estimate.class_label = "tofu"
    estimate.class_names = ["apple", "tofu"]
    estimate.class_probabilities = [0.25, 0.75]
    estimate.stability_probability = float("nan")

    truth = ContactGroundTruth()
    truth.task, truth.trial = "tap_localization", 42
    truth.tap_position_m, truth.rod_length_m = 0.123, 0.3
    truth.class_label = ""
    return {type(m).__name__: m for m in (frame, batch, window, estimate, truth)}


def assert_same(a: object, b: object) -> None:
    """Field-by-field equality that treats NaN == NaN and compares arrays by value."""
    for name in a.get_fields_and_field_types():
        va, vb = getattr(a, name), getattr(b, name)
        if hasattr(va, "get_fields_and_field_types"):
            assert_same(va, vb)
        elif isinstance(va, float):
            assert (np.isnan(va) and np.isnan(vb)) or va == vb, name
        else:
            assert np.array_equal(np.asarray(va), np.asarray(vb)), name
