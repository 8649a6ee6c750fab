import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.errors import NuskinError


def test_words_spread_over_the_interval_since_the_previous_read():
    clock = ArrivalClock(byte_time_ns=1000, min_spread_ns=1_000_000)
    clock.stamp(0, 10_000_000)
    stamps = clock.stamp(4, 10_400_000)
    assert stamps.dtype == np.int64
    assert stamps.tolist() == [10_100_000, 10_200_000, 10_300_000, 10_400_000]


def test_spread_capped_after_an_idle_line():
    clock = ArrivalClock(byte_time_ns=1000, min_spread_ns=1_000_000)
    clock.stamp(0, 0)
    stamps = clock.stamp(2, 5_000_000_000)  # 5 s of silence, then two words
    assert stamps.tolist() == [4_999_500_000, 5_000_000_000]


def test_first_read_uses_the_cap():
    clock = ArrivalClock(byte_time_ns=100_000, min_spread_ns=0)
    assert clock.stamp(2, 10_000_000).tolist() == [9_600_000, 10_000_000]


def test_clock_stepping_back_is_clamped():
    clock = ArrivalClock()
    clock.stamp(1, 50_000_000)
    assert clock.stamp(3, 40_000_000).tolist() == [50_000_000] * 3


def test_for_baud():
    assert ArrivalClock.for_baud(1_000_000).byte_time_ns == 10_000
    with pytest.raises(NuskinError, match=r"'baud' parameter must be > 0\. Got 0"):
        ArrivalClock.for_baud(0)
    with pytest.raises(NuskinError, match="'byte_time_ns'"):
        ArrivalClock(byte_time_ns=0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 500), st.integers(-(10**6), 10**8)), max_size=40))
def test_monotonic_and_inside_the_read_interval(reads):
    clock = ArrivalClock(byte_time_ns=10_000, min_spread_ns=1_000_000)
    t = 10**12
    prev_read = None
    last = -1
    for n, dt in reads:
        t += dt
        stamps = clock.stamp(n, t)
        assert stamps.shape == (n,)
        if n:
            assert np.all(np.diff(stamps) >= 0)
            assert stamps[0] >= last
            assert stamps[-1] == max(t, last, prev_read if prev_read is not None else t)
            if prev_read is not None and dt >= 0:
                assert stamps[0] >= min(prev_read, t)
            last = int(stamps[-1])
        prev_read = t if prev_read is None else max(prev_read, t)
