import pytest

from ext_sense_drivers.transports import TransportError
from ext_sense_drivers.transports.can_bus import CanTransport
from ext_sense_drivers.transports.file_source import FileTransport
from ext_sense_drivers.transports.serial_port import SerialTransport


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
