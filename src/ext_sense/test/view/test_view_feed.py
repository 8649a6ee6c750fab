"""The view's sensor input (no ROS): packets decoded with the drivers' library, the picture of
the words and frames they carry, gaps and bad packets counted."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from ext_sense_bags.messages import sensor_packet

from ext_sense.view.errors import ViewError
from ext_sense.view.feed import MAX_DECODERS, SensorFeed
from ext_sense.view.taxels import N_TAXELS, ElectrodeActivity, TaxelActivity
from ext_sense.view.traces import PacTrace
from ext_sense_drivers.biotac.encoder import encode_standard_frame
from ext_sense_drivers.nuskin.wire import encode_words
from ext_sense_drivers.packets import (
    BIOTAC_BRIDGE_V1,
    NUSKIN_WORDS_V1,
    Packet,
    PacketPacker,
)
from ext_sense_drivers.transports.base import Chunk
from ext_sense_runtime.diagnostics import Level

OPTIONS = "baud=4000000;flag_polarity=ignore"
T0 = 1_000_000_000


def _feed(sensor: str = "nuskin") -> SensorFeed:
    return SensorFeed(sensor, TaxelActivity(), ElectrodeActivity(), PacTrace())


def _word_packets(
    n_words: int = 600, n_reads: int = 60, connection: int = 1, seed: int = 1
) -> tuple[list[Packet], np.ndarray]:
    """A NUSkin word stream cut at random bytes (words split across reads and packets), packed
    as the driver packs it (one packet per 3 reads); and the taxel ids it carries."""
    rng = np.random.default_rng(seed)
    taxel = rng.integers(1, N_TAXELS + 1, n_words)
    data = encode_words(taxel, rng.integers(0, 1024, n_words))
    cuts = np.sort(rng.choice(np.arange(1, len(data)), n_reads - 1, replace=False))
    parts = np.split(np.frombuffer(data, np.uint8), cuts)
    times = T0 + np.cumsum(rng.integers(20_000, 900_000, n_reads))
    reads = [(connection, Chunk(p.tobytes(), int(t))) for p, t in zip(parts, times, strict=True)]
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    packets = []
    for lo in range(0, n_reads, 3):
        packets += packer.pack(reads[lo : lo + 3], link_down=False)
    return packets, taxel


def test_packets_draw_every_word_they_carry_once() -> None:
    packets, taxel = _word_packets()
    feed = _feed()
    for p in packets:
        feed.on_packet(sensor_packet(p, "nuskin"))
    want = np.bincount(taxel - 1, minlength=N_TAXELS)
    assert feed.taxels.counts.tolist() == want.tolist()  # every word, once
    assert feed.counters.events == taxel.size
    level, message, values = feed.status()
    assert (level, message) == (Level.OK, "reading packets")
    assert values["packets"] == len(packets)
    assert values["lost_packets"] == values["dropped_bad_packets"] == 0
    assert _feed().status()[1] == "waiting for packets"


def test_packets_of_the_biotac_feed_the_electrodes_and_pac_of_their_frames() -> None:
    rng = np.random.default_rng(3)
    frames = [
        (seq, sid, rng.integers(0, 4096, 22), rng.integers(1, 4095, 19))
        for seq in range(30)
        for sid in (0, 1)
    ]
    data = b"".join(encode_standard_frame(q, s, pac, el, 1, 2, 3) for q, s, pac, el in frames)
    cuts = np.linspace(0, len(data), 25).astype(int)
    spans = enumerate(itertools.pairwise(cuts))
    reads = [(1, Chunk(data[a:b], T0 + k * 1_000_000)) for k, (a, b) in spans]
    packets = PacketPacker(BIOTAC_BRIDGE_V1).pack(reads, link_down=True)
    feed = _feed("biotac")
    for p in packets:
        feed.on_packet(p)
    electrodes, pac = ElectrodeActivity(), PacTrace()  # fed the frames themselves
    for _, sid, samples, el in frames:
        electrodes.add(sid, np.asarray(el))
        pac.add(sid, np.asarray(samples))
    assert feed.counters.frames == len(frames)
    assert feed.electrodes.sensors() == [0, 1]
    for sid in (0, 1):
        assert feed.electrodes.latest[sid].tolist() == electrodes.latest[sid].tolist()
        assert feed.electrodes.baseline(sid).tolist() == electrodes.baseline(sid).tolist()
    assert feed.pac.message() == pac.message()


def test_a_seq_gap_is_counted_and_the_stream_goes_on() -> None:
    packets, _ = _word_packets()
    feed = _feed()
    for k, p in enumerate(packets):
        if k not in (4, 5, 6):
            feed.on_packet(p)
        if k == 7:
            assert feed.last_lost_packets == 3
    assert feed.counters.lost_packets == 3
    assert feed.last_lost_packets == 0
    assert feed.status()[2]["lost_packets"] == 3
    # the packets after the gap are drawn: every one of theirs but a word cut at its edge
    words_after = sum(len(p.data) for p in packets[7:]) // 4
    drawn_after = feed.counters.events - sum(len(p.data) for p in packets[:4]) // 4
    assert drawn_after >= words_after - 1


def test_a_bad_packet_is_a_counted_drop_on_the_diagnostics_never_an_exception() -> None:
    packets, taxel = _word_packets()
    feed = _feed()
    feed.on_packet(packets[0]._replace(read_end=packets[0].read_end + 3))  # arrays disagree
    assert feed.counters.bad_packets == 1
    assert "read_end must rise to len" in feed.last_packet_error
    level, message, values = feed.status()
    assert level is Level.WARN
    assert message.startswith("dropped 1 bad packet(s): ")
    assert values["dropped_bad_packets"] == 1
    feed.on_packet(packets[1]._replace(encoding="evt3"))
    assert "Unknown packet encoding 'evt3'" in feed.last_packet_error
    feed.on_packet(packets[1]._replace(encoding=BIOTAC_BRIDGE_V1))  # another sensor's packet
    assert "the nuskin view reads" in feed.last_packet_error
    feed.on_packet(packets[1]._replace(options="baud=4000000;parity=odd"))
    assert "not known to this decoder" in feed.last_packet_error
    assert feed.counters.bad_packets == 4
    for p in packets:  # the stream itself is read on
        feed.on_packet(p)
    assert feed.taxels.counts.sum() == taxel.size


def test_streams_on_other_connections_are_decoded_apart() -> None:
    """Two publishers on one topic (a driver and a test's flood) each keep their stream."""
    one, taxel_one = _word_packets(connection=1, seed=1)
    two, taxel_two = _word_packets(connection=7, seed=2)
    feed = _feed()
    for a, b in zip(one, two, strict=True):
        feed.on_packet(a)
        feed.on_packet(b)
    assert feed.counters.lost_packets == 0
    assert feed.taxels.counts.sum() == taxel_one.size + taxel_two.size
    for connection in range(100, 100 + MAX_DECODERS):  # old streams' decoders are let go
        feed.on_packet(one[0]._replace(connection=connection))
    assert len(feed._decoders) == MAX_DECODERS


def test_an_unknown_sensor_is_refused() -> None:
    with pytest.raises(ViewError, match="The 'sensor' parameter must be one of"):
        _feed("gelsight")
