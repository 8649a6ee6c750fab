"""Byte format of raw ACES line samples: int16 little-endian, one per chip, no framing.

The sample clock is the byte count; the int16 range holds 7 coinciding signatures before it
clips (counted, never silent).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.errors import AcesError

WIRE_DTYPE = np.dtype("<i2")
"""Little-endian int16."""

BYTES_PER_SAMPLE = 2

COUNTS_PER_UNIT = 4096
"""Wire counts per line unit (one chip of one signature at nominal amplitude)."""


class Quantised(NamedTuple):
    """Line samples as wire bytes (int16 little-endian), and how many were clipped to fit."""

    data: bytes
    n_clipped: int


def samples_to_bytes(line: npt.ArrayLike) -> Quantised:
    """Quantise line samples ``(n,)`` to the wire (AcesError if not 1-D, real and finite)."""
    x = np.asarray(line)
    if x.ndim != 1 or not (
        np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)
    ):
        raise AcesError(
            "The 'line' parameter must be a 1-D real array. "
            f"Got {x.dtype} of shape {x.shape} instead."
        )
    scaled = np.rint(x.astype(np.float64) * COUNTS_PER_UNIT)
    if not np.isfinite(scaled).all():
        raise AcesError(
            "The 'line' parameter must be finite. "
            f"Got {int((~np.isfinite(scaled)).sum())} NaN/inf samples instead."
        )
    lo, hi = np.iinfo(np.int16).min, np.iinfo(np.int16).max
    n_clipped = int(np.count_nonzero((scaled < lo) | (scaled > hi)))
    return Quantised(np.clip(scaled, lo, hi).astype(WIRE_DTYPE).tobytes(), n_clipped)


def bytes_to_samples(data: bytes | bytearray | memoryview) -> npt.NDArray[np.float64]:
    """Line samples (float64) of whole wire samples (AcesError on an odd byte count)."""
    if len(data) % BYTES_PER_SAMPLE:
        raise AcesError(
            f"The 'data' parameter must hold whole int16 samples. Got {len(data)} bytes."
        )
    return np.frombuffer(data, dtype=WIRE_DTYPE).astype(np.float64) / COUNTS_PER_UNIT


def chunk_samples(
    chunk: bytes | bytearray | memoryview | npt.NDArray[np.floating], odd: bytes = b""
) -> tuple[npt.NDArray[np.float64], bytes]:
    """Line samples (float64) of the next chunk of a stream, and the half wire sample it leaves.

    ``chunk`` is wire bytes (split anywhere) or a 1-D float array in line units; ``odd`` the half
    sample the previous chunk left. AcesError for another type, or an array while one is pending.
    """
    if isinstance(chunk, bytes | bytearray | memoryview):
        data = odd + bytes(chunk)
        cut = len(data) - len(data) % BYTES_PER_SAMPLE
        samples = np.frombuffer(data, WIRE_DTYPE, cut // BYTES_PER_SAMPLE).astype(np.float64) / (
            COUNTS_PER_UNIT
        )
        return samples, data[cut:]
    if not isinstance(chunk, np.ndarray):
        raise AcesError(
            "The 'chunk' parameter must be bytes or a float ndarray. "
            f"Got {type(chunk).__name__} instead."
        )
    if chunk.ndim != 1 or not np.issubdtype(chunk.dtype, np.floating):
        raise AcesError(
            "The 'chunk' parameter must be a 1-D float array in line units (wire counts go "
            f"in as bytes). Got {chunk.dtype} of shape {chunk.shape} instead."
        )
    if odd:
        raise AcesError("The 'chunk' parameter is an array but half a wire sample is pending.")
    return chunk.astype(np.float64), odd
