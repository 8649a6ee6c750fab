import os
import time

import pytest

from ext_sense_drivers.transports import TransportError
from ext_sense_drivers.transports.serial_port import SerialTransport


def _read_until(transport, n, timeout_s=2.0):
    out = b""
    end = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < end:
        out += transport.read(0.05).data
    return out


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
