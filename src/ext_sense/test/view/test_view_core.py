"""The view's functional core: taxel grid, rates, pacing, raster, estimate pictures, layout."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ext_sense.view import channels as ch
from ext_sense.view.errors import ViewError
from ext_sense.view.estimate import (
    diagnostics_message,
    estimate_image,
    estimate_message,
    matching_truth,
)
from ext_sense.view.images import DEAD, ONSET, SATURATED, TRUTH
from ext_sense.view.layout import LAYOUT_PATH, layout_json
from ext_sense.view.pacing import DisplayPacer
from ext_sense.view.raster import raster_image
from ext_sense.view.taxels import ElectrodeActivity, TaxelActivity, biotac_grid, nuskin_grid
from ext_sense.view.traces import PacTrace, rates_message
from ext_sense_runtime.records import Estimate, GroundTruth

S = 1_000_000_000


def test_rates_follow_the_events_and_bad_ids_are_counted() -> None:
    act = TaxelActivity(tau_s=0.1)
    act.update(0)
    for k in range(100):  # 1 s: taxel 1 at 4 kHz, taxel 80 at 100 Hz
        act.add(np.r_[np.ones(40, int), [80] * (k % 1 == 0)])
        act.add([0, 81])
        act.update((k + 1) * S // 100)
    assert act.rate_hz[0] == pytest.approx(4000, rel=0.01)
    assert act.rate_hz[79] == pytest.approx(100, rel=0.01)
    assert act.rejected == 200
    assert act.finger_rates() == pytest.approx([4000, 100], rel=0.01)
    assert act.saturated()[0]
    assert not act.saturated()[79]


def test_a_silent_taxel_is_dead_only_while_its_finger_fires() -> None:
    act = TaxelActivity(dead_after_s=2.0)
    act.update(0)
    for k in range(1, 40):  # taxels 2..40 fire every 0.1 s; taxel 1 and the right finger never
        act.add(np.arange(2, 41))
        act.update(k * S // 10)
    dead = act.dead(39 * S // 10)
    assert dead[0]
    assert not dead[1:40].any()
    assert not dead[40:].any()  # the right finger is idle, not dead


def test_grid_places_taxels_on_their_lattice_and_marks_faults() -> None:
    rate = np.zeros(80)
    rate[0] = 4000.0  # left finger, row 0, column 0
    dead, sat = np.zeros(80, bool), np.zeros(80, bool)
    dead[44] = True  # taxel 45: right finger, row 0, column 4
    sat[0] = True
    img = nuskin_grid(rate, dead, sat, cell=24)
    margin = 8
    assert img.shape == (8 * 24 + 16, 10 * 24 + 24 + 16, 3)
    assert tuple(img[margin, margin + 5]) == SATURATED  # its frame
    assert tuple(img[margin + 12, margin + 12]) == (253, 231, 37)  # top of the colour map
    right_col4 = margin + 5 * 24 + 24 + 4 * 24
    assert tuple(img[margin + 12, right_col4 + 12]) == DEAD  # the cross's centre
    with pytest.raises(ViewError, match="shape \\(80,\\)"):
        nuskin_grid(np.zeros(40), dead, sat)


def test_biotac_grid_marks_open_and_saturated_electrodes() -> None:
    act = ElectrodeActivity(baseline_frames=1)
    values = np.full(19, 2000.0)
    act.add(0, values)
    values = values.copy()
    values[0], values[1] = 0, 4095
    act.add(0, values)
    img = biotac_grid(act, cell=24)
    assert tuple(img[8 + 12, 8 + 12]) == DEAD
    assert tuple(img[8, 8 + 24 + 5]) == SATURATED
    with pytest.raises(ViewError, match="shape \\(19,\\)"):
        act.add(0, np.zeros(22))


def test_pacer_bounds_the_frame_rate_whatever_the_ticks() -> None:
    pacer = DisplayPacer(20.0)
    ticks = np.arange(0, 10 * S, S // 4000)  # asked 4000 times a second for 10 s
    sent = sum(pacer.ready(int(t)) for t in ticks)
    assert 200 <= sent <= 250  # 20/s, at most 1.25x
    with pytest.raises(ViewError, match="rate_hz"):
        DisplayPacer(0)


def test_pac_trace_keeps_the_last_second() -> None:
    trace = PacTrace(seconds=0.1, decimate=1)  # 220 samples
    for k in range(20):
        trace.add(3, np.full(22, k))
    msg = trace.message()
    assert msg["sensor_ids"] == [3]
    assert len(msg["pac_3"]) == 220
    assert msg["pac_3"][-1] == 19
    assert msg["pac_3"][0] == 10
    assert rates_message([1.0, 2.0])["total_events_per_s"] == 3.0


def test_raster_marks_the_onset_and_the_kind() -> None:
    data = np.zeros((80, 1200))
    img = raster_image(data, pre_onset_ns=50_000_000, sample_period_ns=250_000, provisional=True)
    onset_col = round(200 / 3)  # 200 samples before onset, 3 samples a column
    assert tuple(img[50, onset_col]) == ONSET
    assert tuple(img[0, 0]) == (230, 200, 40)  # provisional band
    assert img.shape[1] == 400
    with pytest.raises(ViewError, match="n_channels, n_samples"):
        raster_image(np.zeros(5), 0, 1)


def test_estimate_picture_and_numbers_show_estimate_and_truth() -> None:
    est = Estimate("tap_localization", 10 * S, tap_position_m=0.1, tap_position_std_m=0.01)
    truth = GroundTruth(4, 10 * S + 1000, tap_position_m=0.2, rod_length_m=0.4)
    assert matching_truth(est, [truth], tolerance_ns=1_000_000) == truth
    assert matching_truth(est, [truth], tolerance_ns=10) is None
    img = estimate_image(est, truth)
    truth_x = 20 + round(0.5 * 360)
    assert tuple(img[17, truth_x]) == TRUTH
    msg = estimate_message(est, truth)
    assert msg["error_cm"] == pytest.approx(10.0)
    assert msg["stability_probability"] is None
    json.dumps(msg, allow_nan=False)
    food = Estimate(
        "food_identification",
        0,
        class_index=1,
        class_names=("apple", "tofu"),
        class_probabilities=(0.2, 0.8),
        stability_probability=math.nan,
    )
    img = estimate_image(food, GroundTruth(1, 0, class_label="tofu"))
    assert img.shape[0] == 16 + 2 * 20 + 8


def test_diagnostics_summary_names_what_is_not_ok() -> None:
    msg = diagnostics_message({"a: link": (0, "ok"), "b: rate": (1, "slow"), "c: x": (2, "gone")})
    assert msg["worst"] == "ERROR"
    assert msg["statuses"] == 3
    assert msg["not_ok"] == ["b: rate: WARN slow", "c: x: ERROR gone"]


def test_shipped_layout_is_current_and_names_the_view_channels() -> None:
    assert LAYOUT_PATH.read_text() == layout_json(), "run: python -m ext_sense.view.layout"
    text = LAYOUT_PATH.read_text()
    for topic in (ch.TAXELS, ch.WINDOW, ch.ESTIMATE, ch.RATES, ch.PAC, ch.ESTIMATE_INFO):
        assert topic in text
    assert "/extsense/contact_estimate.tap_position_m" in text
