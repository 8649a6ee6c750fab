"""``stream_on_trigger``: trials played when a behaviour asks, on a fake clock (no waiting)."""

from __future__ import annotations

import itertools
import queue
import threading

import numpy as np
import pytest

from ext_sense_runtime.stamps import MS, S
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import load_scene
from ext_sense_sim.streaming import Trigger, stream_on_trigger
from ext_sense_sim.trial_plan import plan_trials


class FakeClock:
    """Epoch ns that only moves when the streamer sleeps (or a test moves it)."""

    def __init__(self, now_ns: int) -> None:
        self.now = now_ns

    def __call__(self) -> int:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += max(int(seconds * 1e9), 100_000)


@pytest.fixture(scope="module")
def scene():
    return load_scene("handover_rod_nuskin")


def _run(scene, triggers, clock, **kwargs):
    writes, truths = [], []
    stats = stream_on_trigger(
        scene,
        lambda data: writes.append((clock(), data)),
        triggers,
        seed=3,
        on_onset=truths.append,
        clock=clock,
        sleep=clock.sleep,
        **kwargs,
    )
    return stats, writes, truths


def test_each_trigger_plays_a_grasp_of_one_scheduled_class(scene):
    clock = FakeClock(100 * S)
    triggers: queue.Queue[Trigger] = queue.Queue()
    triggers.put(Trigger(100 * S))
    triggers.put(Trigger(100 * S))  # taken once the first grasp is over
    stats, writes, truths = _run(
        scene,
        triggers,
        clock,
        trials=6,
        per_trigger=3,
        period_s=1.0,
        labels=["unstable", "stable"],
    )
    assert stats.trials == 6
    assert stats.extra["triggers"] == 2
    assert [g.class_label for g in truths] == ["unstable"] * 3 + ["stable"] * 3
    # the trials of one trigger are the scene's own trials (same seed) in order, those of
    # another class skipped
    used = [g.trial for g in truths]
    plans = list(itertools.islice(plan_trials(scene, 3), used[-1] + 1))
    unstable = [p.trial for p in plans if p.class_label == "unstable"][:3]
    stable = [p.trial for p in plans if p.class_label == "stable" and p.trial > unstable[-1]][:3]
    assert used == unstable + stable
    starts = np.array([g.onset_ns for g in truths[:3]])
    onsets = []
    for trial in unstable:
        plan = plans[trial]
        times = np.array([c[0] for c in plan.chunks])
        onsets.append(int(times[np.searchsorted(times, plan.onset_ns)]))
    # trial j starts at trigger + j s; its truth is stamped at the write of its onset chunk
    # (within one 1 ms sleep of the fake clock)
    expected = 100 * S + np.arange(3) * S + np.array(onsets)
    assert np.all(np.abs(starts - expected) <= 1 * MS)
    assert sum(len(d) for _, d in writes) == stats.bytes


def test_a_trigger_label_overrides_the_schedule_for_its_grasp(scene):
    clock = FakeClock(100 * S)
    triggers: queue.Queue[Trigger] = queue.Queue()
    triggers.put(Trigger(100 * S, "stable"))
    triggers.put(Trigger(100 * S, "stable"))  # the same class again (a grasp without a window)
    triggers.put(Trigger(100 * S))  # no label: the schedule's third entry
    _, _, truths = _run(
        scene,
        triggers,
        clock,
        trials=6,
        per_trigger=2,
        period_s=1.0,
        labels=["unstable", "unstable", "unstable"],
    )
    assert [g.class_label for g in truths] == ["stable"] * 4 + ["unstable"] * 2


def test_onset_alignment_puts_the_trial_onset_at_the_trigger_stamp(scene):
    # the trigger (e.g. a food probe's motion start) is taken 40 ms after its stamp
    clock = FakeClock(50 * S + 40 * MS)
    triggers: queue.Queue[Trigger] = queue.Queue()
    triggers.put(Trigger(50 * S))
    stats, writes, truths = _run(scene, triggers, clock, trials=1, align="onset")
    (truth,) = truths
    assert truth.onset_ns == 50 * S  # the true onset, by construction
    plan = next(plan_trials(scene, 3))
    times = np.array([c[0] for c in plan.chunks])
    k = int(np.searchsorted(times, plan.onset_ns))
    skipped = sum(len(c[1]) for c in plan.chunks[:k])
    assert stats.extra["skipped_bytes"] == skipped
    assert stats.bytes == sum(len(c[1]) for c in plan.chunks) - skipped
    # the bytes from the onset to "now" go out at once, the rest on time
    first_t, first = writes[0]
    assert first_t == 50 * S + 40 * MS
    assert first.startswith(plan.chunks[k][1])
    last_t, _ = writes[-1]
    assert last_t >= 50 * S - plan.onset_ns + int(times[-1])


def test_no_trigger_no_bytes_and_stop_ends_the_wait(scene):
    stop = threading.Event()
    triggers: queue.Queue[Trigger] = queue.Queue()
    ready = []
    timer = threading.Timer(0.3, stop.set)
    timer.start()
    writes = []
    stats = stream_on_trigger(
        scene, writes.append, triggers, seed=3, stop=stop, on_ready=lambda: ready.append(1)
    )
    timer.join()
    assert writes == []
    assert stats.trials == 0
    assert ready == [1]  # the first trial was simulated and waited for its trigger


def test_bad_arguments_are_named(scene):
    with pytest.raises(SceneError, match="'align' parameter must be one of"):
        stream_on_trigger(scene, print, queue.Queue(), seed=0, align="middle")
    with pytest.raises(SceneError, match="'per_trigger' parameter must be >= 1"):
        stream_on_trigger(scene, print, queue.Queue(), seed=0, per_trigger=0)
