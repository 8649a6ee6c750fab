"""The rod demo's host reads: full USB transfers in a burst, one per latency period otherwise."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_runtime.stamps import MS
from ext_sense_sim.fidelity.captures import LATENCY_NS, TRANSFER_WORDS, read_times


def test_a_burst_arrives_in_full_transfers_and_its_rest_one_latency_period_after_it_opened():
    t = np.arange(2000, dtype=np.int64) * 1000  # a word every microsecond
    read = read_times(t)
    stamps, sizes = np.unique(read, return_counts=True)
    assert sizes.tolist() == [TRANSFER_WORDS] * 3 + [2000 - 3 * TRANSFER_WORDS]
    # a full transfer closes with its last word, the short one a latency period after its first
    assert stamps[:3].tolist() == [t[k * TRANSFER_WORDS - 1] for k in (1, 2, 3)]
    assert stamps[3] == t[3 * TRANSFER_WORDS] + LATENCY_NS


def test_a_slow_stream_arrives_once_a_latency_period_leaving_empty_10_ms_bins():
    t = np.arange(200, dtype=np.int64) * MS  # 1,000 words a second
    read = read_times(t)
    stamps, sizes = np.unique(read, return_counts=True)
    assert np.all(np.diff(stamps) == LATENCY_NS + MS)  # the next word opens the next transfer
    assert set(sizes[:-1].tolist()) == {LATENCY_NS // MS + 1}
    per_bin = np.bincount(read // (10 * MS))
    assert np.count_nonzero(per_bin == 0) > 0.3 * per_bin.size


# unique times: two transfers close at one instant only when words share it
@given(
    st.lists(st.integers(0, 50 * MS), max_size=3000, unique=True),
    st.integers(1, 600),
    st.integers(1, 30 * MS),
)
def test_every_word_is_stamped_once_no_earlier_than_it_came_and_in_order(times, words, latency):
    t = np.sort(np.array(times, dtype=np.int64))
    read = read_times(t, words, latency)
    assert read.shape == t.shape
    assert np.all(read >= t)
    assert np.all(read - t <= latency)
    assert np.all(np.diff(read) >= 0)
    assert np.unique(read, return_counts=True)[1].max(initial=0) <= words
