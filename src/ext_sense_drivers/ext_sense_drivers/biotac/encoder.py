"""Encoders of the BioTac bridge protocol: reply words into frames, one or many at once."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ext_sense_drivers.biotac.crc import crc16_ccitt_false, crc16_ccitt_false_rows
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.frame_layout import (
    CRC,
    HEADER,
    SEQ_MODULO,
    STANDARD_FRAME_SIZE,
    SYNC,
)
from ext_sense_drivers.biotac.words import (
    ELECTRODE_POSITIONS,
    N_ELECTRODES,
    N_PAC,
    PAC_POSITIONS,
    PDC_POSITION,
    TAC_POSITION,
    TDC_POSITION,
    WORDS_PER_FRAME,
    encode_values,
)


def encode_frame(seq: int, sensor_id: int, replies: ArrayLike | bytes) -> bytes:
    """One bridge frame, CRC included, around reply words as the BioTac sent them.

    ``seq`` is 0..65535, ``sensor_id`` 0..255 on the wire (0..4 valid); ``replies`` up to 255
    words (any bits: corrupt words can be encoded) or their bytes. BioTacError if out of range.
    """
    if not 0 <= int(seq) < SEQ_MODULO:
        raise BioTacError(f"The 'seq' field must be in 0..65535. Got {seq} instead.")
    if not 0 <= int(sensor_id) <= 0xFF:
        raise BioTacError(f"The 'sensor_id' field must be in 0..255. Got {sensor_id} instead.")
    if isinstance(replies, bytes | bytearray | memoryview):
        payload = bytes(replies)
        if len(payload) % 2:
            raise BioTacError(f"Reply bytes must come in pairs. Got {len(payload)} bytes.")
    else:
        words = np.asarray(replies, dtype=np.int64).ravel()
        if words.size and (words.min() < 0 or words.max() > 0xFFFF):
            raise BioTacError(
                f"Reply words must be in 0..0xFFFF. Got {words.min()}..{words.max()} instead."
            )
        payload = words.astype(">u2").tobytes()
    n_words = len(payload) // 2
    if n_words > 0xFF:
        raise BioTacError(f"A frame holds at most 255 words. Got {n_words} instead.")
    body = HEADER.pack(SYNC, int(seq), int(sensor_id), n_words)[2:] + payload
    return SYNC + body + CRC.pack(crc16_ccitt_false(body))


def standard_replies(
    pac: ArrayLike, electrodes: ArrayLike, pdc: int, tac: int, tdc: int
) -> NDArray[np.uint16]:
    """The ``(44,)`` reply words of a standard frame, with correct parity.

    22 PAC samples, electrodes E01..E19, PDC, TAC and TDC, all 0..4095 (BioTacError if not).
    """
    pac_arr = np.asarray(pac)
    el_arr = np.asarray(electrodes)
    if pac_arr.shape != (N_PAC,):
        raise BioTacError(f"'pac' must hold {N_PAC} values. Got shape {pac_arr.shape}.")
    if el_arr.shape != (N_ELECTRODES,):
        raise BioTacError(
            f"'electrodes' must hold {N_ELECTRODES} values. Got shape {el_arr.shape}."
        )
    values = np.zeros(WORDS_PER_FRAME, dtype=np.int64)
    values[PAC_POSITIONS] = pac_arr
    values[ELECTRODE_POSITIONS] = el_arr
    values[[PDC_POSITION, TAC_POSITION, TDC_POSITION]] = [pdc, tac, tdc]
    if not np.issubdtype(pac_arr.dtype, np.integer) or not np.issubdtype(el_arr.dtype, np.integer):
        raise BioTacError("'pac' and 'electrodes' must be integers in 0..4095.")
    return encode_values(values)


def encode_standard_frame(
    seq: int, sensor_id: int, pac: ArrayLike, electrodes: ArrayLike, pdc: int, tac: int, tdc: int
) -> bytes:
    """A standard 44-word frame carrying 12-bit values (see :func:`standard_replies`)."""
    return encode_frame(seq, sensor_id, standard_replies(pac, electrodes, pdc, tac, tdc))


def encode_frames(seq: ArrayLike, sensor_id: ArrayLike, replies: ArrayLike) -> bytes:
    """``n`` standard frames back to back from ``(n,)`` seq, ``(n,)`` slots, ``(n, 44)`` replies."""
    seq_a = np.asarray(seq, dtype=np.int64).ravel()
    sid = np.asarray(sensor_id, dtype=np.int64).ravel()
    rep = np.asarray(replies, dtype=np.int64)
    n = seq_a.size
    if sid.size != n or rep.shape != (n, WORDS_PER_FRAME):
        raise BioTacError(
            f"encode_frames needs seq (n,), sensor_id (n,), replies (n, 44). Got "
            f"{seq_a.shape}, {sid.shape}, {rep.shape}."
        )
    if n and (seq_a.min() < 0 or seq_a.max() >= SEQ_MODULO or sid.min() < 0 or sid.max() > 255):
        raise BioTacError("encode_frames: 'seq' must be in 0..65535 and 'sensor_id' in 0..255.")
    if n and (rep.min() < 0 or rep.max() > 0xFFFF):
        raise BioTacError("encode_frames: reply words must be in 0..0xFFFF.")
    out = np.empty((n, STANDARD_FRAME_SIZE), dtype=np.uint8)
    out[:, 0], out[:, 1] = 0xAA, 0x55
    out[:, 2], out[:, 3] = seq_a & 0xFF, seq_a >> 8
    out[:, 4], out[:, 5] = sid, WORDS_PER_FRAME
    out[:, 6:94:2] = rep >> 8
    out[:, 7:94:2] = rep & 0xFF
    crc = crc16_ccitt_false_rows(out[:, 2:94]).astype(np.int64)
    out[:, 94], out[:, 95] = crc & 0xFF, crc >> 8
    return out.tobytes()
