"""The block of decoded taxel events that every NUSkin decoding path hands to the driver node.

Both the receiver-word path (:mod:`ext_sense_drivers.nuskin.wire` with
:mod:`ext_sense_drivers.nuskin.clock`) and the ACES line path return an :class:`EventBlock`, so
the node builds ``TaxelEventBatch`` messages from one shape whatever the source.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt


class EventBlock(NamedTuple):
    """Parallel arrays, one entry per event, in arrival order.

    Attributes:
        t_ns: Host time of each event, integer nanoseconds, shape ``(n,)`` int64.
        taxel: Taxel id 1..80 (1..40 left finger, 41..80 right), shape ``(n,)`` uint16.
        polarity: +1 positive spike, -1 negative, 0 unknown, shape ``(n,)`` int8.
        value: The receiver's 10-bit value field (0 when the source has none), ``(n,)`` uint16.
    """

    t_ns: npt.NDArray[np.int64]
    taxel: npt.NDArray[np.uint16]
    polarity: npt.NDArray[np.int8]
    value: npt.NDArray[np.uint16]

    @property
    def size(self) -> int:
        """Number of events (``len()`` of a NamedTuple is its field count, so not that)."""
        return int(self.t_ns.shape[0])

    @classmethod
    def empty(cls) -> EventBlock:
        """A block with no events."""
        return cls(
            np.empty(0, np.int64),
            np.empty(0, np.uint16),
            np.empty(0, np.int8),
            np.empty(0, np.uint16),
        )

    @classmethod
    def concat(cls, blocks: list[EventBlock]) -> EventBlock:
        """Join blocks end to end (an empty list gives an empty block)."""
        if not blocks:
            return cls.empty()
        return cls(*(np.concatenate([b[i] for b in blocks]) for i in range(4)))
