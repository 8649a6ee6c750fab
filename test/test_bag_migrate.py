"""``ext-sense bag migrate``: bags of decoded arrays from before packets, as packet bags.

On bags the previous code wrote (``src/ext_sense_bags/test/data/bb1956e``: decoded
``TaxelEventBatch`` messages beside estimates and ground truths) and on a tap recording of the
old message type written through rosbags: the packets decode, with the library decoder, to the
recorded events (each word within its transmission time of its recorded time), every other
message is copied as it was, and the current graph's core replays the migrated bag.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from synthetic import MS, T0, CountingModel
from test_record_replay import write_old_tap_bag

from ext_sense.bag_migrate import migrate_bag
from ext_sense_bags import BagError, BagReader, biotac_frame
from ext_sense_drivers.packets import make_decoder
from ext_sense_runtime.stamps import stamp_to_ns

OLD = Path(__file__).resolve().parents[1] / "src/ext_sense_bags/test/data/bb1956e"
EVENTS, PACKETS = "/extsense/nuskin/events", "/extsense/nuskin/packets"
WORD_NS = 10_000
"""One receiver word's transmission at 4 Mbaud (40 bits)."""


def _events(bag: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, taxels, values) of every event the bag's decoded arrays hold."""
    t, k, v = [], [], []
    with BagReader(bag) as reader:
        for _, msg in reader.messages([EVENTS]):
            t += (np.asarray(msg.offset_ns, np.int64) + stamp_to_ns(msg.header.stamp)).tolist()
            k += np.asarray(msg.taxel).tolist()
            v += np.asarray(msg.value).tolist()
    return np.asarray(t), np.asarray(k), np.asarray(v)


def _decoded(bag: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """(times, taxels, values) decoded from the bag's packets, and the packets."""
    with BagReader(bag) as reader:
        packets = [msg for _, msg in reader.messages([PACKETS])]
    decoder = make_decoder(str(packets[0].encoding), str(packets[0].encoding_options))
    blocks = [decoder.decode(p).events for p in packets]
    assert decoder.counters.lost_packets == 0
    cat = [np.concatenate([getattr(b, f) for b in blocks]) for f in ("t_ns", "taxel", "value")]
    return (*cat, packets)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_the_old_code_wrote_decodes_to_its_events_from_packets(storage, tmp_path):
    src = OLD / storage
    done = migrate_bag(src, tmp_path / "new")
    t, taxel, value = _events(src)
    got_t, got_taxel, got_value, packets = _decoded(tmp_path / "new")
    order = np.argsort(t, kind="stable")
    assert got_taxel.tolist() == taxel[order].tolist()
    assert got_value.tolist() == value[order].tolist()
    late = t[order] - got_t  # a word is stamped at most its read's transmission before its time
    assert (late >= 0).all()
    assert late.max() <= 5 * WORD_NS
    assert done.events == taxel.size
    assert packets[-1].end_of_stream  # the stream ends with the recording
    with BagReader(src) as old, BagReader(tmp_path / "new") as new:
        assert EVENTS not in new.topics
        for topic in set(old.topics) - {EVENTS}:  # the rest as recorded
            assert [r.data for r in new.records([topic])] == [r.data for r in old.records([topic])]
            assert done.copied[topic] == old.topics[topic].count


def test_a_migrated_tap_recording_replays_its_taps_and_feeds_a_graph(tmp_path):
    from ext_sense.graphs import GRAPHS
    from ext_sense.offline_replay import offline_estimates
    from ext_sense_perception.online.stage import WindowStage
    from ext_sense_perception.online.window import WindowConfig

    write_old_tap_bag(tmp_path / "old")  # TaxelEventBatch through rosbags, as before packets
    migrate_bag(tmp_path / "old", tmp_path / "new")
    config = WindowConfig.for_task("tap_localization", "nuskin")
    estimates = [
        item
        for kind, item in offline_estimates(tmp_path / "new", config, CountingModel())
        if kind == "estimate" and not item.provisional
    ]
    onsets_ms = np.array([(e.onset_ns - T0) / MS for e in estimates])
    assert np.abs(onsets_ms - [100, 800, 1500]).max() <= 1.0, onsets_ms
    stage = WindowStage(config)  # the windows close on the packets, not at the bag's end
    with BagReader(tmp_path / "new") as reader:
        windows = [w for _, m in reader.messages([PACKETS]) for w in stage.on_packet(m)]
    finals = [w for w in windows if not w.provisional]
    assert len(finals) == 3
    assert not any(w.truncated or w.degraded for w in finals)
    graph = GRAPHS["tap_localization"]
    graph.check_files({**graph.resolve({"source": "bag"}), "bag": str(tmp_path / "new")})


def test_biotac_frames_become_bridge_packets_that_decode_to_them(tmp_path):
    from ext_sense_bags import BagWriter

    pac = [np.arange(22) * 7 % 4096 + s for s in range(5)]
    el = [np.arange(19) * 5 % 4096 + 1 for _ in range(5)]
    with BagWriter(tmp_path / "old") as bag:
        for seq in range(5):
            t = T0 + seq * 10 * MS
            frame = biotac_frame(t, pac[seq], el[seq], 1, 2, 3, sensor_id=0, sequence=seq)
            bag.write("/extsense/biotac/frames", t + MS, frame)
    done = migrate_bag(tmp_path / "old", tmp_path / "new")
    assert done.frames == 5
    with BagReader(tmp_path / "new") as reader:
        packets = [msg for _, msg in reader.messages(["/extsense/biotac/packets"])]
    decoder = make_decoder(str(packets[0].encoding), str(packets[0].encoding_options))
    frames = [f for p in packets for f in decoder.decode(p).frames]
    assert [f.sequence for f in frames] == list(range(5))
    assert [f.pac.tolist() for f in frames] == [p.tolist() for p in pac]
    assert [f.electrodes.tolist() for f in frames] == [e.tolist() for e in el]


def test_bad_input_is_one_clear_error(tmp_path, capsys):
    from ext_sense import cli

    write_old_tap_bag(tmp_path / "old")
    migrate_bag(tmp_path / "old", tmp_path / "new")
    with pytest.raises(BagError, match="holds packets already"):
        migrate_bag(tmp_path / "new", tmp_path / "again")
    with pytest.raises(BagError, match="exists: give a new directory"):
        migrate_bag(tmp_path / "old", tmp_path / "new")
    assert cli.main(["bag", "migrate", str(tmp_path / "nothing"), str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ext-sense bag migrate: ")
    assert "\n" not in err
    assert cli.main(["bag", "migrate", str(tmp_path / "old"), str(tmp_path / "cli")]) == 0
    assert f"{PACKETS}: " in capsys.readouterr().out
