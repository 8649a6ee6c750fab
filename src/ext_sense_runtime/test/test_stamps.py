from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from ext_sense_runtime.stamps import join_ns, split_ns


@given(st.integers(min_value=-(2**62), max_value=2**62))
def test_split_join_round_trip(ns):
    sec, nanosec = split_ns(ns)
    assert 0 <= nanosec < 1_000_000_000
    assert join_ns(sec, nanosec) == ns


def test_epoch_split():
    assert split_ns(1_700_000_000_123_456_789) == (1_700_000_000, 123_456_789)
    assert split_ns(-1) == (-1, 999_999_999)
