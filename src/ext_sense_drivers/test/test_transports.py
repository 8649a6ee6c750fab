import os
import time

import pytest

from ext_sense_drivers.transports import Chunk, LinkState, Transport, TransportError
from ext_sense_drivers.transports.can_bus import CanSink, CanTransport, split_frames
from ext_sense_drivers.transports.file_source import FileTransport
from ext_sense_drivers.transports.reader import Backoff, StreamReader
from ext_sense_drivers.transports.serial_port import SerialTransport


def _read_until(transport, n, timeout_s=2.0):
    out = b""
    end = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < end:
        out += transport.read(0.05).data
    return out


def test_every_transport_meets_the_protocol(tmp_path):
    (tmp_path / "f").write_bytes(b"x")
    for t in (
        SerialTransport("loop://"),
        CanTransport("virtual", "proto", 0x10),
        FileTransport(tmp_path / "f"),
    ):
        assert isinstance(t, Transport)


def test_serial_loop_round_trip_with_monotonic_stamps():
    t = SerialTransport("loop://")
    t.open()
    try:
        t.write(b"abc")
        first = t.read(0.2)
        t.write(b"defg")
        second = t.read(0.2)
        assert first.data + second.data == b"abcdefg"
        assert isinstance(first.t_ns, int)
        assert second.t_ns >= first.t_ns
        assert t.read(0.0).data == b""
    finally:
        t.close()


def test_serial_pty_bytes_and_vanishing_device():
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    t = SerialTransport(path)
    t.open()
    try:
        os.write(master, b"\x20\x42\x80\xe0")
        assert _read_until(t, 4) == b"\x20\x42\x80\xe0"
        os.close(master)

        def read_until_gone():
            for _ in range(20):
                t.read(0.05)

        with pytest.raises(TransportError, match="vanished"):
            read_until_gone()
    finally:
        t.close()
        t.close()


def test_serial_open_errors_name_the_port(tmp_path):
    with pytest.raises(TransportError, match=r"cannot open serial port '.*nope'"):
        SerialTransport(str(tmp_path / "nope")).open()
    with pytest.raises(TransportError, match="'port' parameter"):
        SerialTransport("")
    with pytest.raises(TransportError, match="not open"):
        SerialTransport("loop://").read(0.0)


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


class FakeTime:
    def __init__(self):
        self.ns = 1_000_000_000

    def clock(self):
        return self.ns

    def sleep(self, s):
        self.ns += int(s * 1e9)


def test_file_flat_out_then_exhausted(tmp_path):
    path = tmp_path / "cap.raw"
    path.write_bytes(bytes(range(10)))
    ft = FakeTime()
    t = FileTransport(path, chunk_size=4, clock=ft.clock, sleep=ft.sleep)
    t.open()
    parts = [t.read(0.1).data for _ in range(3)]
    assert parts == [bytes(range(4)), bytes(range(4, 8)), bytes(range(8, 10))]
    assert t.exhausted
    before = ft.ns
    assert t.read(0.1).data == b""
    assert ft.ns - before == 100_000_000  # waited, did not spin


def test_file_recorded_pace(tmp_path):
    path = tmp_path / "cap.raw"
    path.write_bytes(bytes(1000))
    ft = FakeTime()
    t = FileTransport(path, bytes_per_s=100.0, clock=ft.clock, sleep=ft.sleep)
    t.open()
    ft.ns += 250_000_000
    assert len(t.read(0.0).data) == 25
    first = t.read(0.5)  # nothing due: sleeps until the next byte is
    assert len(first.data) == 1
    ft.ns += 10_000_000_000
    assert len(t.read(0.0).data) == 974
    assert t.exhausted


def test_file_loop_and_errors(tmp_path):
    path = tmp_path / "cap.raw"
    path.write_bytes(b"abc")
    t = FileTransport(path, chunk_size=7, loop=True)
    t.open()
    assert t.read(0).data == b"abcabca"
    assert not t.exhausted
    with pytest.raises(TransportError, match="cannot read capture file"):
        FileTransport(tmp_path / "missing").open()
    with pytest.raises(TransportError, match="'bytes_per_s' parameter must be > 0"):
        FileTransport(path, bytes_per_s=0.0)


def test_backoff_delays():
    b = Backoff(0.1, 1.0, 2.0)
    assert [b.delay(k) for k in (1, 2, 3, 4, 5, 9)] == [0.1, 0.2, 0.4, 0.8, 1.0, 1.0]
    with pytest.raises(TransportError, match="'max_s' parameter must be >= initial_s"):
        Backoff(1.0, 0.5)


class FlakyTransport:
    """Fails to open twice, delivers two chunks, vanishes, then delivers one more."""

    description = "flaky"
    exhausted = False

    def __init__(self):
        self.opens = 0
        self.script = []

    def open(self):
        self.opens += 1
        if self.opens <= 2:
            raise TransportError("not there yet")
        self.script = [b"ab", b"cd", TransportError("unplugged")] if self.opens == 3 else [b"ef"]

    def read(self, timeout_s):
        if not self.script:
            time.sleep(timeout_s)
            return Chunk(b"", time.monotonic_ns())
        item = self.script.pop(0)
        if isinstance(item, Exception):
            raise item
        return Chunk(item, time.monotonic_ns())

    def close(self):
        pass


def test_reader_reconnects_with_backoff_and_counts():
    flaky = FlakyTransport()
    woken = []
    reader = StreamReader(
        flaky, backoff=Backoff(0.001, 0.01), read_timeout_s=0.005, on_data=lambda: woken.append(1)
    )
    reader.start()
    tagged = []
    end = time.monotonic() + 5
    while b"".join(c.data for _, c in tagged) != b"abcdef" and time.monotonic() < end:
        tagged += reader.drain_tagged()
        time.sleep(0.005)
    reader.stop()
    assert [(k, c.data) for k, c in tagged] == [(1, b"ab"), (1, b"cd"), (2, b"ef")]
    assert reader.open_failures == 2
    assert reader.connects == 2
    assert reader.disconnects == 1
    assert reader.last_error == "unplugged"
    assert reader.bytes_total == 6
    assert len(woken) == 3
    assert reader.state == LinkState.STOPPED
    assert not reader.alive


def test_reader_ends_exhausted_on_a_finite_file(tmp_path):
    path = tmp_path / "cap.raw"
    path.write_bytes(b"x" * 100)
    reader = StreamReader(FileTransport(path, chunk_size=30), read_timeout_s=0.001)
    reader.start()
    end = time.monotonic() + 5
    while reader.state != LinkState.EXHAUSTED and time.monotonic() < end:
        time.sleep(0.005)
    assert reader.state == LinkState.EXHAUSTED
    assert b"".join(c.data for c in reader.drain()) == b"x" * 100
    reader.stop()


def test_reader_bounds_its_queue_and_counts_drops(tmp_path):
    path = tmp_path / "cap.raw"
    path.write_bytes(b"y" * 1000)
    reader = StreamReader(FileTransport(path, chunk_size=100), max_pending_bytes=250)
    reader.start()
    end = time.monotonic() + 5
    while reader.state != LinkState.EXHAUSTED and time.monotonic() < end:
        time.sleep(0.005)
    kept = sum(len(c.data) for c in reader.drain())
    reader.stop()
    assert kept + reader.dropped_bytes == 1000
    assert kept <= 250


def test_serial_port_is_opened_exclusively():
    master, slave = os.openpty()
    path = os.ttyname(slave)
    first, second = SerialTransport(path), SerialTransport(path)
    try:
        first.open()
        with pytest.raises(TransportError, match="cannot open serial port"):
            second.open()
    finally:
        first.close()
        second.close()
        os.close(master)
        os.close(slave)


def test_link_config_builds_each_transport_and_names_its_hardware(tmp_path):
    from ext_sense_drivers.transports.link_config import LinkConfig, TransportKind

    serial = LinkConfig(transport="SERIAL", port="loop://")
    assert serial.transport_kind == TransportKind.SERIAL
    assert serial.hardware_id == "loop://"
    assert isinstance(serial.make_transport(), SerialTransport)
    can = LinkConfig(transport="can", can_interface="virtual", can_arbitration_id=0x42)
    assert can.hardware_id == "virtual:can0#0x42"
    assert isinstance(can.make_transport(), CanTransport)
    path = str(tmp_path / "capture.bin")
    assert LinkConfig(transport="file", file_path=path).file_rate() is None
    paced = LinkConfig(transport="file", file_path=path, file_bytes_per_s=500.0, file_loop=True)
    assert paced.hardware_id == path
    t = paced.make_transport()
    assert isinstance(t, FileTransport)
    assert (t.bytes_per_s, t.loop) == (500.0, True)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (
            {"transport": "usb"},
            "'transport' parameter must be one of \\['serial', 'can', 'file'\\]",
        ),
        ({"transport": "file"}, "'file_path' parameter must name a capture"),
    ],
)
def test_link_config_refuses_bad_links_with_its_error_type(kwargs, match):
    from dataclasses import dataclass
    from typing import ClassVar

    from ext_sense_drivers.transports.link_config import LinkConfig

    class SensorError(Exception):
        pass

    @dataclass(frozen=True)
    class SensorConfig(LinkConfig):
        error: ClassVar[type[Exception]] = SensorError

    with pytest.raises(TransportError, match=match):
        LinkConfig(**kwargs).make_transport()
    with pytest.raises(SensorError, match=match):
        SensorConfig(**kwargs).check_link()
