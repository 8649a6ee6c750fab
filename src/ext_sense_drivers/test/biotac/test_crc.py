"""CRC-16/CCITT-FALSE of the BioTac bridge frames: scalar and vectorised."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_drivers.biotac.crc import (
    crc16_ccitt_false,
    crc16_ccitt_false_columns,
    crc16_ccitt_false_rows,
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
