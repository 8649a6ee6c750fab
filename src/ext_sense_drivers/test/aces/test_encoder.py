import numpy as np
import pytest

from ext_sense_drivers.aces import AcesError, encode_line, load_bank, sample_to_ns

BANK = load_bank()
L = BANK.n_chips
RATE = BANK.sample_rate_hz


def test_single_event_is_its_signature_at_its_sample():
    t = int(sample_to_ns(1000, RATE))
    enc = encode_line([t], [7], [1])
    assert enc.samples.shape == (1000 + L,)
    assert np.array_equal(enc.samples[1000:], BANK.chips[6].astype(float))
    assert not enc.samples[:1000].any()
    assert enc.start.tolist() == [1000]
    assert enc.n_truncated == 0
    assert enc.n_self_overlaps == 0


def test_negative_polarity_negates_and_amplitude_scales():
    enc = encode_line([0], [80], [-1], amplitude=0.5)
    assert np.array_equal(enc.samples, -0.5 * BANK.chips[79])


def test_overlapping_signatures_sum():
    starts = [10, 15, 15]
    taxels = [1, 2, 40]
    pols = [1, -1, 1]
    enc = encode_line(sample_to_ns(starts, RATE), taxels, pols)
    expected = np.zeros(15 + L)
    for s, k, p in zip(starts, taxels, pols, strict=True):
        expected[s : s + L] += p * BANK.chips[k - 1]
    assert np.array_equal(enc.samples, expected)


def test_times_round_to_the_nearest_sample():
    period = 1e9 / RATE
    t = np.array([0, 984, 985, 2952, 1_000_000])
    enc = encode_line(t, [1] * 5, [1, -1, 1, -1, 1])
    assert enc.start.tolist() == np.rint(t / period).astype(int).tolist()


def test_truncation_and_self_overlap_are_counted():
    t = sample_to_ns([0, 50, 300, 390], RATE)
    enc = encode_line(t, [3, 3, 4, 5], [1, 1, 1, 1], n_samples=400)
    assert enc.samples.shape == (400,)
    assert enc.n_truncated == 2  # 300 + 127 > 400 and 390 + 127 > 400
    assert enc.n_self_overlaps == 1  # taxel 3 at 0 and 50


def test_noise_is_reproducible_with_a_seeded_generator():
    a = encode_line([0], [1], [1], noise_std=0.1, rng=np.random.default_rng(5))
    b = encode_line([0], [1], [1], noise_std=0.1, rng=np.random.default_rng(5))
    assert np.array_equal(a.samples, b.samples)
    assert np.std(a.samples - BANK.chips[0]) == pytest.approx(0.1, rel=0.3)


def test_no_events_gives_an_empty_or_silent_line():
    assert encode_line([], [], []).samples.shape == (0,)
    assert not encode_line([], [], [], n_samples=10).samples.any()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"taxel": [0]}, "'taxel' parameter must be in 1..80"),
        ({"taxel": [81]}, "'taxel' parameter must be in 1..80"),
        ({"polarity": [0]}, "'polarity' parameter must be"),
        ({"t_ns": [-1]}, "'t_ns' parameter must be >= 0"),
        ({"t_ns": [0.5]}, "'t_ns' parameter must be a 1-D integer array"),
        ({"t_ns": [0, 1]}, "one length"),
        ({"noise_std": -1.0}, "'noise_std' parameter"),
        ({"amplitude": float("nan")}, "'amplitude' parameter"),
        ({"n_samples": -5}, "'n_samples' parameter"),
    ],
)
def test_bad_events_are_rejected(kwargs, match):
    args = {"t_ns": [0], "taxel": [1], "polarity": [1]}
    args.update(kwargs)
    t, k, p = args.pop("t_ns"), args.pop("taxel"), args.pop("polarity")
    with pytest.raises(AcesError, match=match):
        encode_line(t, k, p, **args)
