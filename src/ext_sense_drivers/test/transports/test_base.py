from ext_sense_drivers.transports import Transport
from ext_sense_drivers.transports.can_bus import CanTransport
from ext_sense_drivers.transports.file_source import FileTransport
from ext_sense_drivers.transports.serial_port import SerialTransport


def test_every_transport_meets_the_protocol(tmp_path):
    (tmp_path / "f").write_bytes(b"x")
    for t in (
        SerialTransport("loop://"),
        CanTransport("virtual", "proto", 0x10),
        FileTransport(tmp_path / "f"),
    ):
        assert isinstance(t, Transport)
