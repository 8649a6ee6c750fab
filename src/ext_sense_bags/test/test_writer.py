import json
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ext_sense_bags import (
    EXT_SENSE_TYPES,
    BagError,
    BagReader,
    BagWriter,
    Storage,
    biotac_frame,
    ground_truth,
    make_message,
    taxel_event_batch,
    type_hash,
)
from ext_sense_runtime.stamps import stamp_to_ns

T0 = 1_700_000_000_123_456_789
EVENTS = "/extsense/nuskin/events"


def _write_sample(path: Path, storage: Storage) -> None:
    with BagWriter(path, storage=storage) as bag:
        for i in range(5):
            t = T0 + i * 1_000_000
            n = i + 1
            bag.write(
                EVENTS,
                t,
                taxel_event_batch(
                    t, np.arange(1, n + 1), np.ones(n), np.full(n, 7), np.arange(n) * 10
                ),
            )
        bag.write(
            "/extsense/biotac/frames",
            T0,
            biotac_frame(T0, np.arange(22), np.arange(19), 1, 2, 3, sequence=70000),
        )
        bag.write(
            "/extsense/ground_truth",
            T0 + 5,
            ground_truth(T0 + 5, "tap_localization", 4, tap_position_m=0.125),
        )


@pytest.mark.parametrize("storage", list(Storage))
def test_round_trip_every_storage(tmp_path, storage):
    _write_sample(tmp_path / "bag", storage)
    with BagReader(tmp_path / "bag") as bag:
        topics = bag.topics
        assert topics[EVENTS].count == 5
        assert topics["/extsense/ground_truth"].msgtype == "ext_sense_msgs/msg/ContactGroundTruth"
        got = list(bag.messages([EVENTS]))
    assert [r.log_time_ns for r, _ in got] == [T0 + i * 1_000_000 for i in range(5)]
    last = got[-1][1]
    assert last.taxel.dtype == np.uint16
    assert last.taxel.tolist() == [1, 2, 3, 4, 5]
    assert last.offset_ns.tolist() == [0, 10, 20, 30, 40]
    assert stamp_to_ns(last.header.stamp) == T0 + 4_000_000


def test_biotac_sequence_wraps_and_fixed_arrays_checked(tmp_path):
    msg = biotac_frame(T0, np.arange(22), np.arange(19), 1, 2, 3, sequence=70000)
    assert msg.sequence == 70000 % 65536
    with pytest.raises(BagError, match="exactly 22"):
        biotac_frame(T0, np.arange(21), np.arange(19), 1, 2, 3)


def test_mcap_readable_without_ros(tmp_path):
    from mcap_ros2.reader import read_ros2_messages

    _write_sample(tmp_path / "bag", Storage.MCAP)
    (mcap_file,) = (tmp_path / "bag").glob("*.mcap")
    seen = {}
    for m in read_ros2_messages(str(mcap_file)):
        seen.setdefault(m.channel.topic, []).append(m)
        assert m.channel.metadata["topic_type_hash"].startswith("RIHS01_")
    assert len(seen[EVENTS]) == 5
    gt = seen["/extsense/ground_truth"][0].ros_msg
    assert gt.task == "tap_localization"
    assert gt.tap_position_m == pytest.approx(0.125)
    assert list(seen["/extsense/biotac/frames"][0].ros_msg.pac) == list(range(22))


def test_type_hashes_match_rosidl_build():
    share = Path(sys.prefix) / "share" / "ext_sense_msgs" / "msg"
    if not share.is_dir():
        pytest.skip(f"built ext_sense_msgs not found under {share}")
    for name in EXT_SENSE_TYPES:
        data = json.loads((share / f"{name.rsplit('/', 1)[1]}.json").read_text())
        expected = next(h["hash_string"] for h in data["type_hashes"] if h["type_name"] == name)
        assert type_hash(name) == expected


def test_rclpy_serialized_bytes_round_trip(tmp_path):
    pytest.importorskip("rclpy")
    from rclpy.serialization import deserialize_message, serialize_message

    from ext_sense_msgs.msg import ContactEstimate

    est = ContactEstimate(task="tap_localization", tap_position_m=0.2, class_index=-1)
    est.class_probabilities = [0.25, 0.75]
    est.class_names = ["a", "b"]
    with BagWriter(tmp_path / "bag") as bag:
        bag.write_raw("/extsense/contact_estimate", T0, serialize_message(est))
    with BagReader(tmp_path / "bag") as bag:
        ((rec, msg),) = list(bag.messages())
    assert msg.tap_position_m == pytest.approx(0.2)
    assert msg.class_names == ["a", "b"]
    back = deserialize_message(rec.data, ContactEstimate)
    assert back == est


@settings(max_examples=25, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(1, 80), st.sampled_from([-1, 0, 1]), st.integers(0, 1023)),
        max_size=50,
    )
)
def test_event_batch_cdr_round_trip(events):
    from ext_sense_bags.typestore import make_typestore

    store = make_typestore()
    arr = np.array(events, dtype=np.int64).reshape(-1, 3)
    msg = taxel_event_batch(T0, arr[:, 0], arr[:, 1], arr[:, 2], np.arange(len(arr)) * 250_000)
    back = store.deserialize_cdr(store.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)
    assert back.taxel.tolist() == arr[:, 0].tolist()
    assert back.polarity.tolist() == arr[:, 1].tolist()
    assert back.value.tolist() == arr[:, 2].tolist()


def test_errors_name_the_problem(tmp_path):
    with pytest.raises(BagError, match="one length"):
        taxel_event_batch(T0, [1, 2], [1], [1, 2], [0, 1])
    with pytest.raises(BagError, match="offset_ns must be >= 0"):
        taxel_event_batch(T0, [1], [1], [1], [-5])
    with pytest.raises(BagError, match="no field"):
        make_message("ext_sense_msgs/msg/ContactWindow", bogus=1)
    with pytest.raises(BagError, match="Unknown message type"):
        make_message("nope_msgs/msg/Nope")
    with pytest.raises(BagError, match="'storage' parameter"):
        BagWriter(tmp_path / "x", storage="rosbag1")
    (tmp_path / "exists").mkdir()
    with pytest.raises(BagError, match="exists"):
        BagWriter(tmp_path / "exists").open()
    with BagWriter(tmp_path / "b") as bag:
        with pytest.raises(BagError, match="give its msgtype"):
            bag.write_raw("/unknown", T0, b"\x00\x01\x00\x00")
        bag.write(EVENTS, T0, taxel_event_batch(T0, [1], [1], [1], [0]))
        with pytest.raises(BagError, match="holds ext_sense_msgs/msg/TaxelEventBatch"):
            bag.write(EVENTS, T0, ground_truth(T0, "x", 0))
    with pytest.raises(BagError, match="does not exist"):
        BagReader(tmp_path / "missing").open()
    with BagReader(tmp_path / "b") as bag, pytest.raises(BagError, match="not in bag"):
        list(bag.records(["/nope"]))


def test_corrupt_file_gives_bag_error(tmp_path):
    _write_sample(tmp_path / "bag", Storage.MCAP)
    (mcap_file,) = (tmp_path / "bag").glob("*.mcap")
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(mcap_file.read_bytes()[:200] + b"\xff" * 100)
    with pytest.raises(BagError, match=r"bad\.mcap"), BagReader(bad) as bag:
        list(bag.records())
    (tmp_path / "notes.txt").write_text("not a bag")
    with pytest.raises(BagError, match=r"notes\.txt: Unrecognized storage format"):
        BagReader(tmp_path / "notes.txt").open()


def test_custom_data_round_trip(tmp_path):
    with BagWriter(tmp_path / "b") as bag:
        bag.set_custom_data("task", "food_identification")
        bag.write(EVENTS, T0, taxel_event_batch(T0, [1], [1], [1], [0]))
    with BagReader(tmp_path / "b") as bag:
        assert bag.custom_data == {"task": "food_identification"}
