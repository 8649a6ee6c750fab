"""CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0) of bridge frames.

Check value: ``crc16_ccitt_false(b"123456789") == 0x29B1``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

POLY = 0x1021
INIT = 0xFFFF


def _table() -> NDArray[np.uint16]:
    table = np.zeros(256, dtype=np.uint16)
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ POLY) if crc & 0x8000 else (crc << 1)
        table[byte] = crc & 0xFFFF
    return table


TABLE = _table()
_TABLE_LIST = [int(v) for v in TABLE]


def crc16_ccitt_false(data: bytes | bytearray | memoryview, crc: int = INIT) -> int:
    """CRC of one byte string (table driven, plain Python).

    Args:
        data: The bytes covered by the checksum.
        crc: Running value to continue from (``INIT`` for a fresh checksum).

    Returns:
        The 16-bit CRC.
    """
    table = _TABLE_LIST
    for byte in bytes(data):
        crc = ((crc << 8) & 0xFFFF) ^ table[(crc >> 8) ^ byte]
    return crc


def crc16_ccitt_false_rows(rows: NDArray[np.uint8]) -> NDArray[np.uint16]:
    """CRC of every row of a 2-D byte array at once (one NumPy step per column).

    Args:
        rows: ``(n_rows, n_bytes)`` uint8, each row one byte string.

    Returns:
        ``(n_rows,)`` uint16 CRCs.
    """
    rows = np.asarray(rows, dtype=np.uint8)
    crc = np.full(rows.shape[0], INIT, dtype=np.uint16)
    for col in range(rows.shape[1]):
        crc = (crc << np.uint16(8)) ^ TABLE[(crc >> np.uint16(8)) ^ rows[:, col]]
    return crc
