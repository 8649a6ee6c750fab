"""The receiver link's queue: words leave in order, never faster than the link, never early."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ext_sense_runtime.records import EventBlock
from ext_sense_sim.effects.base import Signals, TimeBase
from ext_sense_sim.effects.receiver import ReceiverLink, drain_times


def _reference(t_ns: np.ndarray, starts: np.ndarray, word_ns: float) -> np.ndarray:
    out = np.empty(t_ns.size)
    for a, b in itertools.pairwise(starts):
        last = -np.inf
        for k in range(a, b):
            last = max(float(t_ns[k]), last + word_ns)
            out[k] = last
    return np.round(out).astype(np.int64)


@pytest.mark.parametrize("seed", range(5))
def test_drain_times_equal_the_queue_recursion_per_trial(seed: int) -> None:
    rng = np.random.default_rng(seed)
    sizes = rng.integers(0, 400, size=6)
    t = np.concatenate([np.sort(rng.integers(0, 50_000_000, size=n)) for n in sizes])
    starts = np.r_[0, np.cumsum(sizes)]
    got = drain_times(t, starts, 20_000.0)
    np.testing.assert_array_equal(got, _reference(t, starts, 20_000.0))
    assert np.all(got >= t)  # never before the event
    for a, b in itertools.pairwise(starts):
        assert np.all(np.diff(got[a:b]) >= 20_000 - 1)  # never faster than the link


def test_a_burst_becomes_a_flat_ceiling_and_a_slow_link_changes_nothing_it_can_carry() -> None:
    burst = np.zeros(1000, dtype=np.int64)  # 1000 events at once
    out = drain_times(burst, np.array([0, 1000]), 1e9 / 50_000)
    assert out[-1] == pytest.approx(999 * 20_000, abs=1)
    sparse = np.arange(0, 10_000_000, 100_000, dtype=np.int64)  # 10k/s on a 50k/s link
    np.testing.assert_array_equal(drain_times(sparse, np.array([0, sparse.size]), 20_000), sparse)


def test_the_effect_delays_events_and_zero_words_per_s_is_an_unlimited_link() -> None:
    n = 500
    events = EventBlock(
        np.zeros(n, np.int64),
        np.full(n, 3, np.uint16),
        np.ones(n, np.int8),
        np.full(n, 100, np.uint16),
    )
    time = TimeBase(16000.0, 1600, 1)  # a 0.1 s trial
    for rate, kept, last in (
        (0.0, n, 0),
        (10_000.0, 500, 499 * 100_000),
        (4000.0, 400, 399 * 250_000),
    ):
        signals = Signals(events=(np.zeros(n, np.int32), events))
        link = ReceiverLink({"words_per_s": rate})
        link.run(signals, time, np.random.default_rng(0))
        assert signals["events"][1].size == kept  # words queued past the trial's end are left out
        assert link.dropped == n - kept
        assert int(signals["events"][1].t_ns[-1]) == last


def test_the_new_sensor_and_grasp_parameters_are_fixed_per_sensor_and_off_by_default() -> None:
    from ext_sense_sim.engine import Simulator
    from ext_sense_sim.scene import load_scene

    scene = load_scene("tap_rod30_nuskin")
    sim = Simulator(scene)
    noise = next(e for e in sim.effects if e.name == "sensor_noise")
    again = next(e for e in Simulator(scene).effects if e.name == "sensor_noise")
    np.testing.assert_array_equal(noise.chatty, again.chatty)  # the same sensor every run
    assert noise.chatty.size == 3
    quiet = Simulator(load_scene("food_fork_nuskin"))
    assert next(e for e in quiet.effects if e.name == "sensor_noise").chatty.size == 0
