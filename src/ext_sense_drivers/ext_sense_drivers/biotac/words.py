"""BioTac SPI reply words and the standard 44-word sampling sequence.

A reply word ``b0 << 8 | b1`` carries 7 data bits and an odd-parity LSB per byte; the 12-bit
value is ``(b0 >> 1) * 32 + (b1 >> 3)``. The error replies ``0xA545`` and ``0xA53F`` fail
``b0``'s parity and are recognised before it.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ext_sense_drivers.biotac.errors import BioTacError

WORDS_PER_FRAME = 44
N_PAC = 22
N_ELECTRODES = 19
MAX_VALUE = 4095

PAC_POSITIONS = np.arange(0, 44, 2)
"""Word positions of the 22 PAC samples (even positions 0..42)."""
ELECTRODE_POSITIONS = np.arange(1, 38, 2)
"""Word positions of electrodes E01..E19 (odd positions 1..37)."""
PDC_POSITION = 39
TAC_POSITION = 41
TDC_POSITION = 43


class ErrorReply(IntEnum):
    """Reply words the BioTac sends instead of a sample."""

    PARITY_ERROR = 0xA545
    UNKNOWN_COMMAND = 0xA53F


ODD_PARITY = np.array([bin(b).count("1") % 2 == 1 for b in range(256)], dtype=bool)
"""``ODD_PARITY[b]``: byte ``b`` passes the odd-parity check."""


def _parity_bit(data7: NDArray[np.int64]) -> NDArray[np.int64]:
    """The LSB that makes ``data7 << 1 | bit`` odd parity."""
    ones = np.zeros_like(data7)
    for shift in range(7):
        ones += (data7 >> shift) & 1
    return 1 - (ones & 1)


def encode_values(values: ArrayLike) -> NDArray[np.uint16]:
    """uint16 reply words (correct parity) carrying 12-bit integer values, any shape."""
    arr = np.asarray(values)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise BioTacError(f"BioTac values must be integers in 0..4095. Got dtype {arr.dtype}.")
    v = arr.astype(np.int64)
    if v.size and (v.min() < 0 or v.max() > MAX_VALUE):
        raise BioTacError(
            f"BioTac values must be in 0..{MAX_VALUE}. Got range {v.min()}..{v.max()} instead."
        )
    hi = v >> 5
    lo = (v & 0x1F) << 2
    b0 = (hi << 1) | _parity_bit(hi)
    b1 = (lo << 1) | _parity_bit(lo)
    return ((b0 << 8) | b1).astype(np.uint16)


class WordStatus(IntEnum):
    """What a reply word turned out to be."""

    OK = 0
    PARITY_FAILED = 1
    ERROR_REPLY = 2


def _word_tables() -> tuple[NDArray[np.uint16], NDArray[np.uint8]]:
    """Value and status of every possible reply word (two 64 Ki lookup tables)."""
    word = np.arange(1 << 16, dtype=np.uint32)
    b0, b1 = word >> 8, word & 0xFF
    error = (b0 == 0xA5) & ((b1 == 0x45) | (b1 == 0x3F))
    parity_failed = ~(ODD_PARITY[b0] & ODD_PARITY[b1]) & ~error
    values = ((b0 >> 1) * 32 + (b1 >> 3)).astype(np.uint16)
    values[error | parity_failed] = 0
    status = np.where(error, WordStatus.ERROR_REPLY, WordStatus.OK).astype(np.uint8)
    status[parity_failed] = WordStatus.PARITY_FAILED
    return values, status


WORD_VALUE, WORD_STATUS = _word_tables()
"""``WORD_VALUE[w]``: value of reply word ``w`` (0 when invalid); ``WORD_STATUS[w]``: its
:class:`WordStatus`."""


def decode_word(word: int) -> tuple[int, bool, bool]:
    """``(value, parity_failed, error_reply)`` of one reply word (value 0 for a bad word)."""
    b0, b1 = (word >> 8) & 0xFF, word & 0xFF
    if word in (ErrorReply.PARITY_ERROR, ErrorReply.UNKNOWN_COMMAND):
        return 0, False, True
    if bin(b0).count("1") % 2 == 0 or bin(b1).count("1") % 2 == 0:
        return 0, True, False
    return (b0 >> 1) * 32 + (b1 >> 3), False, False
