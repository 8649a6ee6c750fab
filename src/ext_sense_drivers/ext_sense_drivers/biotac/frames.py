"""Records of decoded BioTac bridge frames: one :class:`Frame`, or a batch as arrays."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ext_sense_drivers.biotac.words import N_ELECTRODES, N_PAC, WORDS_PER_FRAME


class Frame(NamedTuple):
    """One decoded standard frame in plain Python values (fields as :class:`BridgeFrames`)."""

    sensor_id: int
    seq: int
    gap: int
    seq_reset: bool
    pac: tuple[int, ...]
    electrodes: tuple[int, ...]
    pdc: int
    tac: int
    tdc: int
    invalid_mask: int
    parity_errors: int
    error_replies: int
    offset: int


class BridgeFrames(NamedTuple):
    """A batch of decoded standard frames as parallel arrays (``n`` frames).

    ``gap``: frames of that sensor missing just before this one; ``seq_reset``: ``seq`` stepped
    backwards (bridge restart), no gap counted; ``words`` (n, 44) as received; ``pac`` (n, 22),
    ``electrodes`` (n, 19: E01..E19), ``pdc``, ``tac``, ``tdc``: 0 where invalid;
    ``invalid_mask`` bit i: word i failed parity or was an error reply; ``offset``: stream
    position of each frame's first byte.
    """

    sensor_id: NDArray[np.uint8]
    seq: NDArray[np.uint16]
    gap: NDArray[np.int64]
    seq_reset: NDArray[np.bool_]
    words: NDArray[np.uint16]
    pac: NDArray[np.uint16]
    electrodes: NDArray[np.uint16]
    pdc: NDArray[np.uint16]
    tac: NDArray[np.uint16]
    tdc: NDArray[np.uint16]
    invalid_mask: NDArray[np.uint64]
    parity_errors: NDArray[np.uint8]
    error_replies: NDArray[np.uint8]
    offset: NDArray[np.int64]

    @property
    def n(self) -> int:
        """Number of frames."""
        return int(self.seq.shape[0])

    def rows(self) -> list[Frame]:
        """The frames as :class:`Frame` records."""
        return [
            Frame(
                int(self.sensor_id[k]),
                int(self.seq[k]),
                int(self.gap[k]),
                bool(self.seq_reset[k]),
                tuple(int(v) for v in self.pac[k]),
                tuple(int(v) for v in self.electrodes[k]),
                int(self.pdc[k]),
                int(self.tac[k]),
                int(self.tdc[k]),
                int(self.invalid_mask[k]),
                int(self.parity_errors[k]),
                int(self.error_replies[k]),
                int(self.offset[k]),
            )
            for k in range(self.n)
        ]

    @staticmethod
    def concat(batches: list[BridgeFrames]) -> BridgeFrames:
        """Join batches in order."""
        if not batches:
            return _empty_frames()
        return BridgeFrames(*(np.concatenate(cols) for cols in zip(*batches, strict=True)))


def _empty_frames() -> BridgeFrames:
    """A batch of no frames (its arrays are read-only, so it can be shared)."""
    z = np.zeros(0, dtype=np.uint16)
    return BridgeFrames(
        np.zeros(0, np.uint8),
        z,
        np.zeros(0, np.int64),
        np.zeros(0, bool),
        np.zeros((0, WORDS_PER_FRAME), np.uint16),
        np.zeros((0, N_PAC), np.uint16),
        np.zeros((0, N_ELECTRODES), np.uint16),
        z,
        z,
        z,
        np.zeros(0, np.uint64),
        np.zeros(0, np.uint8),
        np.zeros(0, np.uint8),
        np.zeros(0, np.int64),
    )


EMPTY_FRAMES = _empty_frames()
"""A shared batch of no frames (read-only)."""
for _col in EMPTY_FRAMES:
    _col.flags.writeable = False
