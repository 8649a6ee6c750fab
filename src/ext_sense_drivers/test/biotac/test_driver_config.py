"""The BioTac driver's settings and its transports (serial URL, CAN, file), without ROS."""

from __future__ import annotations

import time

import numpy as np
import pytest

from ext_sense_drivers.biotac.clock import FRAME_PERIOD_NS
from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.driver_config import BioTacDriverConfig, TransportKind
from ext_sense_drivers.biotac.encoder import encode_frames
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.words import encode_values


def stream(n=20):
    values = np.arange(n * 44).reshape(n, 44) % 4096
    return encode_frames(np.arange(n) // 2, np.arange(n) % 2, encode_values(values)), values


def read_all(transport, n_bytes, timeout_s=3.0):
    got = b""
    end = time.monotonic() + timeout_s
    while len(got) < n_bytes and time.monotonic() < end:
        got += transport.read(0.05).data
    return got


def test_defaults_and_hardware_ids():
    c = BioTacDriverConfig()
    assert c.transport_kind == TransportKind.SERIAL
    assert c.hardware_id == "/dev/ttyACM0"
    # 10 ms frame span + 96 bytes at 1 Mbaud 8N1.
    assert c.lead_ns == FRAME_PERIOD_NS + 960_000
    can = BioTacDriverConfig(transport="can", can_channel="vcan0", can_arbitration_id=0x201)
    assert can.hardware_id == "socketcan:vcan0#0x201"
    assert can.lead_ns == FRAME_PERIOD_NS


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"transport": "usb"}, "'transport' parameter must be one of"),
        ({"expected_sensors": (0, 5)}, "'expected_sensors'"),
        ({"transport": "file"}, "'file_path'"),
    ],
)
def test_bad_settings(kwargs, match):
    with pytest.raises(BioTacError, match=match):
        BioTacDriverConfig(**kwargs)


def test_can_transport_carries_the_bridge_stream():
    from ext_sense_drivers.transports.can_bus import CanSink

    data, values = stream()
    cfg = BioTacDriverConfig(
        transport="can", can_interface="virtual", can_channel="biotac_cfg", can_arbitration_id=0x200
    )
    t = cfg.make_transport()
    t.open()
    try:
        with CanSink("virtual", "biotac_cfg", 0x200) as sink:
            sink.write(data)
        got = read_all(t, len(data))
    finally:
        t.close()
    frames = BridgeDecoder().feed(got)
    assert frames.n == 20
    assert (frames.pac == values[:, 0::2]).all()


def test_file_and_serial_url_transports(tmp_path):
    data, _ = stream()
    path = tmp_path / "s.bin"
    path.write_bytes(data)
    t = BioTacDriverConfig(transport="file", file_path=str(path)).make_transport()
    t.open()
    try:
        assert BridgeDecoder().feed(read_all(t, len(data))).n == 20
    finally:
        t.close()
    s = BioTacDriverConfig(port="loop://").make_transport()
    s.open()
    try:
        s.write(data[:96])
        assert BridgeDecoder().feed(read_all(s, 96)).n == 1
    finally:
        s.close()
