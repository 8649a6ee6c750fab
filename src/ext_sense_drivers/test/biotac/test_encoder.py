"""Frame encoding of the BioTac bridge: layout byte for byte and argument checks."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_drivers.biotac.crc import crc16_ccitt_false
from ext_sense_drivers.biotac.encoder import (
    encode_frame,
    encode_frames,
    encode_standard_frame,
    standard_replies,
)
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.frame_layout import STANDARD_FRAME_SIZE
from ext_sense_drivers.biotac.words import decode_word


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
