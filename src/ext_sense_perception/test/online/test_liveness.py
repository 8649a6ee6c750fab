from __future__ import annotations

from ext_sense_perception.online.liveness import StreamLiveness
from ext_sense_runtime.diagnostics import Level
from ext_sense_runtime.stamps import MS


class FakeClock:
    def __init__(self) -> None:
        self.ns = 1_000 * MS

    def __call__(self) -> int:
        return self.ns


def _liveness() -> tuple[StreamLiveness, FakeClock]:
    clock = FakeClock()
    live = StreamLiveness(
        "/extsense/nuskin/events", 1000.0, 100 * MS, 500 * MS, 100 * MS, clock=clock
    )
    return live, clock


def _stream(live: StreamLiveness, clock: FakeClock, n: int, stamp0: int) -> int:
    """``n`` messages 1 ms apart, arriving 2 ms after their stamp; returns the next stamp."""
    for i in range(n):
        live.on_message(stamp0 + i * MS, stamp0 + i * MS + 2 * MS)
        clock.ns += MS
    return stamp0 + n * MS


def test_a_stall_while_streaming_is_warn_then_error_naming_the_stream_and_clears():
    live, clock = _liveness()
    stamp = _stream(live, clock, 50, 10**18)
    assert live.check()[0] == Level.OK
    clock.ns += 150 * MS
    live.update(streaming=True)
    level, message, values = live.check()
    assert level == Level.WARN
    assert message.startswith("stall: no input on /extsense/nuskin/events for 15")
    clock.ns += 400 * MS
    live.update(streaming=True)
    assert live.check()[0] == Level.ERROR
    assert live.fault_in(stamp - 40 * MS, stamp + 210 * MS, final=True)  # its final window
    assert "1 contact(s) degraded" in live.check()[1]
    stamp += 550 * MS
    _stream(live, clock, 1, stamp)  # data returns
    level, message, values = live.check()
    assert (level, message) == (Level.OK, "streaming")
    assert values["stalls"] == 1
    assert (values["contacts_degraded"], values["contacts_lost"]) == (1, 0)
    assert int(values["longest_stall_ms"]) >= 550


def test_silence_while_not_streaming_is_no_stall():
    live, clock = _liveness()
    _stream(live, clock, 10, 10**18)
    clock.ns += 5_000 * MS
    live.update(streaming=False)  # an event sensor with nothing touching it
    assert live.check()[0] == Level.OK
    assert live.stalls == 0


def test_windows_overlapping_a_stall_are_degraded_the_others_not():
    live, clock = _liveness()
    t0 = 10**18
    stamp = _stream(live, clock, 100, t0)
    clock.ns += 300 * MS
    live.update(streaming=True)
    # a window closed during the stall overlaps it
    assert live.fault_in(t0 + 50 * MS, t0 + 400 * MS).startswith("stall: no input on")
    stamp += 300 * MS
    _stream(live, clock, 100, stamp)
    reason = live.fault_in(t0 + 50 * MS, t0 + 400 * MS)
    assert "for 30" in reason
    assert "inside the window" in reason
    assert live.fault_in(t0, t0 + 90 * MS) == ""  # before it
    assert live.fault_in(stamp + 10 * MS, stamp + 90 * MS) == ""  # after it
    assert live.degraded_windows == 2


def test_a_late_packet_is_counted_but_degrades_no_window_and_a_constant_offset_is_not_late():
    live, _ = _liveness()
    t0 = 10**18
    for i in range(50):  # a replayed bag: every stamp an hour old, 1 ms apart
        live.on_message(t0 + i * MS, t0 + 3_600_000 * MS + i * MS)
    assert live.late_packets == 0
    live.on_message(t0 + 50 * MS, t0 + 3_600_000 * MS + 50 * MS + 250 * MS)
    assert live.late_packets == 1
    # the window is cut once the stream passes its end: the late packet is in it, complete
    assert live.fault_in(t0 + 40 * MS, t0 + 60 * MS, final=True) == ""
    assert (live.degraded_windows, live.contacts_degraded) == (0, 0)
    assert live.check()[2]["max_late_ms"] == "250"


def _tap_liveness() -> tuple[StreamLiveness, FakeClock]:
    live, clock = _liveness()
    live.contact_words = 8  # the onset detector's activity_min_events
    live.contact_horizon_ns = 400 * MS  # pre 50 + post 250 + 100 ms
    live.debounce_ns = 500 * MS
    return live, clock


def test_a_seq_gap_degrades_the_windows_across_it_and_is_a_lost_contact_only_uncovered():
    live, clock = _tap_liveness()
    t0 = 10**18
    live.on_lost_packets(t0, t0 + 3 * MS, 1)  # one packet: too few words for an onset
    assert live.fault_in(t0 + MS, t0 + 2 * MS) == (
        "lost input: 1 packet(s) missing on /extsense/nuskin/events (seq gap)"
    )
    assert live.fault_in(t0 + 4 * MS, t0 + 5 * MS) == ""
    live.on_lost_packets(t0 + 10 * MS, t0 + 30 * MS, 8)  # enough words for an onset
    assert (live.packets_lost, live.contacts_lost) == (9, 0)  # not settled yet
    _stream(live, clock, 1, t0 + 429 * MS)
    assert live.contacts_lost == 0  # a window may still come to cover it
    _stream(live, clock, 1, t0 + 431 * MS)
    assert live.contacts_lost == 1  # none did: it may have held a whole contact


def test_gaps_inside_the_windows_of_contacts_are_degraded_contacts_not_lost_ones():
    # packet loss at a loaded window node: many gaps in every tap, each tap still windowed
    live, clock = _tap_liveness()
    t0 = 10**18
    for tap in range(62):
        onset = t0 + tap * 1000 * MS
        for k in range(6):  # six gaps of 10 packets in each tap
            live.on_lost_packets(onset + k * 40 * MS, onset + k * 40 * MS + 10 * MS, 10)
        for post in (25, 50, 100, 150):
            live.fault_in(onset - 50 * MS, onset + post * MS)
        assert live.fault_in(onset - 50 * MS, onset + 250 * MS, final=True)
        _stream(live, clock, 1, onset + 900 * MS)
    assert live.packets_lost == 62 * 6 * 10
    assert (live.contacts_degraded, live.contacts_lost) == (62, 0)


def test_uncovered_gaps_closer_than_the_debounce_are_one_lost_contact():
    live, clock = _tap_liveness()
    t0 = 10**18
    for k in range(5):  # 5 gaps within 200 ms: one contact at most
        live.on_lost_packets(t0 + k * 40 * MS, t0 + k * 40 * MS + 20 * MS, 10)
    live.on_lost_packets(t0 + 1500 * MS, t0 + 1520 * MS, 10)  # another, a debounce later
    _stream(live, clock, 1, t0 + 3000 * MS)
    assert live.contacts_lost == 2


def test_the_next_change_follows_the_stall_thresholds():
    from ext_sense_perception.online.liveness import MARGIN_NS

    live, clock = _liveness()
    assert live.next_change_ns(streaming=True) is None  # nothing arrived yet
    live.on_message(stamp_ns=7 * MS, wall_ns=7 * MS)
    arrived = clock.ns
    assert live.next_change_ns(streaming=False) is None  # silence is normal
    warn_at = live.next_change_ns(streaming=True)
    assert warn_at == arrived + 100 * MS + MARGIN_NS
    clock.ns = warn_at
    live.update(streaming=True)
    assert live.stalled  # the timer lands after the threshold, not on it
    error_at = live.next_change_ns(streaming=True)
    assert error_at == arrived + 500 * MS + MARGIN_NS
    clock.ns = error_at
    assert live.next_change_ns(streaming=True) is None  # ERROR reached: wait for data
