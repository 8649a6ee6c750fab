"""Bags recorded before a message definition changed still decode, as they were written.

The "old" bags here are written with the pre-flag definitions: verbatim copies of
``TaxelEventBatch.msg``, ``ContactWindow.msg`` and ``ContactEstimate.msg`` from before
``TaxelEventBatch`` gained ``uint8[] flag`` and the other two ``degraded``/``degraded_reason``
(``test/data/pre_flag/``), registered as the topics' definitions the way a recorder built
before the change registered them.
"""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from ext_sense_bags.reader import to_current
from rosbags.rosbag2 import Reader, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from ext_sense_bags import (
    BagError,
    BagReader,
    BagWriter,
    ground_truth,
    make_message,
    make_typestore,
    recover_bag,
    taxel_event_batch,
    type_hash,
)

PRE_FLAG = Path(__file__).parent / "data" / "pre_flag"
CHANGED = {
    "/extsense/nuskin/events": "ext_sense_msgs/msg/TaxelEventBatch",
    "/extsense/contact_window": "ext_sense_msgs/msg/ContactWindow",
    "/extsense/contact_estimate": "ext_sense_msgs/msg/ContactEstimate",
}
EVENTS, WINDOW, ESTIMATE = CHANGED
BATCH = CHANGED[EVENTS]
TRUTH = "/extsense/ground_truth"
T0 = 1_700_000_000_000_000_000
STEP_NS = 1_000_000


@pytest.fixture(scope="module")
def old_store() -> Typestore:
    """The kilted store with the pre-flag ext_sense definitions (as a HEAD-era recorder had)."""
    store = get_typestore(Stores.ROS2_KILTED)
    types = {}
    for msgtype in CHANGED.values():
        text = (PRE_FLAG / f"{msgtype.rsplit('/', 1)[1]}.msg").read_text(encoding="utf-8")
        types.update(get_types_from_msg(text, msgtype))
    store.register(types)
    return store


def _old(store: Typestore, msgtype: str, **fields: object) -> object:
    """A message of the pre-flag definition: the given fields, ROS defaults for the rest."""
    current = make_message(msgtype)  # defaults for the fields both definitions share
    names = [name for name, _ in store.fielddefs[msgtype][1]]
    assert set(fields) <= set(names), sorted(set(fields) - set(names))
    return store.types[msgtype](**{n: fields.get(n, getattr(current, n)) for n in names})


def _old_batch(store: Typestore, i: int) -> object:
    n = 1 + i % 5
    return _old(
        store,
        BATCH,
        header=make_message("std_msgs/msg/Header", frame_id="nuskin"),
        taxel=np.arange(1, n + 1, dtype=np.uint16),
        polarity=np.ones(n, np.int8),
        value=np.full(n, i, np.uint16),
        offset_ns=np.arange(n, dtype=np.int64) * 1000,
        words_total=np.uint64(i),
    )


def _register_old(bag: BagWriter, store: Typestore) -> None:
    for topic, msgtype in CHANGED.items():
        msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
        bag.add_topic(topic, msgtype, definition=(msgdef, store.hash_rihs01(msgtype)))


def _write_old(bag: BagWriter, store: Typestore, n: int = 12) -> None:
    """``n`` pre-flag batches, one ground truth (unchanged type), a window and an estimate."""
    _register_old(bag, store)
    for i in range(n):
        bag.write_raw(EVENTS, T0 + i * STEP_NS, store.serialize_cdr(_old_batch(store, i), BATCH))
    bag.write(TRUTH, T0 + 3 * STEP_NS, ground_truth(T0, "tap_localization", 7, tap_position_m=0.1))
    window = _old(store, CHANGED[WINDOW], provisional=True, truncated=True, sensor="nuskin")
    estimate = _old(store, CHANGED[ESTIMATE], task="tap_localization", tap_position_m=0.25)
    bag.write_raw(WINDOW, T0 + n * STEP_NS, store.serialize_cdr(window, CHANGED[WINDOW]))
    bag.write_raw(ESTIMATE, T0 + n * STEP_NS, store.serialize_cdr(estimate, CHANGED[ESTIMATE]))


def _old_bag(path: Path, store: Typestore, storage: str = "mcap") -> Path:
    with BagWriter(path, storage=storage) as bag:
        _write_old(bag, store)
    return path


def _check_old_contents(path: Path, store: Typestore) -> None:
    """Every message decodes with the fields as recorded; the topics keep the old hashes."""
    with BagReader(path) as bag:
        for topic, msgtype in CHANGED.items():
            assert bag.topics[topic].type_hash == store.hash_rihs01(msgtype) != type_hash(msgtype)
        batches = [(rec, msg) for rec, msg in bag.messages([EVENTS])]
        assert len(batches) == 12
        for i, (rec, msg) in enumerate(batches):
            assert bag.differs(rec.msgtype)
            assert msg.value.tolist() == [i] * (1 + i % 5)
            assert msg.offset_ns.tolist() == [k * 1000 for k in range(1 + i % 5)]
            assert int(msg.words_total) == i
            assert msg.header.frame_id == "nuskin"
            assert not hasattr(msg, "flag")  # as recorded: the field did not exist
        ((_, window),) = bag.messages([WINDOW])
        assert window.provisional
        assert window.truncated
        assert window.sensor == "nuskin"
        assert getattr(window, "degraded", False) is False
        ((_, estimate),) = bag.messages([ESTIMATE])
        assert (estimate.task, estimate.tap_position_m) == ("tap_localization", 0.25)
        assert not hasattr(estimate, "degraded_reason")
        ((rec, truth),) = bag.messages([TRUTH])
        assert not bag.differs(rec.msgtype)
        assert truth.trial == 7


def test_the_pre_flag_definitions_really_differ(old_store):
    """The fixture is what broke: the current store cannot read a pre-flag batch."""
    data = old_store.serialize_cdr(_old_batch(old_store, 3), BATCH)
    with pytest.raises(Exception, match=r"buffer|unpack|bytes"):
        make_typestore().deserialize_cdr(data, BATCH)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_recorded_before_the_change_decodes_as_recorded(tmp_path, old_store, storage):
    _check_old_contents(_old_bag(tmp_path / "old", old_store, storage), old_store)


def test_a_bag_of_plain_rosbags_with_the_old_definitions_decodes(tmp_path, old_store):
    """rosbags' own Writer (no hash in the mcap channels: only in metadata.yaml) as recorder."""
    with Writer(tmp_path / "plain", version=9) as writer:
        conn = writer.add_connection(EVENTS, BATCH, typestore=old_store)
        writer.write(conn, T0, old_store.serialize_cdr(_old_batch(old_store, 4), BATCH))
    with BagReader(tmp_path / "plain") as bag:
        ((_, msg),) = bag.messages()
        assert msg.value.tolist() == [4] * 5
        assert not hasattr(msg, "flag")


def test_a_current_bag_decodes_with_the_current_store(tmp_path):
    batch = make_message(BATCH, taxel=[3, 4], polarity=[1, -1], value=[9, 9], offset_ns=[0, 5])
    batch.flag = np.array([1, 0], np.uint8)
    with BagWriter(tmp_path / "new") as bag:
        bag.write(EVENTS, T0, batch)
    with BagReader(tmp_path / "new") as bag:
        ((rec, msg),) = bag.messages()
        assert not bag.differs(rec.msgtype)
        assert msg.flag.tolist() == [1, 0]
        assert msg.taxel.tolist() == [3, 4]
        assert bag.current_cdr(rec) == rec.data  # passed through untouched


def test_old_messages_convert_to_the_current_type_with_new_fields_at_defaults(tmp_path, old_store):
    """What a replay into a live graph publishes: bytes a current subscriber can read."""
    current = make_typestore()
    with BagReader(_old_bag(tmp_path / "old", old_store)) as bag:
        for i, rec in enumerate(bag.records([EVENTS])):
            msg = current.deserialize_cdr(bag.current_cdr(rec), BATCH)
            assert msg.value.tolist() == [i] * (1 + i % 5)
            assert msg.flag.size == 0
        ((rec, old),) = bag.messages([WINDOW])
        msg = current.deserialize_cdr(bag.current_cdr(rec), CHANGED[WINDOW])
        assert msg.provisional
        assert msg.truncated
        assert msg.sensor == "nuskin"
        assert (msg.degraded, msg.degraded_reason) == (False, "")
        assert to_current(old, CHANGED[WINDOW]).sensor == "nuskin"


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_crashed_old_bag_decodes_and_recovers_with_its_own_definitions(
    tmp_path, old_store, storage
):
    src = tmp_path / "src"
    bag = BagWriter(src, storage=storage, flush_period_s=1e9).open()
    _write_old(bag, old_store)
    bag.flush()
    crashed = tmp_path / "crashed"
    shutil.copytree(src, crashed)  # what a killed recorder leaves: flushed, never closed
    bag.close()
    with BagReader(crashed) as salvaged:
        assert salvaged.salvaged  # read through the salvage path
    _check_old_contents(crashed, old_store)
    result = recover_bag(crashed, tmp_path / "recovered")
    assert result.messages == 15
    assert not result.skipped_topics
    _check_old_contents(tmp_path / "recovered", old_store)
    with Reader(tmp_path / "recovered") as reader:  # the old definitions, stored verbatim
        for conn in reader.connections:
            if conn.msgtype in CHANGED.values():
                assert conn.msgdef.data == old_store.generate_msgdef(conn.msgtype, ros_version=2)[0]
                assert conn.digest == old_store.hash_rihs01(conn.msgtype)


def test_recover_without_a_stored_hash_takes_it_from_the_stored_definition(tmp_path, old_store):
    """An mcap of rosbags' plain Writer keeps its hash only in metadata.yaml, lost in a crash."""
    with Writer(tmp_path / "plain", version=9) as writer:
        conn = writer.add_connection(EVENTS, BATCH, typestore=old_store)
        writer.write(conn, T0, old_store.serialize_cdr(_old_batch(old_store, 2), BATCH))
    (tmp_path / "plain" / "metadata.yaml").unlink()
    result = recover_bag(tmp_path / "plain", tmp_path / "out")
    assert result.messages == 1
    with BagReader(tmp_path / "out") as bag:
        assert bag.topics[EVENTS].type_hash == old_store.hash_rihs01(BATCH)
        ((_, msg),) = bag.messages()
        assert msg.value.tolist() == [2, 2, 2]


def test_without_a_stored_definition_the_error_says_so(tmp_path, old_store):
    """The bag names an old hash but holds no definition: the current store, a clear error."""
    path = _old_bag(tmp_path / "old", old_store, "sqlite3")
    with sqlite3.connect(next(path.glob("*.db3"))) as db:
        db.execute("DELETE FROM message_definitions WHERE topic_type = ?", (BATCH,))
    with BagReader(path) as bag:
        rec = next(bag.records([EVENTS]))
        with pytest.raises(BagError, match=r"recorded it with another definition.*no definition"):
            bag.decode(rec)
        ((_, truth),) = bag.messages([TRUTH])  # the other topics are unaffected
        assert truth.trial == 7


def test_a_bag_with_an_unparsable_definition_gives_a_clear_error(tmp_path, old_store):
    """The bag's own definitions build its typestore: one that does not parse is named."""
    with BagWriter(tmp_path / "broken") as bag:
        digest = old_store.hash_rihs01(BATCH)
        bag.add_topic(EVENTS, BATCH, definition=("uint8[ broken", digest))
        bag.write_raw(EVENTS, T0, old_store.serialize_cdr(_old_batch(old_store, 1), BATCH))
    with pytest.raises(BagError, match=r"Cannot read bag .*broken"):
        BagReader(tmp_path / "broken").open()


def test_an_old_simulator_bag_gives_the_same_windows(tmp_path, old_store):
    """Training data: an old bag windows exactly as its current-definition twin (the simulator's
    events in 1 ms batches, as a driver publishing decoded arrays sent them)."""
    from ext_sense_perception.data.bags import window_set_from_bag
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    run_scene(load_scene("tap_rod30_nuskin"), tmp_path / "sim", trials=3, formats=("npz",))
    d = np.load(tmp_path / "sim" / "dataset.npz")
    t = T0 + d["ev_trial"].astype(np.int64) * int(d["trial_ns"]) + d["ev_t_ns"]
    order = np.argsort(t, kind="stable")
    t, taxel, polarity, value = (
        t[order],
        *(d[k][order] for k in ("ev_taxel", "ev_polarity", "ev_value")),
    )
    new, old = tmp_path / "new", tmp_path / "old"
    with BagWriter(new) as cur, BagWriter(old) as dst:
        for bag in (cur, dst):
            bag.set_custom_data("task", "tap_localization")
            bag.set_custom_data("sensor", "nuskin")
        _register_old(dst, old_store)
        for i in range(len(d["y"])):
            onset = T0 + i * int(d["trial_ns"]) + int(d["onset_ns"][i])
            truth = ground_truth(
                onset, "tap_localization", i, tap_position_m=float(d["y"][i]), rod_length_m=0.3
            )
            cur.write(TRUTH, onset, truth)
            dst.write(TRUTH, onset, truth)
        bins = t // STEP_NS
        edges = np.flatnonzero(np.diff(bins)) + 1
        for lo, hi in zip(np.r_[0, edges], np.r_[edges, t.size], strict=True):
            stamp = int(bins[lo]) * STEP_NS
            batch = taxel_event_batch(
                stamp, taxel[lo:hi], polarity[lo:hi], value[lo:hi], t[lo:hi] - stamp
            )
            cur.write(EVENTS, stamp + STEP_NS, batch)
            fields = {n: getattr(batch, n) for n, _ in old_store.fielddefs[BATCH][1]}
            data = old_store.serialize_cdr(old_store.types[BATCH](**fields), BATCH)
            dst.write_raw(EVENTS, stamp + STEP_NS, data)
    with BagReader(old) as bag:
        assert bag.topics[EVENTS].type_hash != type_hash(BATCH)
        assert bag.topics[EVENTS].count > 100
    ws_new, counts_new = window_set_from_bag(new)
    ws_old, counts_old = window_set_from_bag(old)
    assert counts_old == counts_new
    assert counts_old.undecodable == 0
    assert counts_old.labelled == 3
    np.testing.assert_array_equal(ws_old.X, ws_new.X)
    np.testing.assert_array_equal(ws_old.y, ws_new.y)
    shutil.rmtree(tmp_path / "sim")
