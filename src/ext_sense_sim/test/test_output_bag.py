"""A dataset's bag: the drivers' packets, which decode to the dataset's events and frames."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_bags import BagReader
from ext_sense_drivers.packets import make_decoder
from ext_sense_runtime.stamps import MS, S, stamp_to_ns
from ext_sense_sim.output.bag import BIOTAC_PACKETS, FRAME_NS, NUSKIN_PACKETS, TRUTH, write_bag

T0 = 1_700_000_000_000_000_000


def _read(bag, topic: str) -> tuple[list, list, dict]:
    with BagReader(bag) as reader:
        packets = [m for _, m in reader.messages([topic])]
        truths = [m for _, m in reader.messages([TRUTH])]
        custom = reader.custom_data
    return packets, truths, custom


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_nuskin_events_come_back_from_the_packets(tmp_path, storage):
    d = dict(
        task=np.array("tap_localization"),
        sensor=np.array("nuskin"),
        label_kind=np.array("regression"),
        y=np.array([0.1, 0.2]),
        onset_ns=np.array([5 * MS, 6 * MS]),
        rod_length_m=np.array([0.3, 0.3]),
        trial_ns=np.array(10 * MS),
        ev_trial=np.array([0, 0, 0, 1], np.int32),
        ev_t_ns=np.array([1_500_000, 500_000, 1_500_000, 9_999_999]),
        ev_taxel=np.array([3, 4, 5, 80], np.uint16),
        ev_polarity=np.array([1, -1, -1, 1], np.int8),
        ev_value=np.array([1, 2, 3, 4], np.uint16),
    )
    write_bag(d, tmp_path / "b", t0_ns=T0, trial_period_ns=S, storage=storage)
    packets, truths, custom = _read(tmp_path / "b", NUSKIN_PACKETS)
    assert custom == {"task": "tap_localization", "sensor": "nuskin"}
    assert [t.tap_position_m for t in truths] == [0.1, 0.2]
    assert stamp_to_ns(truths[1].header.stamp) == T0 + S + 6 * MS
    decoder = make_decoder(str(packets[0].encoding), str(packets[0].encoding_options))
    events = [decoder.decode(p).events for p in packets]
    assert decoder.counters.lost_packets == 0
    fields = ("t_ns", "taxel", "polarity", "value")
    t, taxel, polarity, value = (np.concatenate([getattr(e, f) for e in events]) for f in fields)
    assert taxel.tolist() == [4, 3, 5, 80]  # one read per event time, in time order
    assert polarity.tolist() == [-1, 1, -1, 1]
    assert value.tolist() == [2, 1, 3, 4]
    want = T0 + np.array([500_000, 1_500_000, 1_500_000, S + 9_999_999])
    # a read's last word at the read, the others spread back over the time since the one before
    assert t[[0, 2, 3]].tolist() == want[[0, 2, 3]].tolist()
    assert want[0] < t[1] < want[1]
    # the link opens at trial 0's origin, says "nothing read" while silent, ends after trial 1
    assert stamp_to_ns(packets[0].header.stamp) == T0
    n = len(packets)
    assert [k for k, p in enumerate(packets) if len(p.data)] == [1, 2, n - 3]
    assert n > S // (2 * MS)
    assert packets[-1].end_of_stream
    assert not any(p.end_of_stream for p in packets[:-1])
    assert [int(p.seq) for p in packets] == list(range(len(packets)))


def test_biotac_frames_come_back_from_the_packets(tmp_path):
    slow = np.arange(2 * 2, dtype=np.uint16).reshape(1, 2, 2)
    d = dict(
        task=np.array("handover_stability"),
        sensor=np.array("biotac"),
        label_kind=np.array("classification"),
        y=np.array(["stable"]),
        onset_ns=np.array([5 * MS]),
        rod_length_m=np.array([np.nan]),
        trial_ns=np.array(50 * MS),
        pac=np.arange(2 * 44, dtype=np.uint16).reshape(1, 2, 44),
        pac_t0_ns=np.array([MS]),
        pdc=slow,
        tac=slow + 10,
        tdc=slow + 20,
        electrodes=np.repeat(slow[..., None], 19, axis=3),
    )
    write_bag(d, tmp_path / "b", t0_ns=T0)
    packets, (truth,), _ = _read(tmp_path / "b", BIOTAC_PACKETS)
    assert truth.class_label == "stable"
    decoder = make_decoder(str(packets[0].encoding), str(packets[0].encoding_options))
    frames = [f for p in packets for f in decoder.decode(p).frames]
    assert [(f.sensor_id, f.sequence) for f in frames] == [(0, 0), (1, 0), (0, 1), (1, 1)]
    assert [f.stamp_ns for f in frames] == [T0 + MS] * 2 + [T0 + MS + FRAME_NS] * 2
    assert frames[3].pac.tolist() == list(range(44 + 22, 88))
    assert [(f.pdc, f.tac, f.tdc) for f in frames] == [
        (0, 10, 20),
        (2, 12, 22),
        (1, 11, 21),
        (3, 13, 23),
    ]
    assert frames[3].electrodes.tolist() == [3] * 19
