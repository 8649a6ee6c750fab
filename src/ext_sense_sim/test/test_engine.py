import numpy as np
import pytest
import yaml

from ext_sense_sim.engine import Simulator
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import load_scene, scene_from_dict, shipped_scenes
from ext_sense_sim.streaming import stream

TAP = {
    "task": "tap_localization",
    "sensor": "nuskin",
    "object": {
        "kind": "rod",
        "material": "acrylic",
        "length_m": 0.3,
        "section": {"shape": "circle", "diameter_m": 0.01},
    },
    "grasp": {"held_length_m": 0.03},
    "timing": {"rate_hz": 16000, "trial_s": 0.1},
    "batch_size": 4,
}


def scene(effects, **extra):
    return scene_from_dict({**TAP, **extra, "effects": effects}, "test_scene")


def test_only_listed_effects_are_built_and_run():
    full = Simulator(
        scene(
            [
                "contact_impulse",
                "beam_modes",
                "grasp_transfer",
                "sensor_noise",
                "nuskin_transduction",
                "spurious_events",
            ]
        )
    )
    lean = Simulator(
        scene(["contact_impulse", "beam_modes", "grasp_transfer", "nuskin_transduction"])
    )
    for sim in (full, lean):
        for _ in sim.batches(8, 1):
            pass
    assert set(lean.stats) == {
        "contact_impulse",
        "beam_modes",
        "grasp_transfer",
        "nuskin_transduction",
    }
    assert full.stats["sensor_noise"].calls == 2
    assert full.stats["sensor_noise"].seconds > 0
    assert "sensor_noise" not in lean.stats
    assert "spurious_events" not in lean.stats


def test_missing_effect_is_named():
    with pytest.raises(SceneError, match="needs effect 'nuskin_transduction'"):
        Simulator(scene(["contact_impulse", "beam_modes", "grasp_transfer"]))
    with pytest.raises(
        SceneError, match=r"'beam_modes' needs the signal 'contact'.*'contact_impulse"
    ):
        Simulator(scene(["beam_modes", "grasp_transfer", "nuskin_transduction"]))
    with pytest.raises(SceneError, match="unknown effect 'magic'"):
        Simulator(scene(["magic"]))
    with pytest.raises(SceneError, match="unknown parameter"):
        Simulator(
            scene(
                [
                    {"contact_impulse": {"forse_n": 1}},
                    "beam_modes",
                    "grasp_transfer",
                    "nuskin_transduction",
                ]
            )
        )


def test_bad_scene_fields_are_named(tmp_path):
    with pytest.raises(SceneError, match="'sensor' must be one of"):
        scene_from_dict({**TAP, "sensor": "eye", "effects": ["x"]}, "s")
    with pytest.raises(SceneError, match="held_length_m"):
        scene_from_dict({**TAP, "grasp": {"held_length_m": 0.5}, "effects": ["x"]}, "s")
    with pytest.raises(SceneError, match="neither a shipped scene"):
        load_scene(tmp_path / "missing.yaml")


def test_shipped_scenes_cover_tasks_sensors_and_rods():
    scenes = [load_scene(name) for name in shipped_scenes()]
    kinds = {(s.task.label, s.sensor.label) for s in scenes}
    for task in ("tap_localization", "handover_stability", "food_identification"):
        for sensor in ("nuskin", "biotac"):
            if task == "handover_stability" and sensor == "biotac":
                assert (task, sensor) in kinds
            assert (task, "nuskin") in kinds
    assert {("tap_localization", "biotac"), ("food_identification", "biotac")} <= kinds
    for sensor in ("nuskin", "biotac"):  # the paper's three rods, with either sensor
        rods = {
            s.geometry.length_m
            for s in scenes
            if s.task.label == "tap_localization" and s.sensor.label == sensor
        }
        assert {0.2, 0.3, 0.5} <= rods, sensor
    for s in scenes:
        Simulator(s)  # every shipped chain is complete


def test_same_seed_same_events():
    s = scene(
        ["contact_impulse", "beam_modes", "grasp_transfer", "sensor_noise", "nuskin_transduction"]
    )
    a = next(sig["events"] for _, sig in Simulator(s).batches(4, 3))
    b = next(sig["events"] for _, sig in Simulator(s).batches(4, 3))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_tap_events_follow_the_onset():
    s = scene(["contact_impulse", "beam_modes", "grasp_transfer", "nuskin_transduction"])
    _, sig = next(Simulator(s).batches(4, 0))
    (trial, ev), onset = sig["events"], sig["labels"].onset_ns
    assert ev.t_ns.size > 0
    assert np.all(ev.t_ns >= onset[trial])  # no noise listed: nothing before the tap
    assert set(np.unique(ev.polarity)) <= {-1, 1}
    assert ev.taxel.min() >= 1
    assert ev.taxel.max() <= 80
    assert ev.value.max() <= 1023


STREAMED = ["contact_impulse", "beam_modes", "grasp_transfer", "nuskin_transduction", "nuskin_wire"]
START_NS = 10**18


def _stream_on_fake_clock(now: list[int], trials: int):
    """``stream`` of a tap scene, 0.2 s apart, on a clock that moves only when it sleeps (or
    when the caller moves ``now[0]``): its stats, its writes as ``(time, bytes)`` and truths."""
    written, truths = [], []

    def sleep(s):
        now[0] += max(int(s * 1e9), 1000)

    stats = stream(
        scene(STREAMED),
        lambda data: written.append((now[0], data)),
        seed=1,
        trials=trials,
        period_s=0.2,
        on_onset=truths.append,
        clock=lambda: now[0],
        sleep=sleep,
    )
    return stats, written, truths


def test_streaming_stamps_onset_on_a_fake_clock():
    stats, written, truths = _stream_on_fake_clock([START_NS], trials=2)
    assert stats.trials == 2
    assert len(truths) == 2
    assert stats.bytes == sum(len(w) for _, w in written)
    assert stats.bytes % 4 == 0
    for k, gt in enumerate(truths):
        assert 0.03 < gt.tap_position_m < 0.3
        onset_wall = gt.onset_ns - START_NS - k * 200_000_000
        assert 0.045e9 <= onset_wall <= 0.055e9 + 0.002e9  # onset + 1 ms receiver latency


def test_a_trial_simulated_late_starts_when_ready_at_its_own_pace(monkeypatch):
    """A slow simulator delays the tap; it never squeezes the tap's bytes into one burst."""
    import ext_sense_sim.streaming as streaming

    now = [START_NS]

    def slow_plans(scene, seed):
        for plan in plan_trials(scene, seed):
            if plan.trial == 1:
                now[0] += 700_000_000  # drawn after trial 0's 0.1 s: due at 0.2 s, ready at 0.8 s
            yield plan

    plan_trials = streaming.plan_trials
    monkeypatch.setattr(streaming, "plan_trials", slow_plans)
    stats, written, truths = _stream_on_fake_clock(now, trials=3)
    assert stats.trials == 3
    assert stats.late_trials == 1
    onsets = [gt.onset_ns - START_NS for gt in truths]
    assert onsets[1] - onsets[0] == pytest.approx(0.8e9, abs=15e6)  # 0.2 s period + 0.6 s late
    assert onsets[2] - onsets[1] == pytest.approx(0.2e9, abs=15e6)  # the spacing is kept
    late_trial = [t for t, _ in written if START_NS + 0.8e9 <= t < START_NS + 1.0e9]
    assert len(late_trial) > 10  # written over time, not in one burst
    assert max(late_trial) - min(late_trial) > 0.05e9
    assert min(np.diff([t for t, _ in written])) >= streaming.FRAME_NS  # in 1 ms frames


def test_stream_refuses_a_scene_without_wire():
    sc = scene(["contact_impulse", "beam_modes", "grasp_transfer", "nuskin_transduction"])
    with pytest.raises(SceneError, match="needs effect 'nuskin_wire'"):
        stream(sc, lambda b: None, seed=0, trials=1)


def test_biotac_and_classes(tmp_path):
    _, sig = next(Simulator(load_scene("handover_plate_biotac")).batches(6, 0))
    bt = sig["biotac"]
    assert bt["pac"].shape == (6, 2, 29 * 22)
    assert bt["pac"].dtype == np.uint16
    assert bt["electrodes"].shape == (6, 2, 29, 19)
    assert bt["pac"].max() <= 4095
    assert set(sig["labels"].class_label) <= {"stable", "unstable"}
    food = yaml.safe_load(load_scene("food_fork_nuskin").path.read_text())
    food["timing"]["trial_s"] = 1.0
    _, sig = next(Simulator(scene_from_dict(food, "f")).batches(7, 0))
    assert sorted(sig["labels"].class_label) == sorted(
        ["empty", "water", "tofu", "banana", "watermelon", "apple", "green_pepper"]
    )


def test_stream_over_a_virtual_can_channel():
    can = pytest.importorskip("can")
    from ext_sense_sim.links import open_link

    sc = scene(
        ["contact_impulse", "beam_modes", "grasp_transfer", "nuskin_transduction", "nuskin_wire"]
    )
    receiver = can.Bus(interface="virtual", channel="sim_test_can")
    sink = open_link("can", can_channel="sim_test_can")
    try:
        stats = stream(sc, sink.write, seed=2, trials=1, period_s=0.1)
        data = b""
        while (msg := receiver.recv(timeout=0.2)) is not None:
            assert msg.arbitration_id == 0x100
            data += bytes(msg.data)
    finally:
        sink.close()
        receiver.shutdown()
    assert stats.bytes > 0
    assert len(data) == stats.bytes
