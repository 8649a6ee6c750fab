"""Packets: packing a driver's reads, decoding them as the driver would, loss and damage."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.streams import FlaggedEvents, WordStream
from ext_sense_drivers.nuskin.wire import FlagPolarity, encode_words
from ext_sense_drivers.packets import (
    BIOTAC_BRIDGE_V1,
    NUSKIN_WORDS_V1,
    PacketError,
    PacketPacker,
    QuietSchedule,
    make_decoder,
    parse_options,
)
from ext_sense_drivers.transports.base import Chunk

OPTIONS = "baud=4000000;flag_polarity=ignore"
T0 = 1_000_000_000


def _reads(n_reads: int = 40, seed: int = 1) -> list[Chunk]:
    """A word stream cut at random byte positions (words split across reads)."""
    rng = np.random.default_rng(seed)
    n = 400
    data = encode_words(rng.integers(1, 81, n), rng.integers(0, 1024, n))
    cuts = np.sort(rng.choice(np.arange(1, len(data)), n_reads - 1, replace=False))
    parts = np.split(np.frombuffer(data, np.uint8), cuts)
    times = T0 + np.cumsum(rng.integers(20_000, 900_000, n_reads))
    return [Chunk(p.tobytes(), int(t)) for p, t in zip(parts, times, strict=True)]


def _driver_events(reads: list[Chunk]):
    """What the driver decoded before packets: one WordStream fed read by read."""
    stream = WordStream(FlagPolarity.IGNORE, ArrivalClock.for_baud(4_000_000))
    return FlaggedEvents.concat([stream.feed_flagged(r) for r in reads])


def test_packets_decode_to_exactly_the_driver_events():
    reads = _reads()
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    packets = []
    for lo in range(0, len(reads), 7):  # one drain every 7 reads, all on connection 1
        packets += packer.pack([(1, r) for r in reads[lo : lo + 7]], link_down=False)
    assert [p.seq for p in packets] == list(range(len(packets)))
    decoder = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    decoded = [decoder.decode(p) for p in packets]
    got = FlaggedEvents.concat([FlaggedEvents(d.events, d.flag) for d in decoded])
    want = _driver_events(reads)
    for a, b in zip(got.events, want.events, strict=True):
        assert a.tolist() == b.tolist()
    assert got.flag.tolist() == want.flag.tolist()
    # stream time is complete up to each packet's last read: no later event is earlier
    for d, nxt in itertools.pairwise(decoded):
        assert nxt.events.size == 0 or int(nxt.events.t_ns.min()) > d.complete_ns
    assert decoder.counters.lost_packets == 0


def test_a_seq_gap_is_counted_and_restarts_the_byte_stream():
    reads = _reads()
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    packets = [packer.pack([(1, r)], link_down=False)[0] for r in reads]
    decoder = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    lost = [decoder.decode(p).lost_packets for i, p in enumerate(packets) if i not in (5, 6)]
    assert sum(lost) == 2
    assert decoder.counters.lost_packets == 2
    assert decoder.diagnostics()["lost_packets"] == 2
    assert decoder.counters.driver_restarts == 0
    assert decoder.decode(packets[0]).lost_packets == 0  # a smaller seq: a restarted driver
    assert decoder.counters.driver_restarts == 1


def test_a_malformed_packet_is_refused_with_a_reason_and_counted():
    packet = PacketPacker(NUSKIN_WORDS_V1, OPTIONS).pack([(1, _reads()[0])], False)[0]
    decoder = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    bad = packet._replace(read_end=packet.read_end + 3)
    with pytest.raises(PacketError, match="read_end must rise to len"):
        decoder.decode(bad)
    other = packet._replace(encoding=BIOTAC_BRIDGE_V1)
    with pytest.raises(PacketError, match="this decoder reads"):
        decoder.decode(other)
    assert decoder.counters.bad_packets == 2
    assert decoder.decode(packet).events.size >= 0  # the decoder goes on


def test_unknown_encodings_and_options_are_clear_errors():
    with pytest.raises(PacketError, match="Unknown packet encoding"):
        make_decoder("evt3")
    with pytest.raises(PacketError, match="not known to this decoder"):
        make_decoder(NUSKIN_WORDS_V1, "baud=9600;parity=odd")
    with pytest.raises(PacketError, match="key=value"):
        parse_options("baud", ("baud",))


def test_a_lost_link_ends_the_stream_once_and_a_reconnect_starts_a_new_one():
    reads = _reads(6)
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    first = packer.pack([(1, r) for r in reads[:3]], link_down=True)
    assert [p.end_of_stream for p in first] == [True]
    assert packer.pack([], link_down=True) == []  # already ended
    second = packer.pack([(2, r) for r in reads[3:]], link_down=False)
    assert second[0].connection == 2
    assert not second[0].end_of_stream


def test_a_nothing_read_packet_says_where_stream_time_is_and_leaves_the_clock_alone():
    """The driver's empty packet after its last bytes: stream time is complete up to it, and
    the next read's words are stamped exactly as without it (spread over the time since the
    previous read: they may have waited in the kernel while the reader did not run)."""
    reads = _reads(6)
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    assert packer.nothing_read(T0) is None  # no stream yet: nothing to say
    [first] = packer.pack([(1, r) for r in reads[:3]], link_down=False)
    quiet_ns = reads[2].t_ns + 500_000
    empty = packer.nothing_read(quiet_ns)
    assert (empty.seq, empty.connection, empty.data, empty.end_of_stream) == (1, 1, b"", False)
    assert empty.read_end.size == 0
    assert empty.stamp_ns == empty.end_ns == quiet_ns
    later = reads[3]._replace(t_ns=quiet_ns + 200_000)  # 0.2 ms after it, under the 1 ms cap
    [after] = packer.pack([(1, later)], link_down=False)
    decoder = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    decoded = [decoder.decode(p) for p in (first, empty, after)]
    assert decoded[1].events.size == 0
    assert decoded[1].complete_ns == quiet_ns
    assert decoder.counters.lost_packets == 0
    without = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    without.decode(first)
    alone = without.decode(after._replace(seq=1))
    assert decoded[2].events.t_ns.tolist() == alone.events.t_ns.tolist()
    assert int(decoded[2].events.t_ns.min()) < quiet_ns  # spread back past it, as without it
    assert packer.pack([], link_down=True)[0].end_of_stream
    assert packer.nothing_read(quiet_ns + 10**9) is None  # the stream ended
    aces = PacketPacker("aces-line-v1", "threshold=0.5")
    aces.pack([(1, Chunk(b"\x00\x01" * 8, T0))], link_down=False)
    assert aces.nothing_read(T0 + 10**6) is None  # the line streams samples all the time


def test_an_opened_packet_says_where_the_stream_began_and_leaves_the_clock_alone():
    """The driver's empty packet at the link's open: the stream is known from there, and the
    words that follow are stamped exactly as without it."""
    reads = _reads(6)
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    opened = packer.opened(1, T0 - 2 * 10**9)
    assert (opened.seq, opened.connection, opened.data, opened.end_of_stream) == (0, 1, b"", False)
    assert opened.stamp_ns == opened.end_ns == T0 - 2 * 10**9
    assert packer.opened(1, T0) is None  # said once per connection
    [first] = packer.pack([(1, r) for r in reads[:3]], link_down=False)
    assert (first.seq, first.connection) == (1, 1)
    decoder = make_decoder(NUSKIN_WORDS_V1, OPTIONS)
    assert decoder.decode(opened).complete_ns == opened.stamp_ns
    got = decoder.decode(first)
    assert decoder.counters.lost_packets == 0
    alone = make_decoder(NUSKIN_WORDS_V1, OPTIONS).decode(first._replace(seq=0))
    assert got.events.t_ns.tolist() == alone.events.t_ns.tolist()
    assert packer.nothing_read(reads[2].t_ns + 10**6) is not None  # a stream going
    assert packer.pack([], link_down=True)[0].end_of_stream
    again = packer.opened(2, T0 + 10**9)  # a reconnect: a new stream, said once more
    assert (again.connection, again.end_of_stream) == (2, False)
    assert PacketPacker("aces-line-v1", "threshold=0.5").opened(1, T0) is None  # samples flow


def test_packet_of_reads_a_rosbags_message():
    from ext_sense_bags.messages import sensor_packet

    from ext_sense_drivers.packets import packet_of

    packet = PacketPacker(NUSKIN_WORDS_V1, OPTIONS).pack([(1, r) for r in _reads(3)], False)[0]
    msg = sensor_packet(packet, "nuskin")
    back = packet_of(msg)
    assert back.data == packet.data
    assert back.reads() == packet.reads()


def test_quiet_schedule_says_nothing_read_every_period_after_bytes_for_as_long_as_silent():
    """A fixed cadence of the driver's own, from the last bytes, with no end."""
    quiet = QuietSchedule(period_s=0.005)
    ms = 10**6
    assert not quiet.due(T0)  # no bytes yet
    quiet.on_bytes(T0)
    drains = [T0 + k * ms for k in range(1, 3001)]  # a drain every 1 ms for 3 s, nothing read
    said = [t - T0 for t in drains if quiet.due(t)]
    assert said == [k * 5 * ms for k in range(1, 601)]
    quiet.on_bytes(T0 + 3040 * ms)  # bytes again: one period after them
    assert not quiet.due(T0 + 3044 * ms)
    assert quiet.due(T0 + 3045 * ms)
    never = QuietSchedule(period_s=0.0)  # 0: never
    never.on_bytes(T0)
    assert not never.enabled
    assert not never.due(T0 + 10**9)
