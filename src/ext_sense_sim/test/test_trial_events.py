import numpy as np

from ext_sense_runtime.records import EventBlock
from ext_sense_sim.trial_events import empty, merge


def test_event_batch_merge_sorts():
    a = (
        np.array([1, 0], np.int32),
        EventBlock(
            np.array([5, 9], np.int64),
            np.array([1, 2], np.uint16),
            np.array([1, -1], np.int8),
            np.array([3, 4], np.uint16),
        ),
    )
    trial, m = merge(a, empty())
    assert trial.tolist() == [0, 1]
    assert m.t_ns.tolist() == [9, 5]
