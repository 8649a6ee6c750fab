"""The message-level core of the window and inference nodes, without ROS."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[4] / "test"))  # the repo's test/
from synthetic import MS, T0, tap_stream

from ext_sense.nodes.scoreboard import Scoreboard
from ext_sense_bags import biotac_frame, make_message, taxel_event_batch
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.messages import window_fields, window_from_msg
from ext_sense_perception.online.model_card import ModelCard
from ext_sense_perception.online.model_input import Geometry
from ext_sense_perception.online.predictor import ModelBundle
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.profiles import profile_for
from ext_sense_runtime.records import Estimate, GroundTruth


def _feed(stage, batches):
    out = []
    for b in batches:
        out += stage.on_events(
            taxel_event_batch(b.stamp_ns, b.taxel, b.polarity, b.value, b.offset_ns)
        )
    return out


def test_windows_provisional_then_final_per_tap():
    config = WindowConfig.for_task("tap_localization", "nuskin")
    stage = WindowStage(config)
    windows = _feed(stage, tap_stream([100.0, 900.0], 1400.0, noise_per_s=0.0))
    windows += stage.advance(stage.last_data_ns + 300 * MS)
    finals = [w for w in windows if not w.provisional]
    assert len(finals) == 2
    assert [round((w.onset_ns - T0) / MS) for w in finals] == [100, 900]
    provisional = [w.post_onset_ns for w in windows if w.provisional]
    assert provisional == list(config.anytime_post_ns) * 2
    assert finals[0].data.shape == (80, 50 + 250)  # 1 ms bins


def test_window_closes_by_advance_without_further_events():
    stage = WindowStage(WindowConfig.for_task("tap_localization", "nuskin"))
    got = _feed(stage, tap_stream([10.0], 60.0, noise_per_s=0.0))
    assert not [w for w in got if not w.provisional]
    later = stage.advance(stage.last_data_ns + 300 * MS)
    assert len([w for w in later if not w.provisional]) == 1


def test_malformed_batch_counted_and_dropped():
    stage = WindowStage(WindowConfig.for_task("tap_localization", "nuskin"))
    bad = make_message(
        "ext_sense_msgs/msg/TaxelEventBatch",
        taxel=np.array([1, 2]),
        polarity=np.array([1]),
        value=np.array([1, 2]),
        offset_ns=np.array([0, 1]),
    )
    assert stage.on_events(bad) == []
    assert stage.counters.bad_messages == 1


def test_biotac_frames_of_two_sensors_joined_by_sequence():
    config = WindowConfig.for_task("tap_localization", "biotac")
    stage = WindowStage(config, sensor_ids=(0, 1))
    for seq in range(3):
        for sid in (1, 0):
            stage.on_frame(
                biotac_frame(
                    T0 + seq * 10 * MS,
                    np.full(22, 2000),
                    np.zeros(19),
                    0,
                    0,
                    0,
                    sensor_id=sid,
                    sequence=seq,
                )
            )
    stage.on_frame(biotac_frame(T0, np.zeros(22), np.zeros(19), 0, 0, 0, sensor_id=4))
    c = stage.counters
    assert c.frames == 7
    assert c.frames_wrong_sensor == 1
    assert stage.last_data_ns == T0 + 2 * 10 * MS + 22 * 454_545


def test_window_message_round_trip_and_provisional_flag():
    config = WindowConfig.for_task("tap_localization", "nuskin")
    stage = WindowStage(config)
    windows = _feed(stage, tap_stream([100.0], 400.0, noise_per_s=0.0))
    for win in windows:
        f = window_fields(win)
        msg = make_message(
            "ext_sense_msgs/msg/ContactWindow",
            header=make_message(
                "std_msgs/msg/Header",
                stamp=make_message(
                    "builtin_interfaces/msg/Time",
                    sec=f["stamp_ns"] // 10**9,
                    nanosec=f["stamp_ns"] % 10**9,
                ),
            ),
            **{k: v for k, v in f.items() if k != "stamp_ns"},
        )
        back = window_from_msg(msg)
        assert back.onset_ns == win.onset_ns
        assert back.provisional == win.provisional
        np.testing.assert_array_equal(back.data, win.data)


def test_window_from_msg_rejects_bad_shape():
    msg = make_message(
        "ext_sense_msgs/msg/ContactWindow",
        shape=np.array([80, 10]),
        channels=np.arange(80),
        data=np.zeros(799),
    )
    with pytest.raises(PerceptionError, match="shape"):
        window_from_msg(msg)


class _Pipeline:
    """Stand-in for a fitted pipeline: position = events in the window / 1e6 m, or ``proba``."""

    classes_ = np.array(["stable", "unstable"])

    def __init__(self, position=None, proba=None):
        self.position, self.proba = position, proba

    def predict(self, x):
        if self.position is not None:
            return np.full(len(x), self.position)
        return np.abs(x).sum(axis=1) / 1e6

    def predict_proba(self, x):
        return np.tile(np.asarray(self.proba, dtype=np.float64), (len(x), 1))


def _bundle(runner, task="tap_localization", class_names=()):
    card = ModelCard(
        task=task,
        sensor="nuskin",
        profile=profile_for(task),
        window=Geometry(80, 300, MS, 50 * MS),
        features="baseline",
        feature_params={},
        model="counting",
        best_params={},
        rate_hz=4000.0,
        class_names=class_names,
        metrics={"residual_std_m": 0.01},
        n_train=0,
        data="",
        data_hash="",
        id="m1",
    )
    return ModelBundle(card, "sklearn", runner)


def test_estimate_fields_and_nan_rejection():
    stage = WindowStage(WindowConfig.for_task("tap_localization", "nuskin"))
    win = next(w for w in _feed(stage, tap_stream([100.0], 400.0)) if not w.provisional)
    model = _bundle(_Pipeline())
    est = model.predict(win)
    assert est.tap_position_m == pytest.approx(float(np.abs(win.data).sum()) / 1e6)
    assert est.class_index == -1
    assert est.class_names == ()
    assert math.isnan(est.stability_probability)
    nan_win = win._replace(data=np.full_like(win.data, np.nan))
    with pytest.raises(PerceptionError, match="NaN"):
        model.predict(nan_win)
    with pytest.raises(PerceptionError, match="returned position nan"):
        _bundle(_Pipeline(position=float("nan"))).predict(win)
    classifier = _bundle(
        _Pipeline(proba=[0.5, float("nan")]), "handover_stability", ("stable", "unstable")
    )
    with pytest.raises(PerceptionError, match="NaN or inf class"):
        classifier.predict(win)


def test_scoreboard_matches_nearest_trial_and_summarises():
    board = Scoreboard("tap_localization")
    board.add_truth(GroundTruth(trial=0, onset_ns=T0, tap_position_m=0.10))
    board.add_truth(GroundTruth(trial=1, onset_ns=T0 + 1000 * MS, tap_position_m=0.20))
    est = Estimate(
        task="tap_localization",
        onset_ns=T0 + 1001 * MS,
        provisional=False,
        tap_position_m=0.21,
        tap_position_std_m=0.01,
        class_label="",
        stability_probability=float("nan"),
        compute_latency_ns=3 * MS,
        post_contact_used_ns=250 * MS,
    )
    (line,) = board.add_estimate(est)
    assert "trial 1" in line
    assert "error  1.00 cm" in line
    assert board.add_estimate(est._replace(provisional=True)) == []
    board.add_estimate(est._replace(onset_ns=T0 + 2 * MS, tap_position_m=0.13))
    assert board.summary() == "summary: taps=2 mae_cm=2.00 compute_p50_ms=3.00 compute_p99_ms=3.00"
    # an estimate far from any trial waits, and counts as unmatched at the end
    board.add_estimate(est._replace(onset_ns=T0 + 9000 * MS))
    board.close()
    assert board.unmatched_estimates == 1


def test_scoreboard_classification_accuracy():
    board = Scoreboard("handover_stability")
    board.add_truth(GroundTruth(trial=0, onset_ns=T0, class_label="stable"))
    board.add_truth(GroundTruth(trial=1, onset_ns=T0 + 2000 * MS, class_label="unstable"))
    e = Estimate(
        task="handover_stability",
        onset_ns=T0,
        provisional=False,
        tap_position_m=float("nan"),
        tap_position_std_m=float("nan"),
        class_label="",
        stability_probability=0.9,
        compute_latency_ns=MS,
        post_contact_used_ns=250 * MS,
    )
    board.add_estimate(e)
    board.add_estimate(e._replace(onset_ns=T0 + 2000 * MS, stability_probability=0.8))
    assert board.summary().startswith("summary: trials=2 accuracy=0.500 ")


def test_scoreboard_lists_a_degraded_final_estimate_and_does_not_score_it():
    board = Scoreboard("tap_localization")
    board.add_truth(GroundTruth(trial=0, onset_ns=T0, tap_position_m=0.10))
    board.add_truth(GroundTruth(trial=1, onset_ns=T0 + 1000 * MS, tap_position_m=0.20))
    est = Estimate(
        task="tap_localization",
        onset_ns=T0,
        tap_position_m=0.22,
        compute_latency_ns=3 * MS,
        degraded=True,
        degraded_reason="stall: no input on /extsense/nuskin/events for 812 ms inside the window",
    )
    (line,) = board.add_estimate(est)
    assert line == (
        "trial   0: DEGRADED estimate not scored (stall: no input on /extsense/nuskin/events "
        "for 812 ms inside the window)"
    )
    board.add_estimate(est._replace(onset_ns=T0 + 1000 * MS, degraded=False, degraded_reason=""))
    assert board.summary() == "summary: taps=1 mae_cm=2.00 compute_p50_ms=3.00 compute_p99_ms=3.00"
    assert [e.onset_ns for e in board.degraded] == [T0]


def test_an_empty_batch_stamped_past_a_window_end_closes_it():
    config = WindowConfig.for_task("tap_localization", "nuskin")
    stage = WindowStage(config)
    batches = tap_stream([10.0], 60.0, noise_per_s=0.0)
    got = _feed(stage, batches)
    onset = stage.windower.pending_onsets[0]
    done = {w.post_onset_ns for w in got}
    assert done == {25 * MS}  # the batches (empty ones too) reached onset + 49 ms
    # an empty batch stamped past the final window's end: its stamp is stream time
    late = taxel_event_batch(onset + 260 * MS, [], [], [], [])
    closed = stage.on_events(late)
    assert [w.post_onset_ns for w in closed] == [50 * MS, 100 * MS, 150 * MS, 250 * MS]
    assert not closed[-1].provisional
    assert not closed[-1].truncated
    assert not stage.windower.pending_onsets
