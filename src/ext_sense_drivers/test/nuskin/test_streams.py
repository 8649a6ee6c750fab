"""The decoding paths the driver node holds, and its configuration, without rclpy."""

import numpy as np
import pytest

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.driver_config import DriverConfig, Mode, TransportKind
from ext_sense_drivers.nuskin.errors import NuskinError
from ext_sense_drivers.nuskin.streams import AcesLineStream, FlaggedEvents, WordStream
from ext_sense_drivers.nuskin.wire import FlagPolarity, encode_words
from ext_sense_drivers.transports import Chunk
from ext_sense_drivers.transports.can_bus import CanTransport
from ext_sense_drivers.transports.file_source import FileTransport
from ext_sense_drivers.transports.serial_port import SerialTransport
from ext_sense_runtime.records import EventBlock


def test_word_stream_stamps_words_and_counts():
    stream = WordStream(FlagPolarity.IS_POSITIVE, ArrivalClock(byte_time_ns=1000, min_spread_ns=0))
    raw = encode_words([1, 2, 3, 4], [10, 20, 30, 40], [1, 0, 1, 0])
    assert stream.feed(Chunk(raw[:6], 1_000_000)).size == 1
    block = stream.feed(Chunk(raw[6:8] + b"\x00" + raw[8:], 1_010_000))
    assert block.taxel.tolist() == [2, 3, 4]
    assert block.polarity.tolist() == [-1, 1, -1]
    assert block.t_ns.tolist() == [1_003_333, 1_006_666, 1_010_000]
    assert stream.batch_counters == (4, 1, 1, 0)
    stream.feed(Chunk(raw[:2], 1_020_000))
    stream.restart()
    assert stream.batch_counters.skipped_bytes == 3
    assert stream.diagnostics()["words_total"] == 4


@pytest.mark.parametrize("polarity", list(FlagPolarity))
def test_word_stream_keeps_each_words_flag_bit_as_received(polarity):
    stream = WordStream(polarity)
    raw = encode_words([1, 2, 3], [10, 20, 30], [1, 0, 1])
    first = stream.feed_flagged(Chunk(b"\xff" + raw[:6], 1_000_000))  # a word cut in two
    rest = stream.feed_flagged(Chunk(raw[6:], 2_000_000))
    joined = FlaggedEvents.concat([first, FlaggedEvents(stream.restart(), None), rest])
    assert joined.events.taxel.tolist() == [1, 2, 3]
    assert joined.flag.dtype == np.uint8
    assert joined.flag.tolist() == [1, 0, 1]  # whatever the polarity makes of it


def test_flagged_events_of_a_source_without_the_bit_have_no_flag():
    block = EventBlock.of([1, 2], [3, 4])
    joined = FlaggedEvents.concat([FlaggedEvents(block, None), FlaggedEvents(block, None)])
    assert joined.flag is None
    assert joined.events.size == 4


def test_aces_line_stream_decodes_and_restarts():
    from ext_sense_drivers.aces.encoder import encode_line
    from ext_sense_drivers.aces.wire import samples_to_bytes

    t = np.array([10_000, 400_000, 900_000, 1_500_000], np.int64)
    taxel = np.array([1, 41, 80, 7])
    polarity = np.array([1, -1, 1, -1])
    line = encode_line(t, taxel, polarity, n_samples=1000)
    data = samples_to_bytes(line.samples).data
    stream = AcesLineStream()
    parts = [
        stream.feed_flagged(Chunk(data[i : i + 301], 10**9 + i)) for i in range(0, len(data), 301)
    ]
    assert all(p.flag is None for p in parts)  # the line has no flag bit
    blocks = [p.events for p in parts]
    blocks.append(stream.restart())
    block = EventBlock.concat(blocks)
    assert block.taxel.tolist() == taxel.tolist()
    assert block.polarity.tolist() == polarity.tolist()
    gaps = np.diff(block.t_ns)
    np.testing.assert_allclose(gaps, np.diff(t), atol=2000)  # one line sample is ~1969 ns
    assert stream.batch_counters.words_total == 4
    assert stream.restart().size == 0
    diagnostics = stream.diagnostics()
    assert diagnostics["detections"] == 4
    assert diagnostics["overload_samples"] == diagnostics["rejected"] == 0
    assert diagnostics["unresolved"] == 0


def test_aces_line_stream_counts_what_it_cannot_resolve():
    from ext_sense_drivers.aces.wire import samples_to_bytes

    # A line held at full scale carries no decodable signature: the decoder must say so in the
    # diagnostics instead of inventing events.
    data = samples_to_bytes(np.full(20_000, 6.0)).data
    stream = AcesLineStream()
    blocks = [stream.feed(Chunk(data[i : i + 4000], 10**9 + i)) for i in range(0, len(data), 4000)]
    blocks.append(stream.restart())
    assert EventBlock.concat(blocks).size == 0
    assert stream.diagnostics()["overload_samples"] > 0


def test_config_choices_and_errors(tmp_path):
    assert DriverConfig().transport_kind == TransportKind.SERIAL
    assert DriverConfig(mode="ACES_LINE").mode_kind == Mode.ACES_LINE
    with pytest.raises(NuskinError, match="'transport' parameter must be one of"):
        DriverConfig(transport="usb").make_transport()
    with pytest.raises(NuskinError, match="'mode' parameter must be one of"):
        DriverConfig(mode="bits").make_stream()
    with pytest.raises(NuskinError, match="'flag_polarity'"):
        DriverConfig(flag_polarity="maybe").make_stream()
    with pytest.raises(NuskinError, match="'file_path' parameter must name a capture"):
        DriverConfig(transport="file").make_transport()
    with pytest.raises(NuskinError, match="'file_pace'"):
        DriverConfig(transport="file", file_path="x", file_pace="slow").file_rate()
    assert isinstance(DriverConfig(port="loop://").make_transport(), SerialTransport)
    can = DriverConfig(transport="can", can_interface="virtual", can_arbitration_id=0x42)
    assert isinstance(can.make_transport(), CanTransport)
    assert can.hardware_id == "virtual:can0#0x42"
    flat = DriverConfig(transport="file", file_path=str(tmp_path / "a"), file_pace="flat")
    assert flat.file_rate() is None
    assert isinstance(flat.make_transport(), FileTransport)
    assert DriverConfig(file_pace="serial", baud=1_000_000).file_rate() == 100_000.0
    assert DriverConfig(file_bytes_per_s=5.0).file_rate() == 5.0
    assert isinstance(DriverConfig(mode="aces_line").make_stream(), AcesLineStream)


@pytest.mark.real_data
def test_config_recorded_pace_of_a_lab_capture(food_poking_dir):
    cfg = DriverConfig(transport="file", file_path=str(food_poking_dir / "apple_zero_0_raw.tact"))
    assert 100 < cfg.file_rate() < 1e6
