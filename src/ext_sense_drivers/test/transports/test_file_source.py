import pytest

from ext_sense_drivers.transports import TransportError
from ext_sense_drivers.transports.file_source import FileTransport


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
