import numpy as np
import pytest

from ext_sense_sim.effects.contact import half_sine_bins
from ext_sense_sim.effects.fork import FOODS, penetration_force
from ext_sense_sim.effects.grasp import lattice
from ext_sense_sim.effects.handover import settling, stick_slip
from ext_sense_sim.effects.nuskin import front_end, level_crossing
from ext_sense_sim.effects.wire import WireStream, inject_faults
from ext_sense_sim.events import EventBatch


@pytest.mark.parametrize("duration", [1e-5, 5e-4, 3e-3])
def test_half_sine_impulse_is_exact(duration):
    peak = np.array([3.0])
    f = half_sine_bins(peak, np.array([duration]), np.array([0.01234567]), 16000.0, 800)
    assert f.sum() / 16000 == pytest.approx(2 * 3.0 * duration / np.pi, rel=1e-9)
    assert f.max() <= 3.0 + 1e-12


def test_lattice_is_row_major_8_by_5():
    u, c = lattice(0.003)
    assert u.shape == c.shape == (40,)
    assert np.unique(u).size == 8
    assert np.unique(c).size == 5
    assert u[5] - u[0] == pytest.approx(0.003)
    assert c[1] - c[0] == pytest.approx(0.003)


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


def test_stick_slip_period_is_the_spring_block_answer():
    t = np.arange(0, 1.0, 1e-5)
    normal, mu_s, mu_k, k, v = 3.0, 0.8, 0.4, 1000.0, 0.05
    force, slips = stick_slip(t, normal, mu_s, mu_k, k, v, np.zeros(100))
    assert np.diff(slips[:5]) == pytest.approx([(mu_s - mu_k) * normal / (k * v)] * 4)
    assert force.max() <= mu_s * normal + 1e-9
    assert force[t > slips[0] + 1e-4].min() >= mu_k * normal - 1e-9


def test_settling_reaches_its_final_force():
    t = np.linspace(-0.1, 2.0, 10000)
    f = settling(t, 3.0, 5.0, 0.6)
    assert np.all(f[t < 0] == 0)
    assert f[-1] == pytest.approx(3.0, rel=1e-3)
    assert f.max() < 3.0 * 1.1  # zeta 0.6 overshoots under 10 %


def test_water_forces_are_tiny_and_apple_fractures():
    depth = np.linspace(-0.005, 0.03, 5000)
    water = penetration_force(depth, FOODS["water"], np.zeros(0), 0.0)
    assert 0 < water.max() < 0.01
    apple = penetration_force(depth, FOODS["apple"], np.zeros(0), 0.0)
    assert apple.max() == pytest.approx(FOODS["apple"].fracture_n, rel=0.02)
    assert apple[-1] == pytest.approx(FOODS["apple"].cut_n)
    assert np.all(penetration_force(depth, FOODS["empty"], np.zeros(0), 0.0) == 0)


def test_wire_faults_rates_and_identity():
    rng = np.random.default_rng(0)
    data = bytes(range(256)) * 400
    stream = WireStream(
        data,
        np.arange(0, len(data) + 1, 4, dtype=np.int64),
        np.arange(len(data) // 4, dtype=np.int64),
    )
    same, counts = inject_faults(stream, 0.0, 0.0, 0.0, rng)
    assert same.data == data
    assert counts == {"lost": 0, "flipped": 0, "extra": 0}
    bad, counts = inject_faults(stream, 0.01, 0.01, 0.01, rng)
    n = len(data)
    for key in counts:
        assert abs(counts[key] - 0.01 * n) < 5 * np.sqrt(0.01 * n)
    assert len(bad.data) == n - counts["lost"] + counts["extra"]
    assert bad.offsets[-1] == len(bad.data)


def test_words_round_trip_through_the_drivers_decoder():
    from ext_sense_drivers.nuskin.wire import WordDecoder, encode_words

    taxel = np.array([1, 40, 41, 80], dtype=np.uint16)
    value = np.array([0, 5, 512, 1023], dtype=np.uint16)
    got = WordDecoder().feed(encode_words(taxel, value))
    np.testing.assert_array_equal(got.taxel, taxel)
    np.testing.assert_array_equal(got.value, value)


def test_event_batch_merge_sorts():
    a = EventBatch(
        np.array([1, 0], np.int32),
        np.array([5, 9], np.int64),
        np.array([1, 2], np.uint16),
        np.array([1, -1], np.int8),
        np.array([3, 4], np.uint16),
    )
    m = a.merged(EventBatch.empty())
    assert m.trial.tolist() == [0, 1]
    assert m.t_ns.tolist() == [9, 5]


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


def test_torque_loads_the_two_pads_with_opposite_sign_and_shear_with_the_same():
    from ext_sense_sim.effects.grasp import GraspTransfer
    from ext_sense_sim.scene import load_scene

    grasp = GraspTransfer({"gain_spread": 0.0}, load_scene("tap_rod30_nuskin"))
    w = grasp.weights(np.full((1, 2), 0.001), np.random.default_rng(0), 1)[0]
    left, right = w[:40], w[40:]
    np.testing.assert_allclose(left[:, 6], -right[:, 6])  # torque: opposite
    np.testing.assert_allclose(left[:, 3], right[:, 3])  # shear along the pads: same
    np.testing.assert_allclose(left[:, 1], -right[:, 1])  # load toward the pads: opposite
    assert np.abs(left[:, 6]).max() > 0


def _transduce(params: dict, pressure: np.ndarray) -> EventBatch:
    from ext_sense_sim.effects.base import Signals, TimeBase
    from ext_sense_sim.effects.nuskin import NuskinTransduction

    effect = NuskinTransduction({"bandwidth_hz": 7000.0, **params})
    signals = Signals(taxel_pressure=pressure.astype(np.float32))
    effect.run(signals, TimeBase(16000.0, pressure.shape[-1], 1), np.random.default_rng(0))
    return signals["events"]


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
