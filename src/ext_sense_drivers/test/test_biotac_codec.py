"""SPI reply words, CRC and frame encoding of the BioTac bridge."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_drivers.biotac.bridge import (
    STANDARD_FRAME_SIZE,
    BridgeDecoder,
    SequenceTracker,
    encode_frame,
    encode_frames,
    encode_standard_frame,
    standard_replies,
)
from ext_sense_drivers.biotac.crc import (
    crc16_ccitt_false,
    crc16_ccitt_false_columns,
    crc16_ccitt_false_rows,
)
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.reference import ReferenceDecoder
from ext_sense_drivers.biotac.words import (
    ODD_PARITY,
    ErrorReply,
    decode_word,
    decode_words,
    encode_values,
)


def test_crc_check_value():
    assert crc16_ccitt_false(b"123456789") == 0x29B1
    assert crc16_ccitt_false(b"") == 0xFFFF


@given(st.lists(st.binary(min_size=7, max_size=7), min_size=1, max_size=20))
def test_vector_crc_equals_scalar(rows):
    arr = np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(len(rows), 7)
    expected = [crc16_ccitt_false(r) for r in rows]
    assert crc16_ccitt_false_rows(arr).tolist() == expected
    assert crc16_ccitt_false_columns(arr).tolist() == expected


def test_value_formula_and_parity():
    words = encode_values(np.arange(4096))
    b0, b1 = (words >> 8).astype(np.uint8), (words & 0xFF).astype(np.uint8)
    assert ODD_PARITY[b0].all()
    assert ODD_PARITY[b1].all()
    assert ((b1 >> 1) & 0b11 == 0).all()  # unused data bits of b1 stay 0
    assert ((b0 >> 1).astype(int) * 32 + (b1 >> 3)).tolist() == list(range(4096))
    values, parity_failed, error = decode_words(b0, b1)
    assert values.tolist() == list(range(4096))
    assert not parity_failed.any()
    assert not error.any()


def test_known_words():
    # 4095: b0 = 0x7F << 1 | p (7 ones -> p = 0), b1 = 0x1F << 3 | p (5 ones -> p = 0)
    assert int(encode_values([4095])[0]) == 0xFEF8
    # 0: both bytes carry only the parity bit.
    assert int(encode_values([0])[0]) == 0x0101
    assert decode_word(0xFEF8) == (4095, False, False)
    assert decode_word(0xFEF9) == (0, True, False)


@pytest.mark.parametrize("reply", list(ErrorReply))
def test_error_replies_recognised_before_parity(reply):
    # Both error replies fail the parity check of b0; they must count as error replies.
    assert not ODD_PARITY[reply >> 8]
    assert decode_word(int(reply)) == (0, False, True)
    values, parity_failed, error = decode_words(
        np.array([reply >> 8], np.uint8), np.array([reply & 0xFF], np.uint8)
    )
    assert (values[0], parity_failed[0], error[0]) == (0, False, True)


@pytest.mark.parametrize("bad", [-1, 4096, 70000])
def test_encode_values_rejects_out_of_range(bad):
    with pytest.raises(BioTacError, match=r"must be in 0\.\.4095"):
        encode_values([0, bad])


def test_encode_values_rejects_floats():
    with pytest.raises(BioTacError, match="integers"):
        encode_values([1.5])


def test_frame_layout():
    pac = np.arange(22) * 100
    electrodes = np.arange(19) + 2000
    frame = encode_standard_frame(0x1234, 3, pac, electrodes, 4000, 2500, 2600)
    assert len(frame) == STANDARD_FRAME_SIZE == 96
    assert frame[:2] == b"\xaa\x55"
    assert frame[2:4] == b"\x34\x12"  # seq little-endian
    assert frame[4] == 3
    assert frame[5] == 44
    assert int.from_bytes(frame[94:96], "little") == crc16_ccitt_false(frame[2:94])
    words = [(frame[6 + 2 * k] << 8) | frame[7 + 2 * k] for k in range(44)]
    values = [decode_word(w)[0] for w in words]
    assert values[0:44:2] == pac.tolist()
    assert values[1:38:2] == electrodes.tolist()
    assert (values[39], values[41]) == (4000, 2500)
    assert values[43] == 2600


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"seq": 65536}, "'seq'"),
        ({"seq": -1}, "'seq'"),
        ({"sensor_id": 256}, "'sensor_id'"),
        ({"replies": [0x1FFFF]}, "0..0xFFFF"),
        ({"replies": b"\x01"}, "pairs"),
        ({"replies": [0] * 256}, "at most 255"),
    ],
)
def test_encode_frame_rejects(kwargs, match):
    args = {"seq": 0, "sensor_id": 0, "replies": [0] * 44} | kwargs
    with pytest.raises(BioTacError, match=match):
        encode_frame(**args)


def test_standard_replies_rejects_wrong_lengths():
    with pytest.raises(BioTacError, match="'pac' must hold 22"):
        standard_replies(np.zeros(21, int), np.zeros(19, int), 0, 0, 0)
    with pytest.raises(BioTacError, match="'electrodes' must hold 19"):
        standard_replies(np.zeros(22, int), np.zeros(18, int), 0, 0, 0)


def test_encode_frames_equals_encode_frame():
    rng = np.random.default_rng(3)
    replies = rng.integers(0, 0x10000, (7, 44))
    seq = rng.integers(0, 65536, 7)
    sensor = rng.integers(0, 5, 7)
    expected = b"".join(encode_frame(s, i, r) for s, i, r in zip(seq, sensor, replies, strict=True))
    assert encode_frames(seq, sensor, replies) == expected


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


@given(
    st.lists(st.tuples(st.integers(0, 4), st.integers(0, 65535)), min_size=9, max_size=60),
    st.integers(0, 3),
)
def test_sequence_tracker_batch_equals_per_frame(pairs, split):
    sensor = np.array([p[0] for p in pairs], dtype=np.uint8)
    seq = np.array([p[1] for p in pairs], dtype=np.uint16)
    one, batch = SequenceTracker(), SequenceTracker()
    expected = [one.step(int(a), int(b)) for a, b in zip(sensor, seq, strict=True)]
    got = []
    for part in np.array_split(np.arange(len(pairs)), split + 1):
        gap, reset = batch.steps(sensor[part], seq[part])
        got += list(zip(gap.tolist(), reset.tolist(), strict=True))
    assert got == expected
    assert vars(one) == vars(batch)
