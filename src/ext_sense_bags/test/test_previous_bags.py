"""Bags the previous storage code wrote (commit bb1956e, ``data/bb1956e``) still read and recover.

Complete ones decode message for message; the killed ones (no footer or an open write-ahead
log, no ``metadata.yaml``) read as far as they were flushed, and ``recover_bag`` rewrites them.
"""

import shutil
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader

from ext_sense_bags import BagReader, recover_bag, type_hash

DATA = Path(__file__).parent / "data" / "bb1956e"
T0 = 1_700_000_000_000_000_000
EVENTS, TRUTH, ESTIMATE = (
    "/extsense/nuskin/events",
    "/extsense/ground_truth",
    "/extsense/contact_estimate",
)


def _check(bag: BagReader, n: int) -> None:
    """The bag holds messages 0..n-1 as the old writer wrote them (see the data's README)."""
    got = list(bag.messages())
    assert [(r.log_time_ns - T0) // 1_000_000 for r, _ in got] == list(range(n))
    for rec, msg in got:
        i = (rec.log_time_ns - T0) // 1_000_000
        assert rec.topic == (TRUTH if i % 4 == 3 else ESTIMATE if i % 4 == 2 else EVENTS)
        assert rec.type_hash == type_hash(rec.msgtype)
        assert bag.current_cdr(rec) == rec.data
        if rec.topic == TRUTH:
            assert (msg.trial, msg.tap_position_m) == (i, pytest.approx(0.01 * i))
        elif rec.topic == ESTIMATE:
            assert msg.tap_position_m == pytest.approx(0.02 * i)
        else:
            assert msg.value.tolist() == [i] * (1 + i % 5)
            assert msg.offset_ns.tolist() == list(range(1 + i % 5))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_complete_bag_of_the_previous_writer_decodes(storage):
    with BagReader(DATA / storage) as bag:
        assert bag.salvaged == ""
        assert bag.custom_data == {"task": "tap_localization"}
        assert bag.message_count == 12
        _check(bag, 12)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_killed_bag_of_the_previous_writer_reads_and_recovers(tmp_path, storage):
    bag_dir = tmp_path / "killed"
    shutil.copytree(DATA / f"killed_{storage}", bag_dir)  # read and recovered in place
    with BagReader(bag_dir) as bag:
        assert bag.salvaged
        _check(bag, 8)  # flushed after 8 messages, killed with 4 pending
    result = recover_bag(bag_dir)
    assert result.messages == 8
    assert result.kept == tmp_path / "killed.damaged"
    with BagReader(bag_dir) as bag:
        assert bag.salvaged == ""
        _check(bag, 8)
    with Reader(bag_dir) as reader:
        assert {c.digest for c in reader.connections} == {
            type_hash(c.msgtype) for c in reader.connections
        }
