"""The bridge decoders (vectorised and reference) on encoded streams: masks, gaps, resync."""

from __future__ import annotations

import numpy as np

from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.encoder import encode_frame, encode_frames
from ext_sense_drivers.biotac.reference import ReferenceDecoder
from ext_sense_drivers.biotac.words import ErrorReply, encode_values


def test_round_trip_standard_frames():
    rng = np.random.default_rng(4)
    values = rng.integers(0, 4096, (50, 44))
    seq = (np.arange(50) // 2 + 65530) % 65536  # wraps
    sensor = np.arange(50) % 2
    stream = encode_frames(seq, sensor, encode_values(values))
    frames = BridgeDecoder().feed(stream)
    assert frames.n == 50
    assert frames.seq.tolist() == seq.tolist()
    assert frames.sensor_id.tolist() == sensor.tolist()
    assert (frames.pac == values[:, 0::2]).all()
    assert (frames.electrodes == values[:, 1:38:2]).all()
    assert (frames.pdc == values[:, 39]).all()
    assert (frames.tac == values[:, 41]).all()
    assert (frames.tdc == values[:, 43]).all()
    assert (frames.invalid_mask == 0).all()
    assert (frames.gap == 0).all()
    assert frames.offset.tolist() == list(range(0, 50 * 96, 96))


def test_bad_words_masked_rest_kept():
    values = np.arange(44) * 90
    words = encode_values(values)
    words[4] ^= 0x0001  # PAC sample 2: parity of b1 broken
    words[7] = ErrorReply.PARITY_ERROR  # electrode E04
    words[43] = ErrorReply.UNKNOWN_COMMAND  # TDC
    for dec in (BridgeDecoder(), ReferenceDecoder()):
        out = dec.feed(encode_frame(9, 1, words))
        (frame,) = out.rows() if hasattr(out, "rows") else out
        assert frame.invalid_mask == (1 << 4) | (1 << 7) | (1 << 43)
        assert frame.parity_errors == 1
        assert frame.error_replies == 2
        expected_pac = [int(v) for v in values[0::2]]
        expected_pac[2] = 0
        assert list(frame.pac) == expected_pac
        assert frame.electrodes[3] == 0
        assert frame.electrodes[4] == values[9]
        assert frame.tdc == 0
        assert frame.pdc == values[39]
        c = dec.counters
        assert c.parity_errors == (0, 1, 0, 0, 0)
        assert c.error_replies == (0, 2, 0, 0, 0)


def test_several_sensors_gaps_and_restart():
    def frame(seq, sensor):
        return encode_frame(seq, sensor, encode_values(np.zeros(44, int)))

    stream = b"".join(
        [
            frame(65534, 0),
            frame(10, 1),
            frame(65535, 0),
            frame(2, 0),  # 0 and 1 missing across the wrap: 2 dropped
            frame(11, 1),
            frame(15, 1),  # 3 dropped
            frame(3, 4),
            frame(0, 4),  # backwards: restart, nothing dropped
        ]
    )
    for dec in (BridgeDecoder(), ReferenceDecoder()):
        out = dec.feed(stream)
        rows = out.rows() if hasattr(out, "rows") else out
        assert [r.gap for r in rows] == [0, 0, 0, 2, 0, 3, 0, 0]
        assert [r.seq_reset for r in rows] == [False] * 7 + [True]
        c = dec.counters
        assert c.dropped_frames == (2, 3, 0, 0, 0)
        assert c.seq_resets == (0, 0, 0, 0, 1)
        assert c.sensor_frames == (3, 3, 0, 0, 2)


def test_other_and_bad_sensor_frames_counted_and_skipped():
    good = encode_frame(1, 0, encode_values(np.ones(44, int)))
    short = encode_frame(2, 0, [0x0101, 0x0101])
    bad_sensor = encode_frame(3, 7, encode_values(np.ones(44, int)))
    stream = short + bad_sensor + good
    for dec in (BridgeDecoder(), ReferenceDecoder()):
        out = dec.feed(stream)
        rows = out.rows() if hasattr(out, "rows") else out
        assert [r.seq for r in rows] == [1]
        assert rows[0].offset == len(short) + len(bad_sensor)
        c = dec.counters
        assert (c.other_frames, c.bad_sensor_frames, c.skipped_bytes) == (1, 1, 0)


def test_garbage_resync_and_truncated_tail():
    good = encode_frame(5, 2, encode_values(np.full(44, 7)))
    garbage = b"\x00\xaa\x55\x01\x00\x02\x2c\xff\xaa"  # a false sync claiming 44 words
    stream = garbage + good + good[:50]
    for dec in (BridgeDecoder(), ReferenceDecoder()):
        out = dec.feed(stream)
        rows = list(out.rows() if hasattr(out, "rows") else out)
        rows += list(dec.flush().rows() if hasattr(out, "rows") else dec.flush())
        assert [r.offset for r in rows] == [len(garbage)]
        c = dec.counters
        assert c.crc_failures == 1
        assert c.truncated == 1
        assert c.skipped_bytes == len(garbage) + 50
        assert c.bytes_total == len(stream)
