import numpy as np
import pytest

from ext_sense_drivers.aces import AcesError, correlation_stats, load_bank
from ext_sense_drivers.aces.bank import BANK_SHA256, BANK_SPECS, aperiodic_xcorr
from ext_sense_drivers.aces.sequences import gold_family, m_sequence, to_chips


def periodic_xcorr(a, b):
    """Periodic cross-correlation ``r[d] = sum_i a[i] * b[(i + d) mod N]`` for every shift ``d``."""
    n = a.shape[0]
    idx = (np.arange(n)[:, None] + np.arange(n)[None, :]) % n
    return (b.astype(np.int64)[idx] @ a.astype(np.int64)).astype(np.int64)


def test_bank_v1_shape_clock_and_hash():
    bank = load_bank(1)
    assert bank.chips.shape == (80, 127)
    assert set(np.unique(bank.chips).tolist()) == {-1, 1}
    assert bank.sample_rate_hz == 508_000
    assert bank.signature_ns == 250_000
    assert bank.n_chips * 1_000_000_000 == bank.sample_rate_hz * bank.signature_ns
    assert bank.sha256 == BANK_SHA256[1]


def test_every_published_version_matches_its_hash():
    for version in BANK_SPECS:
        assert load_bank(version).sha256 == BANK_SHA256[version]


def test_bank_is_cached_and_read_only():
    bank = load_bank()
    assert load_bank() is bank
    with pytest.raises(ValueError, match="read-only"):
        bank.chips[0, 0] = 0


def test_codes_are_distinct_rows_of_the_gold_family():
    bank = load_bank()
    spec = BANK_SPECS[1]
    family = to_chips(gold_family(spec.poly_u, spec.poly_v, spec.degree))
    assert np.array_equal(family[bank.gold_rows], bank.chips)
    assert np.unique(bank.chips, axis=0).shape[0] == 80


def test_preferred_pair_gives_three_valued_cross_correlation():
    spec = BANK_SPECS[1]
    u = to_chips(m_sequence(spec.poly_u, spec.degree))
    v = to_chips(m_sequence(spec.poly_v, spec.degree))
    assert set(periodic_xcorr(u, v).tolist()) <= {-17, -1, 15}


def test_m_sequence_is_maximal_and_balanced():
    seq = m_sequence(0b10001001, 7)
    assert seq.shape == (127,)
    assert int(seq.sum()) == 64
    auto = periodic_xcorr(to_chips(seq), to_chips(seq))
    assert auto[0] == 127
    assert set(auto[1:].tolist()) == {-1}


def test_non_primitive_polynomial_is_rejected():
    with pytest.raises(AcesError, match="not primitive"):
        m_sequence(0b10000001, 7)  # x^7 + 1 = (x + 1)(...): not primitive
    with pytest.raises(AcesError, match="'poly' parameter"):
        m_sequence(0b1000, 7)


def test_unknown_version_is_rejected():
    with pytest.raises(AcesError, match="'version' parameter must be one of"):
        load_bank(99)


def test_correlation_bounds_of_v1():
    stats = correlation_stats(load_bank().chips)
    assert stats.periodic_cross == pytest.approx(17 / 127)
    assert stats.aperiodic_cross <= 27 / 127 + 1e-9
    assert stats.aperiodic_auto <= 27 / 127 + 1e-9
    assert stats.rms_cross < 0.07


def test_gold_bank_beats_random_codes_of_the_same_size():
    rng = np.random.default_rng(3)
    random_codes = rng.choice(np.array([-1, 1], np.int8), size=(80, 127))
    gold = correlation_stats(load_bank().chips)
    rand = correlation_stats(random_codes)
    assert gold.periodic_cross < rand.periodic_cross
    assert gold.aperiodic_cross < rand.aperiodic_cross


def test_aperiodic_table_matches_direct_correlation():
    chips = load_bank().chips
    table = aperiodic_xcorr(chips)
    length = chips.shape[1]
    line = np.zeros(3 * length)
    line[length : 2 * length] = chips[5]
    for a in (5, 11):
        for d in (-length + 1, -3, 0, 1, 60, length - 1):
            direct = float(np.dot(line[length + d : 2 * length + d], chips[a]))
            assert table[a, 5, d + length - 1] == direct
