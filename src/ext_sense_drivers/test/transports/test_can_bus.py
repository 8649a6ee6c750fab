import time

import pytest

from ext_sense_drivers.transports import TransportError
from ext_sense_drivers.transports.can_bus import CanSink, CanTransport, split_frames


def _read_until(transport, n, timeout_s=2.0):
    out = b""
    end = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < end:
        out += transport.read(0.05).data
    return out


def test_can_stream_rides_consecutive_frames_and_ignores_other_ids():
    rx = CanTransport("virtual", "t_can_1", 0x123)
    rx.open()
    try:
        with (
            CanSink("virtual", "t_can_1", 0x123) as sink,
            CanSink("virtual", "t_can_1", 0x124) as other,
        ):
            assert sink.write(bytes(range(21))) == 21
            other.write(b"zz")
            sink.write(b"\xff")
            assert sink.frames_sent == 4
        got = _read_until(rx, 22)
        assert got == bytes(range(21)) + b"\xff"
        assert rx.foreign_frames == 1
    finally:
        rx.close()


def test_can_extended_id_and_bad_id():
    rx = CanTransport("virtual", "t_can_2", 0x1ABCDE0, extended=True)
    rx.open()
    try:
        with CanSink("virtual", "t_can_2", 0x1ABCDE0, extended=True) as sink:
            sink.write(b"hello world")
        assert _read_until(rx, 11) == b"hello world"
    finally:
        rx.close()
    with pytest.raises(TransportError, match=r"'arbitration_id' parameter must be in 0\.\.0x7ff"):
        CanTransport("virtual", "x", 0x800)
    with pytest.raises(TransportError, match="cannot open CAN bus"):
        CanTransport("no_such_interface", "x", 1).open()


def test_split_frames():
    assert split_frames(b"") == []
    assert split_frames(bytes(17)) == [bytes(8), bytes(8), bytes(1)]
    with pytest.raises(TransportError, match="'size'"):
        split_frames(b"x", 9)
