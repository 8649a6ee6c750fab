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
    """CRC of one byte string, continuing from ``crc`` (plain Python)."""
    table = _TABLE_LIST
    for byte in bytes(data):
        crc = ((crc << 8) & 0xFFFF) ^ table[(crc >> 8) ^ byte]
    return crc


def crc16_ccitt_false_columns(rows: NDArray[np.uint8], crc: int = INIT) -> NDArray[np.uint16]:
    """CRCs ``(n_rows,)`` of the rows of ``(n_rows, n_bytes)`` bytes, one step per column."""
    rows = np.asarray(rows, dtype=np.uint8)
    reg = np.full(rows.shape[0], crc, dtype=np.uint16)
    for col in range(rows.shape[1]):
        reg = (reg << np.uint16(8)) ^ TABLE[(reg >> np.uint16(8)) ^ rows[:, col]]
    return reg


_POSITION_TABLES: dict[int, tuple[NDArray[np.uint16], int]] = {}


def _position_table(n_bytes: int) -> tuple[NDArray[np.uint16], int]:
    """Per-position tables for ``n_bytes`` messages.

    The CRC is affine over GF(2): the zero message's CRC XOR each byte's zero-init contribution.
    """
    if n_bytes not in _POSITION_TABLES:
        single = np.zeros((n_bytes * 256, n_bytes), dtype=np.uint8)
        pos = np.repeat(np.arange(n_bytes), 256)
        single[np.arange(n_bytes * 256), pos] = np.tile(np.arange(256, dtype=np.uint8), n_bytes)
        table = crc16_ccitt_false_columns(single, crc=0).reshape(n_bytes, 256)
        base = int(crc16_ccitt_false_columns(np.zeros((1, n_bytes), np.uint8))[0])
        _POSITION_TABLES[n_bytes] = (table, base)
    return _POSITION_TABLES[n_bytes]


def crc16_ccitt_false_rows(rows: NDArray[np.uint8]) -> NDArray[np.uint16]:
    """CRCs ``(n_rows,)`` of the rows of ``(n_rows, n_bytes)`` bytes: a lookup per byte."""
    rows = np.asarray(rows, dtype=np.uint8)
    if rows.shape[0] == 0 or rows.shape[1] == 0:
        return np.full(rows.shape[0], INIT, dtype=np.uint16)
    table, base = _position_table(rows.shape[1])
    parts = table[np.arange(rows.shape[1]), rows]
    return np.bitwise_xor.reduce(parts, axis=1) ^ np.uint16(base)
