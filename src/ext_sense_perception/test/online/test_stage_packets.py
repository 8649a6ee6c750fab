"""The window stage on raw packets: the driver's events, loss and damage counted, BioTac frames."""

from __future__ import annotations

import numpy as np

from ext_sense_drivers.biotac.encoder import encode_standard_frame
from ext_sense_drivers.nuskin.wire import encode_words
from ext_sense_drivers.packets import (
    BIOTAC_BRIDGE_V1,
    NUSKIN_WORDS_V1,
    PacketPacker,
    make_decoder,
)
from ext_sense_drivers.transports.base import Chunk
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.window import WindowConfig

MS = 1_000_000
T0 = 5_000_000_000
OPTIONS = "baud=4000000;flag_polarity=ignore"


def _tap_packets(onsets_ms=(100, 700), end_ms=1300):
    """One packet per ms of receiver words: a burst of 40 taxels for 30 ms at each onset."""
    rng = np.random.default_rng(2)
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    packets = []
    for ms in range(end_ms):
        n = 60 if any(0 <= ms - o < 30 for o in onsets_ms) else int(rng.random() < 0.05)
        if not n:
            continue
        data = encode_words(rng.integers(1, 81, n), rng.integers(0, 1024, n))
        packets += packer.pack([(1, Chunk(data, T0 + ms * MS))], link_down=False)
    return packets


def test_packets_cut_the_windows_of_the_events_they_decode_to():
    config = WindowConfig.for_task("tap_localization", "nuskin")
    packets = _tap_packets()
    stage = WindowStage(config)
    by_packet = [w for p in packets for w in stage.on_packet(p)]
    by_packet += stage.flush()
    decoder = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    ref = WindowStage(config)
    by_block = []
    for p in packets:
        d = decoder.decode(p)
        by_block += ref.on_block(d.events, complete_ns=d.complete_ns)
    by_block += ref.flush()
    assert sum(not w.provisional for w in by_packet) == 2
    assert [w.onset_ns for w in by_packet] == [w.onset_ns for w in by_block]
    for a, b in zip(by_packet, by_block, strict=True):
        assert np.array_equal(a.data, b.data)
    assert stage.counters.packets == len(packets)
    assert stage.counters.lost_packets == 0


def test_a_gap_and_a_bad_packet_are_counted_never_raised():
    config = WindowConfig.for_task("tap_localization", "nuskin")
    packets = _tap_packets()
    stage = WindowStage(config)
    stage.on_packet(packets[0])
    stage.on_packet(packets[3])
    assert stage.last_lost_packets == 2
    assert stage.on_packet(packets[4]._replace(read_end=np.array([1], np.uint32))) == []
    assert stage.counters.bad_packets == 1
    assert "read_end" in stage.last_packet_error
    assert stage.on_packet(packets[4]._replace(encoding="evt3")) == []
    assert "Unknown packet encoding" in stage.last_packet_error
    assert stage.counters.lost_packets == 2


def test_biotac_packets_give_the_frames_to_the_pac_windower():
    config = WindowConfig.for_task("tap_localization", "biotac")
    packer = PacketPacker(BIOTAC_BRIDGE_V1, "clock_window_frames=200;lead_ns=10000000")
    stage = WindowStage(config)
    pac = np.full(22, 2000)
    for seq in range(50):
        frame = encode_standard_frame(seq, 0, pac, np.zeros(19, int), 0, 0, 0)
        for p in packer.pack([(1, Chunk(frame, T0 + seq * 10 * MS))], link_down=False):
            stage.on_packet(p)
    assert stage.counters.frames == 50
    assert stage.counters.bad_packets == 0
    assert stage.last_data_ns is not None


def test_a_silent_receiver_first_tap_is_whole_when_the_driver_said_the_link_opened():
    """The emulated receiver sends nothing until the first tap: its window began before the
    first word and was judged "joined mid-stream", unless the driver's packet at the link's
    open (``PacketPacker.opened``) says the stream was there, silent, from then on."""
    config = WindowConfig.for_task("tap_localization", "nuskin")
    rng = np.random.default_rng(3)

    def first_tap(opened: bool) -> list:
        packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
        packets = [packer.opened(1, T0 - 2_000 * MS)] if opened else []
        for ms in range(400):  # the tap at T0, then the silent receiver's end of the window
            n = 60 if ms < 30 else 0
            data = encode_words(rng.integers(1, 81, n), rng.integers(0, 1024, n))
            packets += packer.pack([(1, Chunk(data, T0 + ms * MS))], link_down=False)
        packets.append(packer.nothing_read(T0 + 400 * MS))
        stage = WindowStage(config)
        return [w for p in packets for w in stage.on_packet(p) if not w.provisional]

    [without] = first_tap(opened=False)
    assert without.degraded
    assert without.degraded_reason.startswith("joined mid-stream")
    [whole] = first_tap(opened=True)
    assert not whole.degraded, whole.degraded_reason
    assert whole.onset_ns == without.onset_ns
