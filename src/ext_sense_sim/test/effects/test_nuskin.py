import numpy as np
import pytest

from ext_sense_runtime.records import EventBlock
from ext_sense_sim.effects.nuskin import front_end, level_crossing


def test_level_crossing_ramp_gives_one_event_per_threshold():
    ramp = np.linspace(0, 10.0, 1001)[:, None]  # rises 10 thresholds slowly
    k, ch, pol = level_crossing(ramp, 1.0, refractory=4)
    assert k.size == 10
    assert np.all(pol == 1)
    assert np.all(ch == 0)


def test_level_crossing_refractory_limits_rate():
    step = np.concatenate([np.zeros(10), np.full(200, 100.0), np.zeros(200)])[:, None]
    k, _, pol = level_crossing(step, 1.0, refractory=4)
    gaps = np.diff(k[pol == 1])
    assert gaps.min() == 4  # at most one event per 4 samples (4 kHz at 16 kHz)
    assert (pol == 1).sum() == 50
    assert (pol == -1).sum() == 50


def test_level_crossing_reset_gives_one_event_per_change_whatever_its_size():
    # The real captures report one event per change of the reading (|dv| = 1 count for slow
    # changes, larger jumps in one event): a step of 100 thresholds is one event each way.
    step = np.concatenate([np.zeros(10), np.full(200, 100.0), np.zeros(200)])[:, None]
    k, _, pol = level_crossing(step, 1.0, refractory=4, reset=True)
    assert pol.tolist() == [1, -1]
    assert k.tolist() == [10, 210]
    ramp = np.linspace(0, 10.0, 1001)[:, None]  # slow: still one event per threshold
    k, _, pol = level_crossing(ramp, 1.0, refractory=4, reset=True)
    assert k.size == 10
    assert np.all(pol == 1)


def test_level_crossing_reset_rate_follows_a_fast_oscillation_up_to_the_refractory_cap():
    # A 1 kHz sine of 20 thresholds at 16 kHz: the encoder fires on nearly every refractory
    # period (the event rate, not the count per event, codes the amplitude); a sine below one
    # threshold gives no events at all.
    t = np.arange(1600) / 16000
    big = (20.0 * np.sin(2 * np.pi * 1000 * t))[:, None]
    k, _, _ = level_crossing(big, 1.0, refractory=4, reset=True)
    assert 300 < k.size <= 400
    assert np.diff(k).min() >= 4
    small = (0.4 * np.sin(2 * np.pi * 1000 * t))[:, None]
    assert level_crossing(small, 1.0, refractory=4, reset=True)[0].size == 0


def test_front_end_passes_dc_and_cuts_high_frequencies():
    t = np.arange(16000) / 16000
    x = 5.0 + np.sin(2 * np.pi * 6000 * t)
    y = front_end(x[None, :], 1500.0, 16000.0)[0]
    assert y[8000:].mean() == pytest.approx(5.0, abs=1e-3)
    assert np.abs(y[8000:] - 5.0).max() < 0.1


def test_jitter_never_breaks_the_refractory_period():
    from ext_sense_sim.effects.nuskin import refractory_safe_jitter

    rng = np.random.default_rng(0)
    k = np.repeat(np.arange(0, 4000, 4), 3)  # three channels firing at the maximum rate
    channel = np.tile(np.arange(3), 1000)
    u = refractory_safe_jitter(k, channel, 4, rng)
    assert np.all((u >= 0) & (u < 1))
    for c in range(3):
        t = k[channel == c] + u[channel == c]
        assert np.diff(t).min() >= 4 - 1e-12


def _transduce(params: dict, pressure: np.ndarray) -> EventBlock:
    from ext_sense_sim.effects.base import Signals, TimeBase
    from ext_sense_sim.effects.nuskin import NuskinTransduction

    effect = NuskinTransduction({"bandwidth_hz": 7000.0, **params})
    signals = Signals(taxel_pressure=pressure.astype(np.float32))
    effect.run(signals, TimeBase(16000.0, pressure.shape[-1], 1), np.random.default_rng(0))
    _trial, events = signals["events"]
    return events


def test_clipped_reading_stops_firing_past_full_scale():
    # a ramp from 0 to 2 MPa: 1000 Pa per count puts full scale (1023) at 953 kPa
    ramp = np.zeros((1, 1, 8000))
    ramp[0, 0, 100:7900] = np.linspace(0.0, 2e6, 7800)
    ramp[0, 0, 7900:] = 2e6
    free = _transduce({}, ramp)
    clipped = _transduce({"clip_reading": True}, ramp)
    assert free.value.max() == 1023  # values are clipped either way ...
    assert np.count_nonzero(free.polarity > 0) > 1500  # ... but the unbounded encoder fires on
    assert 900 <= np.count_nonzero(clipped.polarity > 0) <= 960  # one per count up to 1023
    assert clipped.value.max() >= 1020  # the last event lands within a count of full scale


def test_clip_reading_must_be_a_boolean():
    from ext_sense_sim.errors import SceneError

    with pytest.raises(SceneError, match="'clip_reading' must be true or false"):
        _transduce({"clip_reading": "yes"}, np.zeros((1, 1, 100)))
