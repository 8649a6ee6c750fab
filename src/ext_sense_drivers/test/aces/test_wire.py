import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_drivers.aces import (
    COUNTS_PER_UNIT,
    AcesError,
    bytes_to_samples,
    ns_to_sample,
    sample_to_ns,
    samples_to_bytes,
)


def test_wire_round_trip_is_exact_on_the_count_grid():
    line = np.array([0.0, 1.0, -1.0, 2.5, -7.0, 1 / COUNTS_PER_UNIT])
    q = samples_to_bytes(line)
    assert len(q.data) == 2 * line.size
    assert q.n_clipped == 0
    assert np.array_equal(bytes_to_samples(q.data), line)


def test_wire_is_little_endian_int16():
    q = samples_to_bytes(np.array([1.0, -1.0]))
    assert q.data == (4096).to_bytes(2, "little") + (-4096).to_bytes(2, "little", signed=True)


def test_clipping_is_counted():
    q = samples_to_bytes(np.array([0.0, 9.0, -9.0, 7.9]))
    assert q.n_clipped == 2
    assert bytes_to_samples(q.data)[1] == pytest.approx(32767 / COUNTS_PER_UNIT)


def test_bad_line_is_rejected():
    with pytest.raises(AcesError, match="'line' parameter must be finite"):
        samples_to_bytes(np.array([0.0, np.nan]))
    with pytest.raises(AcesError, match="1-D real array"):
        samples_to_bytes(np.zeros((2, 2)))
    with pytest.raises(AcesError, match="whole int16 samples"):
        bytes_to_samples(b"\x00\x01\x02")


@given(st.integers(min_value=0, max_value=2**45))
def test_sample_clock_round_trip(n):
    t = sample_to_ns(n, 508_000)
    assert int(ns_to_sample(t, 508_000)) == n
    # floor of the exact time: never ahead of it, less than one ns behind
    assert 0 <= n * 1_000_000_000 - int(t) * 508_000 < 508_000


@given(st.integers(min_value=0, max_value=2**62))
def test_ns_to_sample_is_nearest_and_never_overflows(t):
    n = int(ns_to_sample(t, 508_000))
    assert abs(n * 1_000_000_000 - t * 508_000) <= 500_000_000
