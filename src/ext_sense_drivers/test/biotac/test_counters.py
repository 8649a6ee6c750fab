"""The per-sensor sequence tracker: batch steps equal per-frame steps."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_drivers.biotac.counters import SequenceTracker


@given(
    st.lists(st.tuples(st.integers(0, 4), st.integers(0, 65535)), min_size=9, max_size=60),
    st.integers(0, 3),
)
def test_sequence_tracker_batch_equals_per_frame(pairs, split):
    sensor = np.array([p[0] for p in pairs], dtype=np.uint8)
    seq = np.array([p[1] for p in pairs], dtype=np.uint16)
    one, batch = SequenceTracker(), SequenceTracker()
    expected = [one.step(int(a), int(b)) for a, b in zip(sensor, seq, strict=True)]
    got = []
    for part in np.array_split(np.arange(len(pairs)), split + 1):
        gap, reset = batch.steps(sensor[part], seq[part])
        got += list(zip(gap.tolist(), reset.tolist(), strict=True))
    assert got == expected
    assert vars(one) == vars(batch)
