"""Byte layout of a BioTac bridge frame.

Little-endian; the CRC-16/CCITT-FALSE covers ``seq`` through the last word byte::

    0xAA 0x55 | seq u16 | sensor_id u8 | n_words u8 | n_words x (b0, b1) | crc u16
"""

from __future__ import annotations

import struct

from ext_sense_drivers.biotac.words import WORDS_PER_FRAME

SYNC = b"\xaa\x55"
HEADER = struct.Struct("<2sHBB")
"""Sync, seq, sensor_id, n_words."""
CRC = struct.Struct("<H")
HEADER_SIZE = HEADER.size  # 6
FRAME_OVERHEAD = HEADER_SIZE + CRC.size  # 8
STANDARD_FRAME_SIZE = FRAME_OVERHEAD + 2 * WORDS_PER_FRAME  # 96
MAX_SENSORS = 5
"""Sensor slots 0..4 share one bridge link."""
SEQ_MODULO = 1 << 16
SEQ_BACKWARD = 1 << 15
"""A sequence step of this many frames or more is taken as a restart, not as a gap."""
