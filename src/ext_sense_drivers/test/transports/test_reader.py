import time

import pytest

from ext_sense_drivers.transports import Chunk, LinkState, TransportError
from ext_sense_drivers.transports.file_source import FileTransport
from ext_sense_drivers.transports.reader import Backoff, StreamReader


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
